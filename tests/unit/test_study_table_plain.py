"""The study table of a plain lab session (no study): a group on a ring, read from its run
folder and from its BIDS export; the person-or-computer rules; bad paths refused in one line."""

from __future__ import annotations

import json
import math
import shutil
import time
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from mirror_avatar.analysis.table import study_table, table_dictionary
from mirror_avatar.analysis.trials import read_study_trials
from mirror_avatar.cli import main
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trial_record import AnswerRecord, read_trial_record
from mirror_avatar.lab.design.guesses import guess, guess_of, is_identification
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.export.run_outcomes import RunOutcomes
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.realtime.inputs import BrowserInput

RING = {
    "condition": "group", "graph": "ring", "duration": 4.0, "trials": 2, "seed": 5,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        {"label": "P2", "kind": "human"},
    ],
}  # fmt: skip


@pytest.fixture(scope="module")
def ring_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two trials of a ring of two people and an avatar, recorded as the lab records them."""
    return record_session(tmp_path_factory.mktemp("lab") / "20261127T010203-001", RING, 2)


def record_session(folder: Path, design: dict[str, Any], trials: int) -> Path:
    """Record ``trials`` whole trials of ``design`` in a new run folder ``folder``; return it."""
    folder.mkdir()
    (folder / "plan.json").write_text(json.dumps({"session_id": folder.name}))
    for n in range(1, trials + 1):
        record_trial(folder, n, design=design)
    return folder


def record_trial(
    folder: Path, n: int, seconds: float | None = None, design: dict[str, Any] = RING
) -> None:
    """Record trial n of ``design`` in ``folder``: whole, or aborted after ``seconds``."""
    plan = parse_plan(design)
    inputs = {k: BrowserInput() for k in plan.humans}
    lab = {"session_id": folder.name, "condition": plan.condition}
    trial = LabTrial(plan, n, folder, inputs, build_avatars(plan), time.monotonic, lab)
    ticks = trial.n_ticks if seconds is None else round(seconds / CONTROL_PERIOD)
    while trial.k < ticks and not trial.finished:
        for i, source in inputs.items():
            source.put(0.3 * math.sin(2 * math.pi * (0.4 + 0.1 * n) * trial.k * 0.03 + i), trial.k)
        trial.tick()
    trial.finish(seconds is None, "completed" if seconds is None else "aborted")


def table(paths: list[Path], out: Path) -> pd.DataFrame:
    assert main(["study", "table", *map(str, paths), "--out", str(out), "--surrogates", "0"]) == 0
    return pd.read_parquet(out / "study.parquet")


def test_a_plain_sessions_table_is_the_same_from_its_folder_and_its_export(ring_session, tmp_path):
    runs = table([ring_session], tmp_path / "runs")
    assert set(runs["participant"]) == {ring_session.name}
    assert list(runs["person"]) == ["P1", "A1", "P2"] * 2
    assert list(runs["trial"]) == [1, 1, 1, 2, 2, 2]
    assert set(runs["block"]) == {1} and set(runs["position"]) == {1}
    assert set(runs["condition"]) == {"group"}
    assert list(runs["partners"][:3]) == ["A1+P2", "P1+P2", "P1+A1"]
    assert list(runs["partner_kind"][:3]) == ["mixed", "person", "mixed"]
    assert runs[["synchronisation", "influence", "group_synchronisation"]].notna().all(axis=None)
    assert not any(column.startswith(("answer_", "guess_")) for column in runs.columns)
    assert not any(column.startswith("transfer_entropy_") for column in runs.columns)
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(ring_session), "--out", str(bids)]) == 0
    pd.testing.assert_frame_equal(runs, table([bids], tmp_path / "bids_table"))


def test_a_trial_too_short_to_measure_keeps_its_rows(ring_session, tmp_path):
    full = table([ring_session], tmp_path / "full")
    trials = read_study_trials([ring_session])
    longest = max(trial.session.duration for trial in trials)
    rows = study_table(trials, trim=longest - 0.01, surrogates=0)
    assert list(rows.columns) == list(full.columns[: len(rows.columns)])
    assert len(rows) == len(full) and "rmse" not in rows


@pytest.mark.parametrize("trim", ["60", "1e9"])
def test_a_trim_that_leaves_no_trial_to_measure_is_refused(ring_session, tmp_path, capsys, trim):
    out = tmp_path / "out"
    assert main(["study", "table", str(ring_session), "--out", str(out), "--trim", trim]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--trim" in error and "the longest lasts" in error
    assert not out.exists()


def test_paths_that_hold_no_study_are_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    for path in (tmp_path / "nowhere", tmp_path / "empty"):
        assert main(["study", "table", str(path), "--out", str(tmp_path / "out")]) == 2
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and path.name in error


def test_two_recordings_under_one_name_are_refused_not_one_of_them_dropped(
    ring_session, tmp_path, capsys
):
    """Two labs' folders whose runs share a name (two pilots of the same participants)."""
    other = tmp_path / "other" / ring_session.name
    shutil.copytree(ring_session, other)
    sidecar = other / "trial-02_session.json"
    text = sidecar.read_text()
    started = json.loads(text)["metadata"]["started_utc"]
    sidecar.write_text(text.replace(started, "2026-11-28T00:00:00+00:00"))
    paths = [ring_session.parent, other.parent]
    assert main(["study", "table", *map(str, paths), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "trial 2 of " in error and "lab pilot --first" in error
    shutil.copy(ring_session / "trial-02_session.json", sidecar)  # the same recording twice
    assert len(table(paths, tmp_path / "twice")) == len(table([ring_session], tmp_path / "once"))


@pytest.fixture(scope="module")
def lab_out(ring_session: Path) -> Path:
    """A lab's --out of three plain sessions: the ring's and two more, recorded alike."""
    out = ring_session.parent / "out"
    shutil.copytree(ring_session, out / ring_session.name)
    for name in ("20261127T020304-002", "20261127T030405-003"):
        (out / name).mkdir()
        (out / name / "plan.json").write_text(json.dumps({"session_id": name}))
        record_trial(out / name, 1)
        record_trial(out / name, 2, seconds=0.6)
    return out


def test_worker_processes_write_the_table_byte_for_byte_as_one_process(lab_out, tmp_path):
    """The run folders shared among forked workers, a folder given twice read once: the same
    three files as one process writes, and the rows `study_table` makes of the trials read at
    once."""
    one, two = tmp_path / "one", tmp_path / "two"
    paths = [str(lab_out), str(lab_out / "20261127T020304-002")]
    assert main(["study", "table", *paths, "--out", str(one), "--surrogates", "3"]) == 0
    assert main(["study", "table", *paths, "--out", str(two), "--surrogates", "3",
                 "--jobs", "2"]) == 0  # fmt: skip
    for name in ("study.csv", "study.parquet", "study.json"):
        assert (one / name).read_bytes() == (two / name).read_bytes()
    rows = pd.read_parquet(two / "study.parquet")
    assert len(set(rows["participant"])) == 3 and len(rows) == 3 * 2 * 3
    whole = study_table(read_study_trials([lab_out]), surrogates=3)
    pd.testing.assert_frame_equal(rows, whole, check_dtype=False)


def test_a_bad_trial_file_in_a_worker_is_one_line(lab_out, tmp_path, capsys):
    """An `InputError` raised in a worker process reaches the command as it was raised."""
    out = tmp_path / "lab"
    shutil.copytree(lab_out, out)
    broken = out / "20261127T030405-003" / "trial-01_session.csv"
    broken.write_text("time,position_0\nnot,a number\n")
    code = main(["study", "table", str(out), "--out", str(tmp_path / "t"), "--jobs", "2"])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and str(broken) in error


def test_a_run_whose_only_person_was_refused_has_their_row_and_no_trial():
    refused = {("p000", "study-p000"): RunOutcomes(refusals={"P1": "Your connection is slow."})}
    (row,) = study_table([], outcomes=refused).itertuples()
    assert (row.participant, row.session, row.person) == ("p000", "study-p000", "P1")
    assert (row.refusals, row.refusal, row.complete) == (1, "Your connection is slow.", False)
    assert pd.isna(row.trial) and pd.isna(row.condition) and pd.isna(row.perturbations)


def answer(question: str, text: str, kind: str, value: object) -> AnswerRecord:
    return AnswerRecord("P1", question, text, kind, value, "trial", None)


@pytest.mark.parametrize(
    ("value", "kind"),
    [("a person", "person"), ("A human being", "person"), ("a computer", "avatar"),
     ("the avatar", "avatar"), ("not sure", None), ("a person or a computer", None)],
)  # fmt: skip
def test_an_answer_names_the_guessed_kind(value: str, kind: str | None) -> None:
    assert guess_of(value) == kind


def test_the_guess_is_the_choice_naming_both_kinds_with_its_confidence() -> None:
    asked = answer("partner", "Was your partner a person or a computer?", "choice", "a person")
    sure = answer("confidence", "How confident are you?", "likert", 6)
    assert is_identification(asked)
    assert not is_identification(answer("mood", "How did the computer feel?", "choice", "fine"))
    assert not is_identification(replace_kind(asked, "text"))
    assert guess([asked, sure]) == ("person", 6.0)
    kind, confidence = guess([asked])  # type: ignore[misc]
    assert kind == "person" and math.isnan(confidence)
    assert guess([sure]) is None


def replace_kind(record: AnswerRecord, kind: str) -> AnswerRecord:
    return AnswerRecord(record.label, record.question, record.text, kind, record.value,
                        record.after, record.utc)  # fmt: skip


def test_an_output_in_the_way_is_refused_before_any_work(ring_session, tmp_path, capsys):
    (tmp_path / "out" / "study.parquet").mkdir(parents=True)
    assert main(["study", "table", str(ring_session), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "study.parquet" in error
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["study.parquet"]


def test_a_measure_s_p_value_is_described_as_a_p_value_not_a_measure():
    from mirror_avatar.analysis.dictionary import measure_info, p_value_column

    assert measure_info(p_value_column("rmse"))["Role"] == "p_value"
    assert measure_info("rmse")["Role"] == "measure"
    assert p_value_column("max_cross_correlation") == "time_lag_p_value"


def test_the_dictionary_lists_the_levels_of_a_text_column_whatever_pandas_calls_its_type():
    """pandas 3 gives text the ``str`` dtype, not ``object``: the levels are listed for both."""
    for dtype in (object, "str"):
        table = pd.DataFrame(
            {
                "condition": pd.Series(["mirror", "free", "mirror"], dtype=dtype),
                "leader": pd.Series(["P1", "none", "P1"], dtype=dtype),
            }
        )
        info = table_dictionary(table, {})
        assert info["condition"]["Levels"] == {"free": "free", "mirror": "mirror"}
        assert set(info["leader"]["Levels"]) == {"P1", "none"}


def test_an_input_that_never_delivers_is_recorded_lost_and_its_record_reads_back(tmp_path):
    """A page that sends nothing has no message number: the lost event's seq is None, not -1."""
    folder = tmp_path / "20261127T010203-002"
    folder.mkdir()
    plan = parse_plan(RING)
    inputs = {k: BrowserInput() for k in plan.humans}
    silent, speaking = sorted(inputs)
    lab = {"session_id": folder.name, "condition": plan.condition}
    trial = LabTrial(plan, 1, folder, inputs, build_avatars(plan), time.monotonic, lab)
    while not trial.finished:  # at least real time, so the silent input outlives its timeout
        inputs[speaking].put(0.3 * math.sin(0.2 * trial.k), trial.k)
        time.sleep(CONTROL_PERIOD)
        trial.tick()
    trial.finish(True, "completed")
    record = read_trial_record(folder / "trial-01_session.json")
    lost = [event for event in record.input_events if event.event == "lost"]
    assert [event.label for event in lost] == [plan.slots[silent].label]
    assert lost[0].seq is None


@pytest.mark.long
def test_an_aborted_trial_is_marked_incomplete_and_left_out_of_the_report_saying_so(
    ring_session, tmp_path, capsys
):
    """A trial aborted after 0.9 s has every measure missing: its rows say complete false, the
    dictionary describes the column, and the report's methods count complete trials only."""
    folder = tmp_path / ring_session.name
    shutil.copytree(ring_session, folder)
    record_trial(folder, 3, seconds=0.9)
    rows = table([folder], tmp_path / "table")
    assert "(3 trials, 1 of them incomplete, 1 participant)" in capsys.readouterr().out
    assert list(rows["complete"]) == [True] * 6 + [False] * 3
    assert rows.loc[rows["trial"] == 3, ["rmse", "synchronisation"]].isna().all(axis=None)
    described = json.loads((tmp_path / "table" / "study.json").read_text())
    assert described["complete"]["Role"] == "quality"
    assert pd.read_csv(tmp_path / "table" / "study.csv")["complete"].dtype == bool
    out = tmp_path / "report"
    assert main(["study", "report", str(tmp_path / "table"), "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    assert (results["parameters"]["rows"], results["parameters"]["incomplete_rows"]) == (4, 2)
    assert "participants' 4 complete trials" in results["methods"]
    assert "2 rows of incomplete trials, stopped before their end, left out" in results["methods"]
    assert "2 rows of incomplete trials left out (complete false" in " ".join(results["notes"])


def test_the_table_and_its_report_never_hold_the_researchers_folders(ring_session, tmp_path):
    """Every file `study table` and `study report` write names files by their base names only:
    neither the recordings' folder nor the output's appears in any of them."""
    table([ring_session], tmp_path / "table")
    assert (
        main(["study", "report", str(tmp_path / "table"), "--out", str(tmp_path / "report")]) == 0
    )
    folders = (str(tmp_path), str(ring_session.parent))
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert {p.parent.name for p in written} == {"table", "report"}
    assert [p.name for p in written if any(f.encode() in p.read_bytes() for f in folders)] == []
    results = json.loads((tmp_path / "report" / "results.json").read_text())
    assert results["parameters"]["source"] == "study.csv"
