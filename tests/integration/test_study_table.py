"""The study table of a protocol played through the real lab server: one row per trial and
player with the design, the measures and the answers; the same table from the run folders and
from their BIDS export; the answers' behavioural files carrying the partners' true kind; a
trial's measures the same in the console, its sidecar, ``evaluate`` and the table."""

from __future__ import annotations

import csv
import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_lab_server import TOKEN, status
from test_lab_study_export import PROTOCOL, Study, play

from mirror_avatar.cli import main
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

DESIGN = [
    "participant", "session", "person", "player_kind", "block", "condition", "trial",
    "position", "partners", "partner_kind", "delay_s", "partner_view", "occluded", "perturbations",
    "complete",
]  # fmt: skip


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Study]:
    """Participants 0 and 1's runs of the export protocol (follow an avatar, then a hidden,
    delayed joint trial of two people), played on the lab server."""
    base = tmp_path_factory.mktemp("study")
    protocol_file = base / "export.toml"
    protocol_file.write_text(PROTOCOL)
    settings = LabSettings(
        out_dir=base / "out", token=TOKEN, countdown=1, protocol=load_protocol(protocol_file)
    )
    with ServerThread(create_lab_app(settings)) as server:
        sid, second = play(server, 0), play(server, 1)
        yield Study(server, sid, base / "out" / sid, base / "out" / second)


def table_of(paths: list[Path], out: Path, capsys: pytest.CaptureFixture[str]) -> pd.DataFrame:
    assert main(["study", "table", *map(str, paths), "--out", str(out)]) == 0, capsys.readouterr()
    return pd.read_parquet(out / "study.parquet")


def test_a_row_per_trial_and_player_with_design_measures_and_answers(study, tmp_path, capsys):
    table = table_of([study.folder.parent], tmp_path / "table", capsys)
    assert list(table.columns[: len(DESIGN)]) == DESIGN
    assert sorted(set(table["participant"])) == ["p000", "p001"]
    first = table[table["participant"] == "p000"]
    assert list(first["person"]) == ["P1", "A1", "P1", "P2"]
    assert list(first["player_kind"]) == ["person", "avatar", "person", "person"]
    assert list(first["trial"]) == [1, 1, 2, 2] and list(first["block"]) == [1, 1, 1, 1]
    assert list(first["position"]) == [1, 1, 2, 2]
    assert list(first["condition"]) == ["follow", "follow", "hidden", "hidden"]
    assert list(first["partners"]) == ["A1", "P1", "P2", "P1"]
    assert list(first["partner_kind"]) == ["avatar", "person", "person", "person"]
    assert first["delay_s"].tolist() == pytest.approx([0, 0, 0.3, 0.3])
    assert list(first["partner_view"]) == ["as_arrives"] * 4
    assert list(first["occluded"]) == [False, False, True, True]
    assert list(first["perturbations"]) == [0, 0, 0, 0]
    assert list(first["complete"]) == [True] * 4
    assert np.isfinite(first["rmse"]).all() and np.isfinite(first["phase_locking"]).all()
    # the AnsweringPage says "a computer" with confidence 5: right of the avatar, wrong of P2
    people = first[first["player_kind"] == "person"]
    assert list(people["answer_partner"]) == ["a computer"] * 3
    assert list(people["guess_kind"]) == ["avatar"] * 3
    assert list(people["guess_correct"]) == [True, False, False]
    assert people["guess_confidence"].iloc[0] == 5.0  # no confidence asked after trial 2
    assert people["guess_confidence"].iloc[1:].isna().all()
    assert first[first["player_kind"] == "avatar"]["guess_kind"].isna().all()
    csv_table = pd.read_csv(tmp_path / "table" / "study.csv")
    assert list(csv_table.columns) == list(table.columns) and len(csv_table) == len(table)
    dictionary = json.loads((tmp_path / "table" / "study.json").read_text())
    assert list(dictionary) == list(table.columns)
    assert {info["Role"] for info in dictionary.values()} == {
        "identifier", "design", "quality", "measure", "answer"
    }  # fmt: skip
    assert dictionary["rmse"]["Units"] == "playing range units"
    assert dictionary["partner_kind"]["Levels"]["avatar"]
    assert "a person or a computer?" in dictionary["answer_partner"]["Description"]


@pytest.mark.long
def test_the_table_from_the_runs_equals_the_table_from_their_bids_export(study, tmp_path, capsys):
    bids = tmp_path / "bids"
    for folder in (study.folder, study.second):
        assert main(["lab", "export", str(folder), "--out", str(bids)]) == 0
    from_runs = table_of([study.folder, study.second], tmp_path / "runs", capsys)
    from_bids = table_of([bids], tmp_path / "from_bids", capsys)
    pd.testing.assert_frame_equal(from_runs, from_bids)
    subject = table_of([bids / "sub-p000P2"], tmp_path / "subject", capsys)
    run = from_runs[(from_runs["participant"] == "p000") & (from_runs["trial"] == 2)]
    pd.testing.assert_frame_equal(subject, run[subject.columns].reset_index(drop=True))
    assert run.drop(columns=subject.columns).isna().all(axis=None)  # no confidence asked


HOSTILE_ANSWER = 'a\tcomputer,\r\n  "it said" C:\\new\\ \x1b[31m\\t '
"""A typed answer with what a TSV cell cannot hold as it is: a tab, line breaks, a backslash
before a t or an n, and spaces and quotes a reader may eat."""


def test_a_typed_answer_is_the_same_from_the_runs_and_from_their_bids_export(
    study, tmp_path, capsys
):
    folder = tmp_path / "out" / study.folder.name
    shutil.copytree(study.folder, folder)
    answers = folder / "trial-01_answers.json"
    recorded = json.loads(answers.read_text())
    recorded["answers"]["P1"]["partner"]["value"] = HOSTILE_ANSWER
    answers.write_text(json.dumps(recorded))
    assert main(["lab", "export", str(folder), "--out", str(tmp_path / "bids")]) == 0
    from_runs = table_of([folder], tmp_path / "runs", capsys)
    from_bids = table_of([tmp_path / "bids"], tmp_path / "from_bids", capsys)
    pd.testing.assert_frame_equal(from_runs, from_bids)
    assert from_bids["answer_partner"].iloc[0] == HOSTILE_ANSWER


def test_the_answers_carry_the_partners_true_kind(study, tmp_path):
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(study.folder), "--out", str(bids)]) == 0
    rows = {}
    for run in (1, 2):
        (path,) = bids.glob(f"sub-p000P1/beh/*_run-{run}_beh.tsv")
        with path.open(encoding="utf-8", newline="") as handle:
            rows[run] = list(csv.DictReader(handle, delimiter="\t"))
    assert {(r["partners"], r["partner_kind"]) for r in rows[1]} == {("A1", "avatar")}
    assert {(r["partners"], r["partner_kind"]) for r in rows[2]} == {("P2", "person")}
    described = json.loads((bids / "task-mirrorgame_beh.json").read_text())
    assert set(described["partner_kind"]["Levels"]) == {"person", "avatar", "mixed", "none"}


def test_evaluate_reads_the_export_from_its_motion_files_once_per_trial(study, tmp_path, capsys):
    bids = tmp_path / "bids"
    for folder in (study.folder, study.second):
        assert main(["lab", "export", str(folder), "--out", str(bids)]) == 0

    def evaluated(*paths: Path) -> list[dict]:
        capsys.readouterr()
        assert main(["evaluate", *map(str, paths), "--json", "--surrogates", "0"]) == 0
        out = capsys.readouterr().out
        found, _ = json.JSONDecoder().raw_decode(out[out.index("{") :])  # a weak-null line follows
        return list(found.values())

    from_bids = evaluated(bids)  # 6 motion files of 4 trials; sourcedata's 4 trials not read
    from_runs = evaluated(study.folder, study.second)
    assert len(from_bids) == len(from_runs) == 4
    for exported, recorded in zip(from_bids, from_runs, strict=True):
        for key in ("rmse", "phase_locking", "time_lag", "co_confidence_rate"):
            assert exported[key] == recorded[key]
    assert len(evaluated(bids / "sub-p000P1")) == 2


def test_a_trials_measures_are_the_same_in_the_console_sidecar_evaluate_and_table(
    study, tmp_path, capsys
):
    """The lab's own analysis, ``evaluate`` and ``study table`` measure a trial one way (the same
    trim, rate and surrogates' seed): the follow trial's CV, RMS and CC rate, as the console's JSON
    (the server's answer), its sidecar, ``evaluate --json`` and ``study.csv`` give them, and
    its surrogates drawn from its recorded seed."""
    (console,) = [row for row in status(study.server, study.sid)["trials"] if row["n"] == 1]
    trial = study.folder / "trial-01_session.csv"
    sidecar = json.loads(trial.with_suffix(".json").read_text())["metadata"]
    assert main(["evaluate", str(trial), "--json", "--surrogates", "19"]) == 0
    out = capsys.readouterr().out
    evaluated, _ = json.JSONDecoder().raw_decode(out[out.index("{") :])
    assert main(["study", "table", str(study.folder), "--out", str(tmp_path)]) == 0
    with (tmp_path / "study.csv").open() as handle:
        (row, _) = [r for r in csv.DictReader(handle) if r["trial"] == "1"]
    cv = console["metrics"]["phase_locking"]
    assert 0.0 < cv <= 1.0
    assert sidecar["metrics"]["phase_locking"] == evaluated["phase_locking"] == cv
    assert float(row["phase_locking"]) == cv
    for key in ("rmse", "co_confidence_rate"):
        shown = console["metrics"] | console["measures"]
        assert float(row[key]) == evaluated[key] == shown[key]
    drawn = sidecar["measures"]["surrogates"]  # 1 s after the trim: too short for shifts
    assert drawn == evaluated["surrogates"] == console["measures"]["surrogates"]
    assert drawn["seed"] == sidecar["seed"]
