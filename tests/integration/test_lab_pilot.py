"""`mirror-avatar lab pilot`: virtual participants play a protocol through the real lab server."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.lab.design.protocol import load_protocol
from waiting import wait_for

PROTOCOL = """
title = "Delay pilot"
seed = 7

[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]

[questions.sure]
text = "How sure are you?"
kind = "likert"
points = 5
anchors = ["guessing", "certain"]

[[blocks]]
name = "main"
order = "latin"

[[blocks.conditions]]
name = "nodelay"
game = "leader_follower"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:fast" },
]
leaders = ["A1"]
trials = 1
duration = 3
pause = 0
after_trial = ["partner", "sure"]

[[blocks.conditions]]
name = "delayed"
game = "leader_follower"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:fast" },
]
leaders = ["A1"]
trials = 1
duration = 3
pause = 0
delay = 0.5
"""


COMMAND = [sys.executable, "-c", "from mirror_avatar.console import run; run()"]


def run_command(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*COMMAND, *arguments],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip


@pytest.fixture(scope="module")
def piloted(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, subprocess.CompletedProcess[str]]:
    folder = tmp_path_factory.mktemp("pilot")
    protocol = folder / "delay.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    out = folder / "out"
    result = run_command(
        "lab", "pilot", "--protocol", str(protocol), "--participants", "2",
        "--stand-in", "P1=bundled:slow", "--answer", "partner=first", "--seed", "3",
        "--out", str(out),
    )  # fmt: skip
    return out, result


@pytest.mark.long
def test_a_pilot_records_every_participant_as_a_study_does(piloted):
    out, result = piloted
    assert result.returncode == 0, result.stderr
    assert "participant 0: finished" in result.stdout
    assert "participant 1: finished" in result.stdout
    for number in (0, 1):
        run = out / f"delay-p00{number}"
        study = json.loads((run / "study.json").read_text())
        assert study["participant"] == number
        sidecars = sorted(run.glob("trial-*_session.json"))
        assert len(sidecars) == 2
        conditions = [json.loads(s.read_text())["metadata"]["lab"] for s in sidecars]
        assert {c["protocol_condition"] for c in conditions} == {"nodelay", "delayed"}
        delays = {c["protocol_condition"]: c["partner_delay_s"] for c in conditions}
        assert delays["nodelay"] == 0.0
        assert delays["delayed"] == pytest.approx(0.51)


@pytest.mark.long
def test_the_stand_in_moves_the_person_s_point_from_its_page(piloted):
    out, _ = piloted
    for csv in sorted(out.glob("delay-p00*/trial-*_session.csv")):
        person = pd.read_csv(csv)["position_0"].to_numpy()
        assert np.all(np.isfinite(person)), csv
        assert person.std() > 0.01, f"{csv}: the stand-in's point did not move"
        inputs = pd.read_csv(csv.with_name(csv.name.replace("_session.csv", "_inputs.csv")))
        live = inputs[[c for c in inputs.columns if c.startswith("seq_")][0]].nunique()
        assert live > len(inputs) / 2, f"{csv}: most samples held the same pointer position"


@pytest.mark.long
def test_the_virtual_participants_answer_by_their_rules(piloted):
    out, _ = piloted
    answered = sorted(out.glob("delay-p00*/trial-*_answers.json"))
    assert len(answered) == 2
    for path in answered:
        answers = json.loads(path.read_text())["answers"]["P1"]
        assert answers["partner"]["value"] == "a person"
        assert answers["sure"]["value"] in range(1, 6)


@pytest.mark.long
def test_the_server_s_log_ends_as_finished_after_a_normal_pilot(piloted):
    out, result = piloted
    assert result.returncode == 0, result.stderr
    log = (out / "pilot-server.log").read_text()
    assert "aborted" not in log, log
    assert "Finished server process" in log.strip().splitlines()[-1], log


@pytest.mark.long
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_an_interrupted_pilot_ends_with_its_one_line(signum, tmp_path):
    protocol = tmp_path / "delay.toml"
    protocol.write_text(PROTOCOL.replace("duration = 3", "duration = 60"), encoding="utf-8")
    out = tmp_path / "out"
    arguments = ["lab", "pilot", "--protocol", str(protocol), "--participants", "1"]
    process = subprocess.Popen(
        [*COMMAND, *arguments, "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        wait_for(
            lambda: any(out.glob("delay-p000/trial-*")) or process.poll() is not None,
            timeout=300,
            what="the first trial to be recorded, the stand-in's page playing it",
        )
        process.send_signal(signum)
        _, stderr = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr, stderr
    assert stderr.strip() == f"mirror-avatar: aborted ({signum.name})"
    assert "aborted" in (out / "pilot-server.log").read_text().strip().splitlines()[-1]


@pytest.mark.long
def test_a_resumed_pilot_refuses_a_trial_whose_recording_was_deleted(piloted, tmp_path):
    """Participant 0's second recording deleted, its sidecar kept: resuming their run names the
    recording in one line, never counts the trial as played, and plays nothing."""
    out, _ = piloted
    copy = tmp_path / "out"
    shutil.copytree(out / "delay-p000", copy / "delay-p000")
    (copy / "delay-p000" / "trial-02_session.csv").unlink()
    protocol = tmp_path / "delay.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    result = run_command(
        "lab", "pilot", "--protocol", str(protocol), "--participants", "1",
        "--stand-in", "P1=bundled:slow", "--out", str(copy),
    )  # fmt: skip
    assert result.returncode == 2, result.stdout
    assert result.stderr.strip().count("\n") == 0, result.stderr
    assert "trial-02_session.csv: missing, but trial 2's other files" in result.stderr
    assert "complete" not in result.stdout
    assert not (copy / "delay-p000" / "trial-02_session.csv").exists()


def played(out: Path) -> dict[str, dict[str, Any]]:
    """Return each run folder's trials: their conditions and the answers given, by trial file."""
    return {
        run.name: {
            sidecar.name: (
                json.loads(sidecar.read_text())["metadata"]["lab"]["protocol_condition"],
                answer_values(sidecar.with_name(sidecar.name.replace("_session", "_answers"))),
            )
            for sidecar in sorted(run.glob("trial-*_session.json"))
        }
        for run in sorted(out.glob("delay-p*"))
    }


def answer_values(path: Path) -> dict[str, dict[str, Any]] | None:
    """Return a trial's answers by person and question (their values, not their times)."""
    if not path.exists():
        return None
    answers = json.loads(path.read_text())["answers"]
    return {person: {q: a["value"] for q, a in given.items()} for person, given in answers.items()}


def session_events(log: Path) -> list[tuple[str, str]]:
    """Return the sessions' events in a pilot's server log, in order: (run, event)."""
    return re.findall(r"session (\S+): (.+)$", log.read_text(), flags=re.MULTILINE)


@pytest.mark.long
def test_participants_piloted_at_once_play_what_they_play_in_turn(tmp_path):
    protocol = tmp_path / "delay.toml"
    protocol.write_text(PROTOCOL.replace("duration = 3", "duration = 2"), encoding="utf-8")
    runs = {}
    for at_once in (1, 2):
        out = tmp_path / f"at-once-{at_once}"
        result = run_command(
            "lab", "pilot", "--protocol", str(protocol), "--participants", "4", "--seed", "8",
            "--at-once", str(at_once), "--out", str(out),
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
        assert result.stdout.count(": finished, 2 of 2 trial(s) complete") == 4, result.stdout
        runs[at_once] = played(out)
        events = session_events(out / "pilot-server.log")
        ended = [run for run, event in events if event == "all trials played"]
        assert sorted(ended) == [f"delay-p00{n}" for n in range(4)], events
        # a run plays from its first trial's start to the end of its last: at most N at once,
        # and N at some moment
        playing: set[str] = set()
        most = 0
        for run, event in events:
            if event == "trial 1 started":
                playing.add(run)
                most = max(most, len(playing))
            elif event == "all trials played":
                playing.discard(run)
        assert most == at_once, events
    # the same runs, trials, conditions in the same order and answers (each stand-in's seed is
    # its participant's, whoever plays beside it)
    assert runs[2] == runs[1]
    assert all(len(trials) == 2 for trials in runs[1].values()), runs[1]


def test_a_stand_in_for_nobody_is_refused_in_one_line(tmp_path):
    protocol = tmp_path / "delay.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    result = run_command(
        "lab", "pilot", "--protocol", str(protocol), "--stand-in", "P9=bundled:slow",
        "--out", str(tmp_path / "out"),
    )  # fmt: skip
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0, result.stderr
    assert "P9" in result.stderr and "P1" in result.stderr


ROOT = Path(__file__).parents[2]
TEMPLATES = sorted((ROOT / "examples" / "protocols").glob("*.toml"))


def rehearsal(template: Path, folder: Path, duration: float = 2.0) -> Path:
    """Copy a template with every trial shortened to ``duration`` (s), one per condition, and no
    pauses.

    Its specs' paths, relative to the repository's root where the lab runs from, are made
    absolute, so that the copy runs from any folder.
    """
    text = template.read_text(encoding="utf-8")
    for key, value in (("duration", f"{duration:g}"), ("trials", "1"), ("pause", "0")):
        text = re.sub(rf"^{key} = .*$", f"{key} = {value}", text, flags=re.MULTILINE)
    text = text.replace('spec = "examples/', f'spec = "{ROOT.as_posix()}/examples/')
    copy = folder / template.name
    copy.write_text(text, encoding="utf-8")
    return copy


def test_the_field_s_designs_are_templates():
    assert [t.stem for t in TEMPLATES] == [
        "brezis2017", "delay_handling", "llobera2022", "online", "slowinski2017", "turing"
    ]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("template", TEMPLATES, ids=lambda t: t.stem)
def test_each_template_is_piloted_through_the_server(template, tmp_path):
    protocol = load_protocol(template)
    out = tmp_path / "out"
    result = run_command(
        "lab", "pilot", "--protocol", str(rehearsal(template, tmp_path)), "--participants", "2",
        "--seed", "5", "--out", str(out),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    conditions = [c.name for block in protocol.blocks for c in block.conditions]
    for run in sorted(out.glob("*-p00*")):
        sidecars = sorted(run.glob("trial-*_session.json"))
        played = [
            json.loads(s.read_text())["metadata"]["lab"]["protocol_condition"] for s in sidecars
        ]
        assert sorted(played) == sorted(conditions), run
        for sidecar in sidecars:
            assert json.loads(sidecar.read_text())["metadata"]["complete"], sidecar


def _huge_file(folder: Path) -> str:
    huge = folder / "huge.csv"
    with huge.open("wb") as handle:
        handle.truncate(2 * 2**30)  # sparse: 2 GB on paper, nothing on disk
    return str(huge)


def _fifo(folder: Path) -> str:
    fifo = folder / "pipe.csv"
    os.mkfifo(fifo)
    return str(fifo)


HOSTILE_STAND_INS = {
    "device": (lambda folder: "/dev/zero", "character device"),
    "fifo": (_fifo, "named pipe"),
    "huge file": (_huge_file, "over the limit"),
    "out of range": (lambda folder: "kuramoto:coupling=1e308", "coupling"),
    "process file": (lambda folder: "/proc/self/environ", "/proc/self/environ"),
}


@pytest.mark.long
@pytest.mark.parametrize("kind", HOSTILE_STAND_INS)
def test_a_stand_in_that_cannot_play_is_refused_before_anything_starts(kind, tmp_path):
    make, problem = HOSTILE_STAND_INS[kind]
    protocol = tmp_path / "delay.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    out = tmp_path / "out"
    result = run_command(
        "lab", "pilot", "--protocol", str(protocol), "--stand-in", f"P1={make(tmp_path)}",
        "--out", str(out),
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    error = result.stderr.strip()
    assert error.count("\n") == 0, error
    assert "--stand-in" in error and "P1=" in error and problem in error, error
    assert not out.exists(), "the server started for a stand-in that cannot play"
