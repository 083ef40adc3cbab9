"""Resuming a participant's run from a hostile or damaged folder: one line each, nothing read
beyond its bound, and a gap in the trials refused rather than played out of order."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_io import MAX_SIDECAR_BYTES
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.study import ParticipantRun, study_folder

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"


def _session(tmp_path: Path, participant: int = 0) -> LabSession:
    protocol = load_protocol(EXAMPLE)
    folder = tmp_path / study_folder(protocol, participant)
    return LabSession(folder.name, ParticipantRun(protocol, participant), folder, time.monotonic)


def _folder_with(tmp_path: Path, participant: int = 0) -> Path:
    folder = tmp_path / study_folder(load_protocol(EXAMPLE), participant)
    folder.mkdir()
    return folder


def test_a_fifo_study_json_is_refused_without_waiting_for_a_writer(tmp_path):
    os.mkfifo(_folder_with(tmp_path) / "study.json")
    with pytest.raises(InputError, match=r"study\.json: .*named pipe \(FIFO\)") as refused:
        _session(tmp_path)
    assert "\n" not in str(refused.value)


def test_a_huge_study_json_is_refused_before_it_is_read(tmp_path):
    with (_folder_with(tmp_path) / "study.json").open("wb") as file:
        file.truncate(600 * 2**20)  # sparse: its size is real, its blocks are not
    with pytest.raises(InputError, match=f"over the limit of {MAX_SIDECAR_BYTES:,} bytes"):
        _session(tmp_path)


def test_a_deeply_nested_study_json_is_refused_in_one_line(tmp_path):
    (_folder_with(tmp_path) / "study.json").write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(InputError, match="nested deeper than the limit"):
        _session(tmp_path)


HEAD = '{"seed": 20261125, "participant": 0, '


@pytest.mark.parametrize("text", ["[1, 2]", HEAD + '"order": 3}', HEAD + '"order": [1]}'])
def test_a_study_json_of_another_shape_is_refused_in_one_line(tmp_path, text):
    (_folder_with(tmp_path) / "study.json").write_text(text)
    with pytest.raises(InputError, match=r"study\.json: (this folder holds no readable study|"
                       "recorded with another order)"):  # fmt: skip
        _session(tmp_path)


def test_a_run_with_a_trial_missing_before_a_recorded_one_is_refused_naming_the_gap(tmp_path):
    session = _session(tmp_path)
    (session.directory / "trial-02_session.csv").write_text("t\n")
    with pytest.raises(InputError, match=r"p000: trial 1 has no files \(trial-01_\*\) but trial 2"):
        _session(tmp_path)
    (session.directory / "trial-01_session.csv").write_text("t\n")
    (session.directory / "trial-04_session.csv").write_text("t\n")
    with pytest.raises(InputError, match="trial 3 has no files"):
        _session(tmp_path)
    (session.directory / "trial-03_session.csv").write_text("t\n")
    assert _session(tmp_path).next_trial == 5


def test_a_trial_whose_recording_is_missing_is_refused_never_counted_as_played(tmp_path):
    """Its sidecar (record) and inputs kept, its recording deleted: resume names the recording."""
    directory = _session(tmp_path).directory
    for n in (1, 2, 3):
        for suffix in ("_session.csv", "_session.json", "_inputs.csv"):
            (directory / f"trial-{n:02d}{suffix}").write_text("t\n")
    (directory / "trial-02_session.csv").unlink()
    with pytest.raises(InputError, match=r"trial-02_session\.csv: missing, but trial 2's other "
                       "files .* or move the folder away") as refused:  # fmt: skip
        _session(tmp_path)
    assert "\n" not in str(refused.value)
    (directory / "trial-02_session.csv").write_text("t\n")
    (directory / "trial-03_session.csv").unlink()
    with pytest.raises(InputError, match=r"trial-03_session\.csv: .*move its other files away"):
        _session(tmp_path)
    for leftover in directory.glob("trial-03_*"):
        leftover.unlink()
    assert _session(tmp_path).next_trial == 3
