"""Tests of the BIDS-Motion export of lab sessions and of reading a trial back from it."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.reading import read_lab_recording
from mirror_avatar.files.bids.writing import write_bids_motion
from mirror_avatar.files.trial_files import read_trial
from mirror_avatar.files.trial_record import SlotRecord, StudyRecord, TrialRecord
from mirror_avatar.files.trials import make_trial
from mirror_avatar.lab.export.bids import export_bids, without_folders
from mirror_avatar.sessions.graphs import complete_graph, ring_graph
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session
from mirror_avatar.sessions.writer import SessionWriter

T = 0.03
N_SAMPLES = 300

MOTION_FILE = re.compile(
    r"sub-(?P<sub>[A-Za-z0-9]+)/motion/"
    r"sub-(?P=sub)(_ses-[A-Za-z0-9]+)?_task-(?P<task>[A-Za-z0-9]+)"
    r"_tracksys-(?P<tracksys>[A-Za-z0-9]+)(_acq-(?P<acq>[A-Za-z0-9]+))?(_run-(?P<run>[0-9]+))?"
    r"_(?P<suffix>motion|channels|events)\.(?P<ext>tsv|json)"
)
"""BIDS 1.9 motion: sub-<label>[_ses-<label>]_task-<label>_tracksys-<label>[_acq-<label>]
[_run-<index>]_<motion.tsv|motion.json|channels.tsv>, in sub-<label>/motion/."""

TOP_LEVEL = {
    "dataset_description.json", "README", "participants.tsv", "participants.json",
    "task-mirrorgame_events.json", "scans.json",
}  # fmt: skip
REQUIRED_SIDECAR = {
    "TaskName", "TaskDescription", "SamplingFrequency", "TrackingSystemName",
    "MotionChannelCount", "POSChannelCount", "VELChannelCount", "RecordingDuration",
    "RecordingType", "SubjectArtefactDescription", "MirrorGame",
}  # fmt: skip
GAME_KEYS = {
    "lab", "participant", "slot", "graph", "complete", "dropped", "held", "seed", "perturbations",
}  # fmt: skip


def slot(label: str, kind: str, role: str, device: str | None = None) -> dict[str, Any]:
    spec = "ims:seed=3" if kind == "avatar" else None
    return {"label": label, "kind": kind, "role": role, "spec": spec, "device": device}


@dataclass
class LabTrial:
    number: int
    slots: list[dict[str, Any]]
    graph: np.ndarray
    condition: str
    complete: bool = True
    dropped: dict[str, int] | None = None
    crash: bool = False


def write_lab_session(
    folder: Path, session_id: str, trials: list[LabTrial], seed: int,
    study: StudyRecord | None = None,
) -> Path:  # fmt: skip
    """Record a lab session folder as the lab does: one SessionWriter per trial.

    Each sidecar's metadata is written by the trial record (`mirror_avatar.files.trial_record`), the
    one declaration of its format: a key renamed there and not in the export breaks these tests.
    """
    folder = folder / session_id
    folder.mkdir(parents=True)
    (folder / "plan.json").write_text(json.dumps({"session_id": session_id}))
    rng = np.random.default_rng(seed)
    for trial in trials:
        labels = [s["label"] for s in trial.slots]
        record = TrialRecord(
            session_id=session_id,
            trial=trial.number,
            condition=trial.condition,
            slots=tuple(SlotRecord(**s) for s in trial.slots),
            study=study,
            seed=seed,
            created_utc="2025-03-01T10:00:00+00:00",
        )
        path = folder / f"trial-{trial.number:02d}_session.csv"
        writer = SessionWriter(path, labels, [s["role"] for s in trial.slots], trial.graph, T,
                               record.metadata_json())  # fmt: skip
        for row in session_rows(rng, len(labels)):
            writer.append(row)
        held = {s["label"]: int(rng.integers(0, 5)) for s in trial.slots if s["kind"] == "human"}
        writer.close(trial.complete, {"dropped": trial.dropped or {}, "held": held})
        if trial.crash:
            with path.open("a", encoding="utf-8") as handle:
                handle.write("9.0,0.1,0.2")
    return folder


def session_rows(rng: np.random.Generator, n_players: int) -> np.ndarray:
    """Rows time, then position, velocity, control, reference per player: sines plus noise."""
    t = np.arange(N_SAMPLES) * T
    frequency = rng.uniform(0.2, 0.6, (n_players, 1))
    phase = rng.uniform(0, 2 * np.pi, (n_players, 1))
    x = 0.3 * np.sin(2 * np.pi * frequency * t + phase) + 0.01 * rng.normal(
        size=(n_players, t.size)
    )
    v = 0.3 * 2 * np.pi * frequency * np.cos(2 * np.pi * frequency * t + phase)
    v += 0.05 * rng.normal(size=v.shape)
    controls = rng.normal(size=x.shape)
    controls[:, -1] = np.nan
    references = np.full(x.shape, np.nan)
    channels = np.stack([x, v, controls, references], axis=1).reshape(4 * n_players, -1)
    return np.column_stack([t, channels.T])


def dyad_trials() -> list[LabTrial]:
    slots = [slot("P_1", "human", "leader", "pointer"), slot("avatar1", "avatar", "follower")]
    return [LabTrial(n, slots, complete_graph(2), "leader_follower") for n in (1, 2)]


def ring_trials() -> list[LabTrial]:
    slots = [
        slot("P_1", "human", "joint", "lsl"),
        slot("av-a", "avatar", "joint"),
        slot("P2", "human", "joint", "pointer"),
        slot("av-b", "avatar", "joint"),
    ]
    return [
        LabTrial(1, slots, ring_graph(4), "group"),
        LabTrial(2, slots, ring_graph(4), "group", complete=False, dropped={"P2": 150}, crash=True),
    ]


@dataclass
class Exported:
    root: Path
    dyad: Path
    ring: Path
    written: list[Path]


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Exported:
    base = tmp_path_factory.mktemp("lab")
    dyad = write_lab_session(base / "out", "2025-03-01_dyad", dyad_trials(), seed=11)
    ring = write_lab_session(base / "out", "2025-03-02_ring", ring_trials(), seed=12)
    root = base / "bids"
    written = export_bids(dyad, root) + export_bids(ring, root)
    return Exported(root, dyad, ring, written)


def source_of(motion: Path, exported: Exported) -> Session:
    info = json.loads(motion.with_name(motion.name.replace(".tsv", ".json")).read_text())
    game = info["MirrorGame"]
    folder = exported.dyad if game["lab"]["session_id"].endswith("dyad") else exported.ring
    return load_session(folder / f"trial-{game['lab']['trial']:02d}_session.csv")


def test_every_human_gets_a_file_per_trial_named_as_bids_says(exported: Exported) -> None:
    names = sorted(p.relative_to(exported.root).as_posix() for p in exported.written)
    assert len(names) == 6
    expected = {
        ("P1", "pointer", "20250301dyad", "1"), ("P1", "pointer", "20250301dyad", "2"),
        ("P1", "lsl", "20250302ring", "1"), ("P1", "lsl", "20250302ring", "2"),
        ("P2", "pointer", "20250302ring", "1"), ("P2", "pointer", "20250302ring", "2"),
    }  # fmt: skip
    found = set()
    for name in names:
        match = MOTION_FILE.fullmatch(name)
        assert match is not None, name
        assert match["task"] == "mirrorgame" and match["suffix"] == "motion"
        found.add((match["sub"], match["tracksys"], match["acq"], match["run"]))
    assert found == expected


def test_the_dataset_holds_only_bids_files_and_the_source_data(exported: Exported) -> None:
    files = [p.relative_to(exported.root) for p in exported.root.rglob("*") if p.is_file()]
    outside = {
        p.as_posix() for p in files if p.parts[0] not in ("sourcedata",) and len(p.parts) > 2
    }
    assert all(MOTION_FILE.fullmatch(name) for name in outside), sorted(outside)
    assert len(outside) == 4 * 6
    scans = {p.as_posix() for p in files if len(p.parts) == 2 and p.parts[0] != "sourcedata"}
    assert scans == {"sub-P1/sub-P1_scans.tsv", "sub-P2/sub-P2_scans.tsv"}
    assert {p.name for p in files if len(p.parts) == 1} == TOP_LEVEL
    assert sorted(p.name for p in exported.root.iterdir() if p.is_dir()) == [
        "sourcedata", "sub-P1", "sub-P2"
    ]  # fmt: skip
    assert not any("av" in p.as_posix().lower() for p in files if p.parts[0] != "sourcedata")


def test_source_data_are_copies_of_the_trial_files(exported: Exported) -> None:
    for folder in (exported.dyad, exported.ring):
        copies = exported.root / "sourcedata" / folder.name
        originals = sorted(folder.iterdir())
        assert sorted(p.name for p in copies.iterdir()) == [p.name for p in originals]
        for original in originals:
            assert (copies / original.name).read_bytes() == original.read_bytes()


def test_round_trip_is_exact(exported: Exported) -> None:
    for motion in exported.written:
        back = load_session(motion)
        source = source_of(motion, exported)
        np.testing.assert_array_equal(back.positions, source.positions)
        np.testing.assert_array_equal(back.velocities, source.velocities)
        np.testing.assert_array_equal(back.times, source.times)
        np.testing.assert_array_equal(back.graph, source.graph)
        assert np.isnan(back.controls).all() and np.isnan(back.references).all()
        assert back.labels == source.labels and back.roles == source.roles
        assert back.period == source.period == T
        assert back.metadata["lab"] == source.metadata["lab"]
        for key in ("complete", "dropped", "held", "seed"):
            assert back.metadata[key] == source.metadata[key], key


def test_values_are_written_exactly(exported: Exported) -> None:
    motion = exported.written[0]
    first = motion.read_text().splitlines()[0].split("\t")
    source = source_of(motion, exported)
    assert first[:2] == [repr(float(source.positions[0, 0])), repr(float(source.velocities[0, 0]))]
    assert len(first) == 4 and "n/a" not in first


def test_read_trial_gives_the_participants_own_position(exported: Exported) -> None:
    for motion in exported.written:
        game = json.loads(motion.with_name(motion.name.replace(".tsv", ".json")).read_text())
        index = game["MirrorGame"]["slot"]
        trial = read_trial(motion)
        source = source_of(motion, exported)
        np.testing.assert_array_equal(trial.positions, source.positions[index])
        assert trial.times.size == source.n_samples


def test_an_incomplete_trial_is_exported_as_recorded_with_its_drop(exported: Exported) -> None:
    incomplete = [p for p in exported.written if "ring_run-2" in p.name]
    assert len(incomplete) == 2
    for motion in incomplete:
        assert len(motion.read_text().splitlines()) == N_SAMPLES
        info = json.loads(motion.with_name(motion.name.replace(".tsv", ".json")).read_text())
        assert info["MirrorGame"]["complete"] is False
        assert info["MirrorGame"]["dropped"] == {"P2": 150}
        assert "P2" in info["SubjectArtefactDescription"]
        assert "150" in info["SubjectArtefactDescription"]
        assert load_session(motion).metadata["complete"] is False
    complete = next(p for p in exported.written if "dyad_run-1" in p.name)
    info = json.loads(complete.with_name(complete.name.replace(".tsv", ".json")).read_text())
    assert info["SubjectArtefactDescription"] == "n/a"
    assert info["MirrorGame"]["complete"] is True


def test_sidecar_holds_the_required_keys(exported: Exported) -> None:
    for motion in exported.written:
        info = json.loads(motion.with_name(motion.name.replace(".tsv", ".json")).read_text())
        assert set(info) >= REQUIRED_SIDECAR
        assert set(info["MirrorGame"]) >= GAME_KEYS
        assert info["TaskName"] == "mirrorgame"
        assert info["SamplingFrequency"] == pytest.approx(33.333333333333)
        assert 1.0 / info["SamplingFrequency"] == T
        assert info["RecordingType"] == "continuous"
        assert info["RecordingDuration"] == pytest.approx(N_SAMPLES * T)
        n_players = len(info["MirrorGame"]["lab"]["slots"])
        assert info["MotionChannelCount"] == 2 * n_players
        assert info["POSChannelCount"] == info["VELChannelCount"] == n_players
        assert info["TrackingSystemName"] in ("pointer", "lsl")
        assert f"tracksys-{info['TrackingSystemName']}_" in motion.name
        slots = info["MirrorGame"]["lab"]["slots"]
        assert slots[info["MirrorGame"]["slot"]]["label"] == info["MirrorGame"]["participant"]
        assert {s["kind"] for s in slots} == {"human", "avatar"}
        assert all(s["spec"] for s in slots if s["kind"] == "avatar")


def test_channels_file_names_every_players_position_and_velocity(exported: Exported) -> None:
    motion = next(p for p in exported.written if p.name.startswith("sub-P2") and "run-1" in p.name)
    lines = motion.with_name(motion.name.replace("_motion.tsv", "_channels.tsv")).read_text()
    rows = [line.split("\t") for line in lines.splitlines()]
    assert rows[0] == ["name", "component", "type", "tracked_point", "units", "description"]
    assert [r[0] for r in rows[1:]] == [
        "position", "velocity", "position_P_1", "velocity_P_1", "position_av-a", "velocity_av-a",
        "position_av-b", "velocity_av-b",
    ]  # fmt: skip
    assert [r[2] for r in rows[1:]] == ["POS", "VEL"] * 4
    assert {r[1] for r in rows[1:]} == {"x"} and {r[4] for r in rows[1:]} == {"n/a"}
    assert [r[3] for r in rows[1::2]] == ["P2", "P_1", "av-a", "av-b"]
    assert "-0.5..0.5" in rows[1][5] and "per second" in rows[2][5]
    widths = {len(line.split("\t")) for line in motion.read_text().splitlines()}
    assert widths == {len(rows) - 1}


def test_dataset_description_and_participants(exported: Exported) -> None:
    description = json.loads((exported.root / "dataset_description.json").read_text())
    assert description["BIDSVersion"] == "1.9.0" and description["DatasetType"] == "raw"
    assert description["GeneratedBy"][0]["Name"] == "mirror-avatar"
    table = (exported.root / "participants.tsv").read_text()
    rows = [line.split("\t") for line in table.splitlines()]
    assert rows == [
        ["participant_id", "label", "device"],
        ["sub-P1", "P_1", "lsl,pointer"],
        ["sub-P2", "P2", "pointer"],
    ]
    described = json.loads((exported.root / "participants.json").read_text())
    assert set(described) == {"participant_id", "label", "device"}
    assert "mirror" in (exported.root / "README").read_text().lower()


def test_exporting_again_merges_without_duplicates(exported: Exported, tmp_path: Path) -> None:
    root = tmp_path / "bids"
    first = export_bids(exported.ring, root)
    table = (root / "participants.tsv").read_text()
    assert first == export_bids(exported.ring, root)
    assert (root / "participants.tsv").read_text() == table
    export_bids(exported.dyad, root)
    ids = [line.split("\t")[0] for line in (root / "participants.tsv").read_text().splitlines()]
    assert ids == ["participant_id", "sub-P1", "sub-P2"]


def test_missing_or_empty_folders_are_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such folder"):
        export_bids(tmp_path / "nowhere", tmp_path / "bids")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no trial file"):
        export_bids(tmp_path / "empty", tmp_path / "bids")
    assert not (tmp_path / "bids").exists()


def test_two_participants_with_one_bids_label_are_refused(tmp_path: Path) -> None:
    slots = [slot("a_b", "human", "joint", "pointer"), slot("ab", "human", "joint", "lsl")]
    folder = write_lab_session(tmp_path, "s1", [LabTrial(1, slots, complete_graph(2), "joint")], 1)
    with pytest.raises(InputError, match="sub-ab"):
        export_bids(folder, tmp_path / "bids")
    assert not (tmp_path / "bids").exists()


def test_a_new_label_for_an_exported_participant_id_is_refused(
    exported: Exported, tmp_path: Path
) -> None:
    root = tmp_path / "bids"
    export_bids(exported.dyad, root)
    slots = [slot("P-1", "human", "leader", "pointer"), slot("x", "avatar", "follower")]
    trial = LabTrial(1, slots, complete_graph(2), "leader_follower")
    folder = write_lab_session(tmp_path, "s2", [trial], 2)
    with pytest.raises(InputError, match="sub-P1"):
        export_bids(folder, root)


def test_a_motion_file_without_the_mirror_game_key_is_another_tools(tmp_path: Path) -> None:
    t = np.arange(100) * T
    path = tmp_path / "sub-01_task-mirror_tracksys-pointer_motion.tsv"
    write_bids_motion(make_trial(t, 0.2 * np.sin(t), label="mirror"), path)
    with pytest.raises(InputError, match="not a mirror-avatar lab export.*signature"):
        read_lab_recording(path)
    session = load_session(path)  # one player: its one position channel
    assert session.n_players == 1
    np.testing.assert_allclose(session.positions[0], 0.2 * np.sin(t), atol=1e-12)


@pytest.mark.parametrize(
    ("damage", "problem"),
    [
        (lambda rows: rows[:-2], "missing channel.*av-b"),
        (lambda rows: [*rows, rows[-1]], "two channels share a name"),
    ],
)
def test_damaged_channels_are_refused(
    exported: Exported, tmp_path: Path, damage: Any, problem: str
) -> None:
    motion = copy_recording(exported, tmp_path)
    channels = motion.with_name(motion.name.replace("_motion.tsv", "_channels.tsv"))
    lines = channels.read_text().splitlines()
    channels.write_text("\n".join([lines[0], *damage(lines[1:])]) + "\n")
    if "missing" in problem:
        motion.write_text("".join("\t".join(r.split("\t")[:-2]) + "\n"
                                  for r in motion.read_text().splitlines()))  # fmt: skip
    with pytest.raises(InputError, match=problem):
        load_session(motion)


def test_rows_of_the_wrong_width_are_refused(exported: Exported, tmp_path: Path) -> None:
    motion = copy_recording(exported, tmp_path)
    lines = motion.read_text().splitlines()
    lines[4] += "\t0.5"
    motion.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="row 5 has 9 values"):
        load_session(motion)


def copy_recording(exported: Exported, folder: Path) -> Path:
    """Copy a ring recording's three files to ``folder``; return the motion file."""
    motion = next(p for p in exported.written if p.name.startswith("sub-P2") and "run-1" in p.name)
    stem = motion.name.removesuffix("_motion.tsv")
    for suffix in ("_motion.tsv", "_motion.json", "_channels.tsv"):
        (folder / f"{stem}{suffix}").write_bytes(motion.with_name(f"{stem}{suffix}").read_bytes())
    return folder / motion.name


def test_each_subject_lists_its_recordings_with_their_acquisition_time(exported: Exported) -> None:
    lines = (exported.root / "sub-P2" / "sub-P2_scans.tsv").read_text().splitlines()
    assert lines[0].split("\t") == ["filename", "acq_time", "trial", "block", "condition"]
    rows = [dict(zip(lines[0].split("\t"), line.split("\t"), strict=True)) for line in lines[1:]]
    assert [row["filename"] for row in rows] == [
        f"motion/sub-P2_task-mirrorgame_tracksys-pointer_acq-20250302ring_run-{n}_motion.tsv"
        for n in (1, 2)
    ]
    assert {row["acq_time"] for row in rows} == {"2025-03-01T10:00:00.000000Z"}
    assert [(row["trial"], row["block"], row["condition"]) for row in rows] == [
        ("1", "n/a", "group"), ("2", "n/a", "group")
    ]  # fmt: skip


def write_study_session(
    folder: Path, protocol: str, participant: int, labels: tuple[str, ...], seed: int
) -> Path:
    """Record a study session folder ``<protocol>-p<participant>``: its trials and study.json."""
    slots = [slot(label, "human", "joint", "pointer") for label in labels]
    session_id = f"{protocol}-p{participant:03d}"
    slots.append(slot("A1", "avatar", "joint"))
    trial = LabTrial(1, slots, complete_graph(len(slots)), "group")
    partners = {s["label"]: s["kind"] for s in slots}
    run = StudyRecord(protocol, participant, "b", "c", 1, 0.0, (), partners)
    session = write_lab_session(folder, session_id, [trial], seed, run)
    (session / "plan.json").unlink()
    study = {"id": session_id, "protocol": {"source": f"/lab/{protocol}.toml", "title": "t"},
             "seed": 3, "participant": participant, "order": []}  # fmt: skip
    (session / "study.json").write_text(json.dumps(study))
    return session


def participants_of(root: Path) -> list[list[str]]:
    return [line.split("\t") for line in (root / "participants.tsv").read_text().splitlines()]


def test_a_studys_people_are_subjects_of_their_participant(
    exported: Exported, tmp_path: Path
) -> None:
    """Participants 3 and 12 both have P_1 and P2: four subjects, beside a plain session's."""
    root = tmp_path / "bids"
    export_bids(exported.dyad, root)
    written = [
        path.relative_to(root).as_posix()
        for participant in (3, 12)
        for path in export_bids(
            write_study_session(tmp_path, "pilot", participant, ("P_1", "P2"), participant), root
        )
    ]
    assert [name.split("_task")[0] for name in written] == [
        f"{subject}/motion/{subject}" for subject in ("sub-p003P1", "sub-p003P2", "sub-p012P1",
                                                      "sub-p012P2")
    ]  # fmt: skip
    assert all(MOTION_FILE.fullmatch(name) for name in written)
    assert participants_of(root) == [
        ["participant_id", "label", "device", "study_participant", "protocol"],
        ["sub-P1", "P_1", "pointer", "n/a", "n/a"],
        ["sub-p003P1", "P_1", "pointer", "3", "pilot"],
        ["sub-p003P2", "P2", "pointer", "3", "pilot"],
        ["sub-p012P1", "P_1", "pointer", "12", "pilot"],
        ["sub-p012P2", "P2", "pointer", "12", "pilot"],
    ]
    described = json.loads((root / "participants.json").read_text())
    assert set(described) == set(participants_of(root)[0])
    scans = (root / "sub-p012P2" / "sub-p012P2_scans.tsv").read_text()
    assert "motion/sub-p012P2_task-mirrorgame_tracksys-pointer_acq-pilotp012_run-1" in scans


def test_a_plain_sessions_participants_get_no_study_columns(exported: Exported) -> None:
    assert participants_of(exported.root)[0] == ["participant_id", "label", "device"]


@pytest.mark.parametrize(
    ("first", "second", "subject"),
    [
        (("pilot", 3, ("P1",)), ("pilot", 3, ("P_1",)), "sub-p003P1"),  # another label
        (("pilot", 100, ("0P1",)), ("pilot", 1000, ("P1",)), "sub-p1000P1"),  # digits run on
        (("pilot", 3, ("P1",)), ("main", 3, ("P1",)), "sub-p003P1"),  # another protocol
        (None, ("pilot", 3, ("P1",)), "sub-p003P1"),  # a plain session's p003P1
    ],
)
def test_two_people_with_one_subject_label_are_refused(
    tmp_path: Path, first: Any, second: Any, subject: str
) -> None:
    root = tmp_path / "bids"
    if first is None:
        slots = [slot("p003-P1", "human", "joint", "pointer"), slot("A1", "avatar", "joint")]
        trial = LabTrial(1, slots, complete_graph(2), "joint")
        export_bids(write_lab_session(tmp_path, "plain", [trial], 1), root)
    else:
        export_bids(write_study_session(tmp_path / "a", *first, seed=1), root)
    before = {p: p.read_bytes() for p in root.rglob("*") if p.is_file()}
    folder = write_study_session(tmp_path / "b", *second, seed=2)
    with pytest.raises(InputError, match=f"both map to {subject}"):
        export_bids(folder, root)
    assert {p: p.read_bytes() for p in root.rglob("*") if p.is_file()} == before


def test_two_people_of_one_run_with_one_subject_label_are_refused(tmp_path: Path) -> None:
    folder = write_study_session(tmp_path, "pilot", 3, ("P-1", "P1"), 1)
    with pytest.raises(InputError, match="both map to sub-p003P1"):
        export_bids(folder, tmp_path / "bids")
    assert not (tmp_path / "bids").exists()


def test_a_trial_of_another_participant_or_a_damaged_study_file_is_refused(
    tmp_path: Path,
) -> None:
    folder = write_study_session(tmp_path, "pilot", 3, ("P1",), 1)
    sidecar = folder / "trial-01_session.json"
    data = json.loads(sidecar.read_text())
    data["metadata"]["lab"]["participant"] = 4
    sidecar.write_text(json.dumps(data))
    with pytest.raises(InputError, match="participant 4 in participant 3's study folder"):
        export_bids(folder, tmp_path / "bids")
    data["metadata"]["lab"]["participant"] = 3
    sidecar.write_text(json.dumps(data))
    study = folder / "study.json"
    study.write_text(study.read_text().replace('"participant": 3', '"participant": "3"'))
    with pytest.raises(InputError, match="study.json.*'3' is not a participant number"):
        export_bids(folder, tmp_path / "bids")
    assert not (tmp_path / "bids").exists()


def test_a_shared_dataset_never_holds_the_researchers_folders(tmp_path: Path) -> None:
    """Avatars' specs naming files and the protocol's path, all absolute on the researcher's
    machine, appear in the export by their base names only, in every file of it."""
    home = tmp_path / "home" / "researcher"
    folder = write_study_session(tmp_path / "out", "pilot", 3, ("P1",), 1)
    for sidecar in folder.glob("trial-*_session.json"):
        data = json.loads(sidecar.read_text())
        data["metadata"]["lab"]["slots"][-1]["spec"] = f"vt:{home}/recordings/anna.csv"
        sidecar.write_text(json.dumps(data))
    study = json.loads((folder / "study.json").read_text())
    study["protocol"]["source"] = str(home / "protocols" / "pilot.toml")
    study["order"] = [{"plan": {"slots": [{"label": "A1", "spec": str(home / "anna.npz")}]}}]
    (folder / "study.json").write_text(json.dumps(study))
    root = tmp_path / "bids"
    [motion] = export_bids(folder, root)
    leaking = [p for p in root.rglob("*") if p.is_file() and str(tmp_path) in p.read_text()]
    assert leaking == []
    game = json.loads(motion.with_name(motion.name.replace(".tsv", ".json")).read_text())
    assert game["MirrorGame"]["lab"]["slots"][-1]["spec"] == "vt:anna.csv"
    shared = json.loads((root / "sourcedata" / folder.name / "study.json").read_text())
    assert shared["protocol"]["source"] == "pilot.toml"
    assert shared["order"][0]["plan"]["slots"][0]["spec"] == "anna.npz"
    assert (root / "sourcedata" / folder.name / "trial-01_session.csv").read_bytes() == (
        folder / "trial-01_session.csv"
    ).read_bytes()


@pytest.mark.parametrize(
    ("spec", "shared"),
    [("/home/me/a.npz", "a.npz"), ("vt:/home/me/t.csv", "vt:t.csv"),
     ("vt:C:\\me\\t.csv", "vt:t.csv"), ("C:\\Users\\me\\a.npz", "a.npz"),
     ("avatars/a.npz", "a.npz"), ("bundled:slow", "bundled:slow"),
     ("adaptive:k=1,tau=0.2", "adaptive:k=1,tau=0.2"), ("a.npz", "a.npz")],
)  # fmt: skip
def test_a_spec_keeps_its_files_base_name_only(spec: str, shared: str) -> None:
    assert without_folders(spec) == shared
