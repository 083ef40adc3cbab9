"""A trial is its person and its source, never its base name: seven people's folders of
``trial_00.csv ...`` give the results that uniquely named files give, through the command line."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.cli.trial_sets import read_trial_set
from mirror_avatar.experiments.generator import (
    analyse_splits,
    compute_style_emd,
    identify_styles,
    split_and_generate,
)
from mirror_avatar.files.trial_io import read_csv_trial, write_csv_trial
from mirror_avatar.files.trials import Trial

PEOPLE = 7


def write_people(root: Path, trials: list[Trial], per_person: int, unique: bool) -> list[str]:
    """Folders p1..p7 of one person's real trials each, and ``people.csv`` mapping them.

    Each person plays one bundled style (alternately fast and slow), shifted in time and scaled
    so that the seven differ. With ``unique`` False every folder holds ``trial_00.csv ...``.
    """
    rows = ["file,group"]
    for p in range(PEOPLE):
        folder = root / f"p{p + 1}"
        folder.mkdir(parents=True)
        style = trials[:9] if p % 2 == 0 else trials[9:]
        for k in range(per_person):
            moved = np.roll(style[k].positions, 37 * p) * (0.6 + 0.08 * p)
            name = f"p{p + 1}_trial_{k:02d}.csv" if unique else f"trial_{k:02d}.csv"
            write_csv_trial(replace(style[k], positions=moved), folder / name)
            rows.append(f"p{p + 1}/{name},person{p + 1}")
    (root / "people.csv").write_text("\n".join(rows) + "\n")
    return [str(root / f"p{p + 1}") for p in range(PEOPLE)]


def signature_of(root: Path, folders: list[str], out: Path) -> dict:
    arguments = ["signature", *folders, "--group-by", f"map:{root / 'people.csv'}"]
    assert main([*arguments, "--out", str(out)]) == 0
    return json.loads((out / "signature.json").read_text())


@pytest.mark.long
def test_same_file_names_in_seven_folders_give_the_unique_names_results(
    zhai_trials, tmp_path, capsys
) -> None:
    same = write_people(tmp_path / "same", zhai_trials, 3, unique=False)
    unique = write_people(tmp_path / "unique", zhai_trials, 3, unique=True)
    a = signature_of(tmp_path / "same", same, tmp_path / "a")
    b = signature_of(tmp_path / "unique", unique, tmp_path / "b")
    assert a["groups"] == b["groups"] == [f"person{p // 3 + 1}" for p in range(21)]
    np.testing.assert_array_equal(a["emd"], b["emd"])
    assert a["labels"][:4] == ["p1/trial_00", "p1/trial_01", "p1/trial_02", "p2/trial_00"]
    assert len(set(a["labels"])) == 21 and len(a["trial_stroke_statistics"]) == 21
    assert a["stroke_statistics"] == b["stroke_statistics"]
    printed = capsys.readouterr().out
    assert "group 'person7': 3 trial(s) (p7/trial_00, p7/trial_01, p7/trial_02)" in printed


@pytest.mark.long
def test_the_generator_validation_of_seven_people_ignores_file_names(zhai_trials, tmp_path):
    """Each person's within-person EMD and identification, as with unique names (no warning)."""
    results = []
    for unique in (False, True):
        root = tmp_path / str(unique)
        folders = write_people(root, zhai_trials, 9, unique)
        trials = read_trial_set(folders, f"map:{root / 'people.csv'}").trials
        splits = split_and_generate(trials, seed=0)
        analysis, rows = analyse_splits(splits)
        results.append((compute_style_emd(analysis, rows), identify_styles(analysis, splits, rows)))
    (same_emd, same_found), (unique_emd, unique_found) = results
    assert same_emd.equals(unique_emd)
    assert same_emd["human_within"].nunique() == PEOPLE
    assert np.all(np.isfinite(same_emd["between"]))
    assert same_found["correct"].tolist() == unique_found["correct"].tolist()
    assert len(same_found) == 3 * PEOPLE


def test_convert_keeps_seven_people_apart(zhai_trials, tmp_path, capsys) -> None:
    folders = write_people(tmp_path / "data", zhai_trials, 3, unique=False)
    out = tmp_path / "converted"
    assert main(["convert", *folders, "--group-by", "none", "--out", str(out)]) == 0
    written = sorted(p.name for p in (out / "all").iterdir())
    assert len(written) == 21 and written[:2] == ["p1_trial_00.csv", "p1_trial_01.csv"]
    back = read_csv_trial(out / "all" / "p4_trial_01.csv")
    original = read_csv_trial(tmp_path / "data" / "p4" / "trial_01.csv")
    np.testing.assert_array_equal(back.positions, original.positions)
    manifest = json.loads((out / "convert.json").read_text())
    assert manifest["trials"][3]["source"] == str(tmp_path / "data" / "p2" / "trial_00.csv")


@pytest.mark.long
def test_a_map_takes_paths_relative_to_itself_or_as_given(
    zhai_trials, tmp_path, capsys, monkeypatch
) -> None:
    folders = write_people(tmp_path / "data", zhai_trials, 3, unique=False)
    maps = tmp_path / "maps"
    maps.mkdir()
    rows = [f"../data/p{p // 3 + 1}/trial_{p % 3:02d}.csv,who{p // 3 + 1}" for p in range(21)]
    (maps / "relative.csv").write_text("file,group\n" + "\n".join(rows) + "\n")
    out = tmp_path / "s"
    arguments = ["signature", *folders, "--out", str(out), "--group-by"]
    assert main([*arguments, f"map:{maps / 'relative.csv'}"]) == 0
    assert json.loads((out / "signature.json").read_text())["group_names"][-1] == "who7"
    monkeypatch.chdir(tmp_path)
    given = [f"data/p{p // 3 + 1}/trial_{p % 3:02d}.csv,as{p // 3 + 1}" for p in range(21)]
    (maps / "given.csv").write_text("file,group\n" + "\n".join(given) + "\n")
    relative = [f"data/p{p + 1}" for p in range(PEOPLE)]
    command = ["signature", *relative, "--out", "s2", "--group-by", "map:maps/given.csv"]
    assert main(command) == 0
    assert json.loads(Path("s2/signature.json").read_text())["group_names"][0] == "as1"
    capsys.readouterr()


def test_a_bare_name_in_a_map_that_fits_several_files_is_refused(
    zhai_trials, tmp_path, capsys
) -> None:
    folders = write_people(tmp_path / "data", zhai_trials, 3, unique=False)
    names = tmp_path / "names.csv"
    names.write_text("file,group\ntrial_00.csv,a\ntrial_01.csv,b\ntrial_02.csv,c\n")
    out = tmp_path / "s"
    arguments = ["signature", *folders, "--out", str(out), "--group-by", f"map:{names}"]
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "names both" in error and "map's folder" in error
    assert not out.exists()


@pytest.mark.parametrize("twice", ["folder", "file"])
def test_a_file_given_twice_is_read_once(zhai_trials, tmp_path, twice) -> None:
    folders = write_people(tmp_path / "data", zhai_trials, 3, unique=False)
    again = folders[0] if twice == "folder" else f"{folders[0]}/trial_01.csv"
    found = read_trial_set([*folders, again], "directory")
    assert len(found.trials) == 21 and len({t.label for t in found.trials}) == 21
    assert any("given more than once" in note for note in found.notes)


@pytest.mark.parametrize("given", ["people", "sessions"])
def test_two_folders_of_one_name_are_refused_not_merged_into_one_person(
    zhai_trials, tmp_path, capsys, given
) -> None:
    """``a/alice`` and ``b/alice``, given as such or as ``a`` and ``b``: two people or one?"""
    for session, trials in (("a", zhai_trials[:3]), ("b", zhai_trials[9:12])):
        (tmp_path / session / "alice").mkdir(parents=True)
        for k, trial in enumerate(trials):
            write_csv_trial(trial, tmp_path / session / "alice" / f"trial_{k:02d}.csv")
    paths = ["a/alice", "b/alice"] if given == "people" else ["a", "b"]
    out = tmp_path / "s"
    arguments = ["signature", *(str(tmp_path / path) for path in paths), "--out", str(out)]
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error == (
        f"mirror-avatar: error: {tmp_path / 'a' / 'alice'} and {tmp_path / 'b' / 'alice'} would "
        "both be group 'alice' (one person): rename one folder, or say whose trials are whose "
        "with --group-by map:FILE.csv\n"
    )
    assert not out.exists()
