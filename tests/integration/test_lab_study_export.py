"""The BIDS export of a study protocol's sessions, played through the real lab server: one run
per trial with its condition and manipulations as events, the answers as behavioural files,
acquisition times, each sample's clock, two participants' people as distinct subjects of one
dataset, the official validator, the toolkit reading it back, and the console's export
request."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import httpx
import numpy as np
import pytest
from test_lab_server import BEARER, TOKEN, status
from test_lab_study import QUESTIONS, AnsweringPage, create_participant, play_to_the_end

from mirror_avatar.cli import main
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread

PROTOCOL = f"""
title = "export study"
seed = 3
{QUESTIONS}
[[blocks]]
name = "partners"
order = "fixed"
after_block = ["remarks"]

[[blocks.conditions]]
name = "follow"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "bundled:slow" }},
]
leaders = ["A1"]
trials = 1
duration = 2
pause = 0.5
after_trial = ["partner", "confidence"]

[[blocks.conditions]]
name = "hidden"
game = "joint"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "P2", kind = "person" }},
]
trials = 1
duration = 3
pause = 0.5
delay = 0.3
occlude = [[1, 2]]
after_trial = ["partner"]
"""

PERTURBATION = {"sample": 40, "time_s": 1.2, "player": "A1", "change": "coupling: leader"}
"""A perturbation of the avatar, as the lab records one in a trial's sidecar."""


@dataclass
class Study:
    server: ServerThread
    sid: str
    folder: Path
    second: Path


def play(server: ServerThread, participant: int) -> str:
    """Play a participant's run of the protocol (follow, then hidden); return its session id."""
    created = create_participant(server.url, participant, BEARER)
    sid = created["id"]
    pages = [AnsweringPage(created["links"][label]) for label in ("P1", "P2")]
    play_to_the_end(server, sid, pages, force=True)
    return sid


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Study]:
    """Participants 0 and 1's runs of the protocol, played one after the other on the lab server.

    Exported alone, the ``folder`` of participant 0 has ``sub-p000P1`` and ``sub-p000P2``.
    """
    base = tmp_path_factory.mktemp("study")
    protocol_file = base / "export.toml"
    protocol_file.write_text(PROTOCOL)
    settings = LabSettings(
        out_dir=base / "out", token=TOKEN, countdown=1, protocol=load_protocol(protocol_file)
    )
    with ServerThread(create_lab_app(settings)) as server:
        sid, second = play(server, 0), play(server, 1)
        yield Study(server, sid, base / "out" / sid, base / "out" / second)


def rows_of(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle, delimiter="\t"))


def test_every_trial_is_a_run_with_its_condition_and_manipulations(study, tmp_path, capsys):
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(study.folder), "--out", str(bids)]) == 0
    assert "wrote 3 motion files" in capsys.readouterr().out  # P1 twice, P2 once
    acq = "exportp000"
    motion = sorted(p.relative_to(bids).as_posix() for p in bids.glob("sub-*/motion/*_motion.tsv"))
    assert motion == [
        f"sub-p000P1/motion/sub-p000P1_task-mirrorgame_tracksys-pointer_acq-{acq}_run-1_motion.tsv",
        f"sub-p000P1/motion/sub-p000P1_task-mirrorgame_tracksys-pointer_acq-{acq}_run-2_motion.tsv",
        f"sub-p000P2/motion/sub-p000P2_task-mirrorgame_tracksys-pointer_acq-{acq}_run-2_motion.tsv",
    ]
    follow = rows_of(next(bids.glob("sub-p000P1/motion/*run-1_events.tsv")))
    assert [(r["trial_type"], r["trial"], r["block"], r["condition"]) for r in follow] == [
        ("trial", "1", "partners", "follow")
    ]
    hidden = rows_of(next(bids.glob("sub-p000P2/motion/*run-2_events.tsv")))
    kinds = [r["trial_type"] for r in hidden]
    assert kinds[:3] == ["trial", "delay", "occlusion"]
    assert {r["condition"] for r in hidden} == {"hidden"}
    delay = hidden[1]
    assert (float(delay["onset"]), float(delay["delay_s"])) == (0.0, pytest.approx(0.3))
    occlusion = hidden[2]
    assert (float(occlusion["onset"]), float(occlusion["duration"])) == (1.0, 1.0)
    assert int(occlusion["sample"]) == 34  # the first sample at or after 1 s: 34 * 0.03 s
    sidecar = load_session(study.folder / "trial-02_session.csv").metadata
    lost = [(e["sample"], e["label"]) for e in sidecar["input_events"] if e["event"] == "lost"]
    assert [(int(r["sample"]), r["player"]) for r in hidden if r["trial_type"] == "input_lost"] == (
        sorted(lost)
    )


def test_answers_are_behavioural_files_beside_the_runs(study, tmp_path):
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(study.folder), "--out", str(bids)]) == 0
    (first,) = bids.glob("sub-p000P1/beh/sub-p000P1_task-mirrorgame_acq-exportp000_run-1_beh.tsv")
    rows = rows_of(first)
    assert [(r["question"], r["kind"], r["answer"], r["after"]) for r in rows] == [
        ("partner", "choice", "a computer", "trial"),
        ("confidence", "likert", "5", "trial"),
    ]
    assert rows[0]["text"] == "Was your partner a person or a computer?"
    assert {(r["trial"], r["block"], r["condition"]) for r in rows} == {("1", "partners", "follow")}
    recorded = json.loads((study.folder / "trial-01_answers.json").read_text())
    assert rows[1]["answered_utc"] == recorded["answers"]["P1"]["confidence"]["utc"]
    for label in ("P1", "P2"):  # the last trial of the block: its question and the block's
        (last,) = bids.glob(f"sub-p000{label}/beh/*_run-2_beh.tsv")
        assert [(r["question"], r["answer"], r["after"]) for r in rows_of(last)] == [
            ("partner", "a computer", "trial"), ("remarks", "smooth", "block")
        ]  # fmt: skip
    described = json.loads((bids / "task-mirrorgame_beh.json").read_text())
    assert set(described) == {"TaskName", *rows[0]}


def test_scans_give_each_runs_start_and_the_motion_every_samples_clock(study, tmp_path):
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(study.folder), "--out", str(bids)]) == 0
    scans = {r["filename"]: r for r in rows_of(bids / "sub-p000P1" / "sub-p000P1_scans.tsv")}
    assert len(scans) == 4  # two runs, each a motion and a beh file
    for n in (1, 2):
        metadata = load_session(study.folder / f"trial-{n:02d}_session.csv").metadata
        started = datetime.fromisoformat(metadata["started_utc"])
        created = datetime.fromisoformat(metadata["created_utc"])
        assert created <= started
        motion = next(name for name in scans if name.startswith("motion/") and f"run-{n}_" in name)
        stamp = scans[motion]["acq_time"]
        assert stamp.endswith("Z") and datetime.fromisoformat(stamp) == started
        inputs = np.genfromtxt(study.folder / f"trial-{n:02d}_inputs.csv", delimiter=",",
                               names=True)  # fmt: skip
        channels = rows_of(bids / "sub-p000P1" / motion.replace("_motion.tsv", "_channels.tsv"))
        names = [c["name"] for c in channels]
        values = np.loadtxt(bids / "sub-p000P1" / motion, delimiter="\t", ndmin=2)
        assert values.shape == (inputs.size, len(names))
        np.testing.assert_array_equal(values[:, names.index("clock")], inputs["clock_s"])
        np.testing.assert_allclose(
            values[:, names.index("latency")], inputs["clock_s"] - inputs["clock_s"][0], atol=5e-7
        )
        np.testing.assert_array_equal(values[:, names.index("late")], inputs["late_ms"])
        types = {c["name"]: (c["type"], c["units"]) for c in channels}
        assert types["latency"] == ("LATENCY", "s") and types["clock"] == ("MISC", "s")
        sidecar = json.loads((bids / "sub-p000P1" / motion.replace(".tsv", ".json")).read_text())
        assert sidecar["MirrorGame"]["clock_start_s"] == inputs["clock_s"][0]
        assert sidecar["MirrorGame"]["created_utc"] == metadata["created_utc"]
    copied = sorted(p.name for p in (bids / "sourcedata" / study.sid).iterdir())
    assert {"study.json", "trial-01_inputs.csv", "trial-02_answers.json"} <= set(copied)


def perturbed_copy(study: Study, tmp_path: Path) -> Path:
    """A copy of the study's folder whose first trial records a perturbation of its avatar."""
    folder = tmp_path / study.sid
    shutil.copytree(study.folder, folder)
    sidecar = folder / "trial-01_session.json"
    data = json.loads(sidecar.read_text())
    data["metadata"]["perturbations"] = [PERTURBATION]
    sidecar.write_text(json.dumps(data))
    return folder


def export_both(study: Study, bids: Path, first: Path | None = None) -> None:
    """Export participant 0's folder (or ``first``), then participant 1's, into ``bids``."""
    for folder in (first or study.folder, study.second):
        assert main(["lab", "export", str(folder), "--out", str(bids)]) == 0


SUBJECTS = ["sub-p000P1", "sub-p000P2", "sub-p001P1", "sub-p001P2"]
"""The people of participants 0 and 1: four subjects, though both runs label them P1 and P2."""


def test_two_participants_people_are_distinct_subjects_of_one_dataset(study, tmp_path):
    bids = tmp_path / "bids"
    export_both(study, bids)
    assert sorted(p.name for p in bids.glob("sub-*")) == SUBJECTS
    participants = rows_of(bids / "participants.tsv")
    assert [tuple(r.values()) for r in participants] == [
        (subject, subject[-2:], "pointer", str(int(subject[5:8])), "export") for subject in SUBJECTS
    ]
    assert list(participants[0]) == ["participant_id", "label", "device", "study_participant",
                                     "protocol"]  # fmt: skip
    described = json.loads((bids / "participants.json").read_text())
    assert set(described) == set(participants[0])
    for n, folder in enumerate((study.folder, study.second)):
        scans = rows_of(bids / f"sub-p00{n}P1" / f"sub-p00{n}P1_scans.tsv")
        assert len(scans) == 4 and all(f"acq-exportp00{n}_" in r["filename"] for r in scans)
        started = load_session(folder / "trial-01_session.csv").metadata["started_utc"]
        (first,) = [r for r in scans if r["filename"].endswith("run-1_motion.tsv")]
        assert datetime.fromisoformat(first["acq_time"]) == datetime.fromisoformat(started)
        (motion,) = bids.glob(f"sub-p00{n}P1/motion/*run-1_motion.tsv")
        np.testing.assert_array_equal(
            load_session(motion).positions, load_session(folder / "trial-01_session.csv").positions
        )
    assert sorted(p.name for p in (bids / "sourcedata").iterdir()) == [
        study.sid, study.second.name
    ]  # fmt: skip
    tables = {p: p.read_bytes() for p in bids.rglob("*.tsv") if "_scans" in p.name}
    tables[bids / "participants.tsv"] = (bids / "participants.tsv").read_bytes()
    assert main(["lab", "export", str(study.folder), "--out", str(bids)]) == 0
    assert {p: p.read_bytes() for p in tables} == tables  # exported again: nothing added


def test_a_perturbation_is_an_event_and_the_validator_finds_no_error(study, tmp_path):
    """Participants 0 (their first trial perturbed) and 1 exported into one dataset."""
    bids = tmp_path / "bids"
    export_both(study, bids, first=perturbed_copy(study, tmp_path))
    assert sorted(p.name for p in bids.glob("sub-*")) == SUBJECTS
    events = rows_of(next(bids.glob("sub-p000P1/motion/*run-1_events.tsv")))
    (change,) = [r for r in events if r["trial_type"] == "perturbation"]
    assert (change["onset"], change["sample"], change["player"], change["change"]) == (
        "1.2", "40", "A1", "coupling: leader"
    )  # fmt: skip
    validator = Path(sys.executable).parent / "bids-validator-deno"
    report = subprocess.run(
        [validator, str(bids), "--format", "json"], capture_output=True, text=True, timeout=300
    )
    found = json.loads(report.stdout)
    errors = [issue for issue in found["issues"]["issues"] if issue["severity"] == "error"]
    assert errors == [], errors[:3]
    warnings = {issue["code"] for issue in found["issues"]["issues"]}
    assert warnings <= {"NO_AUTHORS", "TOO_FEW_AUTHORS", "JSON_KEY_RECOMMENDED",
                        "SIDECAR_KEY_RECOMMENDED"}, warnings  # fmt: skip
    assert sorted(found["summary"]["dataTypes"]) == ["beh", "motion"]
    assert sorted(found["summary"]["subjects"]) == [subject[4:] for subject in SUBJECTS]


def test_convert_signature_and_evaluate_read_the_runs_apart(study, tmp_path, capsys):
    bids = tmp_path / "bids"
    export_both(study, bids)
    out = tmp_path / "converted"
    capsys.readouterr()
    assert main(["convert", str(bids), "--group-by", "bids", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for subject, runs in zip(SUBJECTS, (2, 1, 2, 1), strict=True):
        assert f"group '{subject}': {runs} trial(s)" in printed, printed
    converted = sorted(p.name for p in out.rglob("*.csv"))
    assert converted == [
        f"{subject}_task-mirrorgame_tracksys-pointer_acq-exportp{subject[5:8]}_run-{n}.csv"
        for subject in SUBJECTS
        for n in ((1, 2) if subject.endswith("P1") else (2,))
    ]
    signature = tmp_path / "signature"
    assert main(["signature", str(bids / "sub-p000P1"), "--group-by", "bids", "--out",
                 str(signature)]) == 0  # fmt: skip
    labels = json.loads((signature / "signature.json").read_text())["labels"]
    assert labels == [name.removesuffix(".csv") for name in converted[:2]]
    evaluated = tmp_path / "evaluated"
    runs = sorted(bids.glob("sub-p00*P1/motion/*_motion.tsv"))
    assert len(runs) == 4
    capsys.readouterr()
    assert main(["evaluate", *map(str, runs), "--out", str(evaluated)]) == 0
    table = capsys.readouterr().out
    assert all(run.name in table for run in runs), table
    for n in (1, 2):
        (motion,) = bids.glob(f"sub-p000P1/motion/*run-{n}_motion.tsv")
        back, recorded = (
            load_session(motion),
            load_session(study.folder / f"trial-{n:02d}_session.csv"),
        )
        np.testing.assert_array_equal(back.positions, recorded.positions)
        assert back.labels == recorded.labels
        assert back.metadata["bids"]["entities"]["run"] == str(n)
        assert back.metadata["lab"]["condition"] == recorded.metadata["lab"]["condition"]


def test_the_console_exports_the_session_into_the_lab_folder(study):
    url = f"{study.server.url}/api/sessions/{study.sid}/export"
    assert httpx.post(url, json={}).status_code == 403
    done = httpx.post(url, json={}, headers=BEARER)
    assert done.status_code == 200, done.text
    answer = done.json()
    folder = study.folder.parent / "bids"
    assert answer["folder"] == str(folder) and answer["motion_files"] == 3
    assert answer["files"] == sum(1 for p in folder.rglob("*") if p.is_file())
    assert len(list(folder.glob("sub-*/beh/*_beh.tsv"))) == 3
    second = httpx.post(url.replace(study.sid, study.second.name), json={}, headers=BEARER)
    assert second.status_code == 200 and second.json()["motion_files"] == 3
    assert sorted(p.name for p in folder.glob("sub-*")) == SUBJECTS
    named = httpx.post(url, json={"folder": "bids_2"}, headers=BEARER)
    assert named.status_code == 200 and named.json()["folder"] == str(folder.parent / "bids_2")
    for bad in ("../elsewhere", ".hidden", study.sid, "a/b"):
        refused = httpx.post(url, json={"folder": bad}, headers=BEARER)
        assert refused.status_code == 400 and refused.json()["error"].startswith("folder: ")
    assert not (study.folder.parent.parent / "elsewhere").exists()
    events = status(study.server, study.sid)["events"]
    assert any("exported 3 motion files" in event for event in events)


@pytest.mark.browser
def test_the_console_button_exports_the_session(study, chromium):
    """The researcher clicks Export BIDS on the console in Chromium; the dataset appears."""
    folder = study.folder.parent / "bids"
    shutil.rmtree(folder, ignore_errors=True)
    console = chromium.new_context(viewport={"width": 1280, "height": 1000}).new_page()
    try:
        console.goto(f"{study.server.url}/console?token={TOKEN}")
        console.click(f"#sessions-list a:has-text('{study.sid}')")
        console.wait_for_selector("#session:not([hidden])")
        console.wait_for_function("!document.getElementById('export').disabled")
        console.click("#export")
        console.wait_for_function(
            "document.getElementById('export-result').textContent.startsWith('exported') || "
            "document.getElementById('session-error').textContent !== ''"
        )
        assert console.locator("#session-error").inner_text() == ""
        shown = console.locator("#export-result").inner_text()
    finally:
        console.context.close()
    files = sum(1 for p in folder.rglob("*") if p.is_file())
    assert shown == f"exported 3 motion file(s); {folder} holds {files} files"
    assert len(list(folder.glob("sub-*/motion/*_motion.tsv"))) == 3
    assert len(list(folder.glob("sub-*/beh/*_beh.tsv"))) == 3


def test_samples_missing_from_a_cut_inputs_file_have_no_clock(study, tmp_path):
    """A crash between a sample's two lines: the inputs file lacks the last samples."""
    folder = tmp_path / study.sid
    shutil.copytree(study.folder, folder)
    inputs = folder / "trial-01_inputs.csv"
    lines = inputs.read_text().splitlines(keepends=True)
    inputs.write_text("".join(lines[:-3]) + lines[-3].split(",")[0] + ",")
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(folder), "--out", str(bids)]) == 0
    (motion,) = bids.glob("sub-p000P1/motion/*run-1_motion.tsv")
    names = [
        c["name"]
        for c in rows_of(motion.with_name(motion.name.replace("motion.tsv", "channels.tsv")))
    ]
    rows = [line.split("\t") for line in motion.read_text().splitlines()]
    clock = [row[names.index("clock")] for row in rows]
    assert clock[-3:] == ["n/a"] * 3 and "n/a" not in clock[:-3]
    assert len(rows) == load_session(folder / "trial-01_session.csv").n_samples
