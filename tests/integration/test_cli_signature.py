import html
import json

import numpy as np
import pytest

from mirror_avatar.cli import main

FIGURES = ["ims.png", "similarity.png", "distances.png", "strokes.png"]


def write_csvs(zhai_trials, root):
    for trial in zhai_trials:
        folder = root / trial.group
        folder.mkdir(parents=True, exist_ok=True)
        data = np.column_stack([trial.times, trial.positions])
        np.savetxt(folder / f"{trial.label}.csv", data, delimiter=",", header="time,position",
                   comments="")  # fmt: skip
    return [root / "fast", root / "slow"]


def test_signature_of_csv_directories(zhai_trials, tmp_path, capsys):
    folders = write_csvs(zhai_trials, tmp_path / "data")
    out = tmp_path / "out"
    assert main(["signature", *map(str, folders), "--out", str(out)]) == 0
    result = json.loads((out / "signature.json").read_text())
    assert sorted(result["groups"]) == ["fast"] * 9 + ["slow"] * 9
    emd = np.array(result["emd"])
    same = np.equal.outer(result["groups"], result["groups"])
    upper = np.triu(np.ones_like(emd, dtype=bool), 1)
    assert 3 * emd[upper & same].mean() < emd[upper & ~same].mean()
    for name in FIGURES:
        assert (out / name).read_bytes().startswith(b"\x89PNG")


def test_signature_of_bundled_data(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["signature", "--bundled", "--out", str(out), "--level", "0.5"]) == 0
    result = json.loads((out / "signature.json").read_text())
    assert result["level"] == 0.5 and result["group_names"] == ["fast", "slow"]
    assert len(result["coordinates"]) == 18 and len(result["emd"]) == 18
    assert set(result["ellipses"]) == {"fast", "slow"}
    assert result["overlaps"][0][0] == pytest.approx(1.0)
    assert result["stroke_statistics"]["fast"]["n_strokes"] > 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [*FIGURES, "signature.json", "report.html"]
    )
    assert "18 trials in 2 groups" in capsys.readouterr().out


def test_the_report_leads_with_whether_the_people_are_told_apart(tmp_path, capsys):
    """Issue 39.3: signature wrote no HTML and no verdict."""
    out = tmp_path / "out"
    assert main(["signature", "--bundled", "--out", str(out)]) == 0
    verdict = (
        "The 2 people are told apart: 18 of 18 trials (100%) are nearest their own person's "
        "other trials; chance"
    )
    assert verdict in capsys.readouterr().out
    page = html.unescape((out / "report.html").read_text())
    assert page.index('<p class="lead">' + verdict) < page.index('<section id="people">')
    assert page.count("data:image/png;base64,") == 4
    identification = json.loads((out / "signature.json").read_text())["identification"]
    assert identification["rate"] == 1.0 and identification["told_apart"] is True
    assert identification["p_value"] == pytest.approx(0.001)


@pytest.mark.parametrize(
    "arguments",
    [["--bundled", "--level", "1.5"], ["--bundled", "--rate", "0"], []],
)
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, arguments):
    out = tmp_path / "out"
    assert main(["signature", *arguments, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("mirror-avatar: error:") and error.count("\n") == 1
    assert not out.exists()


@pytest.mark.long
@pytest.mark.parametrize(
    ("group_by", "expected"), [("none", {"all"}), ("file", {"fast/fast-1", "slow/slow-9"})]
)
def test_group_by_none_and_file(zhai_trials, tmp_path, capsys, group_by, expected):
    folders = write_csvs(zhai_trials, tmp_path / "data")
    out = tmp_path / "out"
    arguments = ["signature", *map(str, folders), "--out", str(out), "--group-by", group_by]
    assert main(arguments) == 0
    result = json.loads((out / "signature.json").read_text(), parse_constant=pytest.fail)
    assert expected <= set(result["groups"])
    assert len(result["group_names"]) == (1 if group_by == "none" else 18)
    if group_by == "file":
        assert result["ellipses"]["fast/fast-1"] is None
        assert result["overlaps"][0][1] is None


def test_two_trials_give_an_emd_and_a_note_for_the_ellipse(zhai_trials, tmp_path, capsys):
    """Two trials make an EMD matrix; only the ellipse, which needs three, is skipped."""
    write_csvs(zhai_trials[:2], tmp_path / "data")
    out = tmp_path / "out"
    assert main(["signature", str(tmp_path / "data" / "fast"), "--out", str(out)]) == 0
    result = json.loads((out / "signature.json").read_text())
    emd = np.array(result["emd"])
    assert emd.shape == (2, 2) and emd[0, 1] == emd[1, 0] > 0.0
    assert result["ellipses"] == {"fast": None}
    printed = capsys.readouterr()
    assert "group 'fast' has 2 trial(s): no confidence ellipse" in printed.err
    for name in FIGURES:
        assert (out / name).read_bytes().startswith(b"\x89PNG")


def test_one_trial_is_refused_in_one_line(zhai_trials, tmp_path, capsys):
    write_csvs(zhai_trials[:1], tmp_path / "data")
    assert main(["signature", str(tmp_path / "data"), "--out", str(tmp_path / "out")]) == 2
    assert "needs at least 2 trials, got 1" in capsys.readouterr().err
