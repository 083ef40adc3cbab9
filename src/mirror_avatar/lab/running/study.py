"""A participant's run of a study protocol: its conditions in their order, resumable from disk.

A `ParticipantRun` is the schedule (`mirror_avatar.lab.running.schedule.Schedule`) of a
`mirror_avatar.lab.running.runner.LabSession` whose plan changes from one condition to the next of a
participant's order (`mirror_avatar.lab.design.protocol.Protocol.schedule`). Its trials are numbered
across the whole protocol (``trial-01`` to ``trial-NN`` in one folder), each sidecar naming its
block, condition, trial within the condition and the true kind of every player. Each person
keeps one join link for the whole protocol; a person who does not play a condition waits. Pages
are blinded: the players they see are "your partner" (or "partner 1", "partner 2", ...), never a
label or a kind.

The folder is named after the protocol and the participant (``<protocol>-p003``) and holds
``study.json``: the protocol's seed and source, the participant's number and the order of the
conditions as run, with each condition's trial numbers and partners; once the last trial is
played, ``ended.json`` (`mirror_avatar.lab.export.run_outcomes`). Creating the same
participant's session again (after a crash, a server restart) resumes it: ``study.json`` must
match the protocol (same seed, same order), and play continues at the first trial whose files
are not on disk; the trial a crash interrupted keeps what it recorded, and a trial whose
recording is missing beside its other files is refused (`first_unrecorded`).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.files.trial_io import read_sidecar_text
from mirror_avatar.files.trial_record import StudyRecord
from mirror_avatar.files.user_files import parse_json
from mirror_avatar.lab.design.perturbation import Perturbation
from mirror_avatar.lab.design.plan import SessionPlan
from mirror_avatar.lab.design.protocol import Condition, Protocol, Question
from mirror_avatar.lab.export.run_outcomes import write_ended
from mirror_avatar.lab.files import (
    ANSWERS_SUFFIX,
    SESSION_SUFFIX,
    STUDY_FILE,
    trial_file,
    trial_stem,
)
from mirror_avatar.lab.running.messages import Answer
from mirror_avatar.lab.running.participant import COLOURS, Participant
from mirror_avatar.lab.running.partner_frames import PartnerFrames
from mirror_avatar.lab.running.schedule import (
    Entered,
    Opening,
    Publisher,
    next_in,
    welcome,
)
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.realtime.trial import Array


@dataclass
class Asking:
    """The questions open after trial ``n``: who has yet to answer which, and the answers."""

    n: int
    questions: dict[str, Question]
    after: dict[str, list[str]]
    pending: dict[str, set[str]]
    answers: dict[str, dict[str, dict[str, object]]]
    done: asyncio.Event = field(default_factory=asyncio.Event)


def study_folder(protocol: Protocol, participant: int) -> str:
    """Return the folder name of a participant's run of a protocol."""
    return f"{Path(protocol.source).stem}-p{participant:03d}"


class ParticipantRun:
    """A participant's run of a protocol: the schedule of their lab session (module docstring).

    Parameters
    ----------
    protocol
        The protocol.
    participant
        The participant's number (0-based; their row of the counterbalancing).
    """

    def __init__(self, protocol: Protocol, participant: int) -> None:
        self.protocol = protocol
        self.number = participant
        self.steps = protocol.schedule(participant)
        seeds = spawn_seeds(protocol.seed, participant + 1)[participant]
        seeds = spawn_seeds(int(seeds), len(self.steps))
        self.plans = [
            protocol.blocks[s.block].conditions[s.condition].plan(s.persons, int(seed))
            for s, seed in zip(self.steps, seeds, strict=True)
        ]
        self.first_trials = [1]
        for plan in self.plans:
            self.first_trials.append(self.first_trials[-1] + plan.trials)
        self.by_label = {
            label: Participant(k, label, "pointer", [k]) for k, label in enumerate(protocol.people)
        }
        self.directory = Path()  # the session's folder, once opened
        self.asking: Asking | None = None
        self.answered: dict[int, dict[str, dict[str, object]]] = {}
        self.frames = PartnerFrames()
        self.step = 0
        self.plan: SessionPlan = self.plans[0]
        self.playing: dict[int, Participant] = {}
        self._enter(0)

    @property
    def people(self) -> list[Participant]:
        """Every person of the protocol."""
        return list(self.by_label.values())

    @property
    def total_trials(self) -> int:
        """Number of trials of the whole protocol for this participant."""
        return self.first_trials[-1] - 1

    def describe(self, session_id: str, created_utc: str) -> dict[str, Any]:
        """Return the participant's schedule as ``study.json`` records it."""
        order = []
        for i, (step, plan) in enumerate(zip(self.steps, self.plans, strict=True)):
            block = self.protocol.blocks[step.block]
            order.append(
                {
                    "block": block.name,
                    "condition": step.name,
                    "game": plan.condition,
                    "trials": list(range(self.first_trials[i], self.first_trials[i + 1])),
                    "players": {slot.label: slot.kind for slot in plan.slots},
                    "plan": plan.to_json(),
                }
            )
        return {
            "id": session_id,
            "created_utc": created_utc,
            "protocol": {"source": self.protocol.source, "title": self.protocol.title},
            "seed": self.protocol.seed,
            "participant": self.number,
            "order": order,
        }

    def open(self, session_id: str, directory: Path, created_utc: str) -> Opening:
        """Create the folder and ``study.json``, or resume the run recorded there.

        The step of the trial played next becomes the current one (entered at its trial).
        """
        self.directory = directory
        opening = self._open(session_id, created_utc)
        n = opening.next_trial
        self._enter(self._step_of(n) if n <= self.total_trials else 0)
        return opening

    def _open(self, session_id: str, created_utc: str) -> Opening:
        path = self.directory / STUDY_FILE
        if not self.directory.exists():
            self.directory.mkdir(parents=True)
            write_atomic_json(path, self.describe(session_id, created_utc))
            return Opening(created_utc, 1)
        recorded = read_schedule(path)
        expected = self.describe(session_id, created_utc)
        for key in ("seed", "participant"):
            if recorded.get(key) != expected[key]:
                raise InputError(path, f"recorded with another {key} (use another --out folder)")
        order = recorded.get("order")
        names = [
            (c.get("condition"), c.get("players")) if isinstance(c, dict) else None
            for c in (order if isinstance(order, list) else [])
        ]
        if names != [(c["condition"], c["players"]) for c in expected["order"]]:
            raise InputError(path, "recorded with another order (use another --out folder)")
        created = recorded.get("created_utc")
        next_trial = first_unrecorded(self.directory, self.total_trials)
        resumed = f"resumed at trial {next_trial} of {self.total_trials}"
        return Opening(created if isinstance(created, str) else created_utc, next_trial, resumed)

    def _step_of(self, n: int) -> int:
        """Return the index of the step trial n belongs to."""
        return max(i for i, first in enumerate(self.first_trials[:-1]) if first <= n)

    def _enter(self, step: int) -> None:
        """Make step ``step``'s plan the current one, with its people's slots."""
        self.step = step
        self.plan = self.plans[step]
        self.playing = {}
        for k in self.plan.humans:
            person = self.by_label[self.plan.slots[k].label]
            person.index, person.visible = k, [k, *self.plan.neighbours(k)]
            self.playing[k] = person

    def enter(self, n: int, again: bool) -> Entered | None:
        """Make trial n's condition current when it changes, or ``again`` (no avatars built yet).

        Says where the trial is in the protocol and the condition's marker.
        """
        step = self._step_of(n)
        if step == self.step and not again:
            return None
        self._enter(step)
        return Entered(f"now {self.where(n)}", self.condition_marker())

    def condition_marker(self) -> str:
        """Return the marker of the condition entered: its name, block and line-up.

        For instance ``condition 'follow' of block 'dyads': P1 human follower, A1 avatar
        leader``.
        """
        step = self.steps[self.step]
        players = ", ".join(
            f"{slot.label} {slot.kind} {role}"
            for slot, role in zip(self.plan.slots, self.plan.roles, strict=True)
        )
        block = self.protocol.blocks[step.block].name
        return f"condition '{step.name}' of block '{block}': {players}"

    def channels(self) -> tuple[list[str], list[str], list[str]]:
        """Return the outlet's channels: every player label of the run, with roles and kinds.

        Labels in order of first appearance over the participant's conditions; a label's
        roles and kinds are those it plays, joined by ``/`` when they change from one
        condition to the next (``human/avatar`` for a ``person-or-avatar`` drawn both ways).
        """
        roles: dict[str, list[str]] = {}
        kinds: dict[str, list[str]] = {}
        for plan in self.plans:
            for slot, role in zip(plan.slots, plan.roles, strict=True):
                for seen, value in ((roles, role), (kinds, slot.kind)):
                    values = seen.setdefault(slot.label, [])
                    if value not in values:
                        values.append(value)
        labels = list(roles)
        return labels, ["/".join(roles[x]) for x in labels], ["/".join(kinds[x]) for x in labels]

    def publisher(self, outlet: Publisher | None) -> Callable[[Array, float], None] | None:
        """Publish each sample on the run's channels, NaN for the players not in the condition."""
        if outlet is None:
            return None
        labels = self.channels()[0]
        index = [labels.index(slot.label) for slot in self.plan.slots]
        values = np.full(len(labels), np.nan)

        def publish(positions: Array, timestamp: float) -> None:
            values[index] = positions
            outlet.push_positions(values, timestamp)

        return publish

    def where(self, n: int) -> str:
        """Say where trial n is in the protocol: block, condition and trial within it."""
        step = self._step_of(n)
        blocks = list(dict.fromkeys(s.block for s in self.steps))
        block = self.steps[step].block
        within = n - self.first_trials[step] + 1
        return (
            f"block {blocks.index(block) + 1} of {len(blocks)}, condition "
            f"'{self.steps[step].name}', trial {within} of {self.plans[step].trials}"
        )

    def welcome(self, participant: Participant, state: str) -> dict[str, Any]:
        """Return the blinded welcome, with the protocol's completion code or link.

        ``completion`` is in it when the protocol has one: the end page shows it.
        """
        message = self.blinded_welcome(participant, state)
        ending = self.protocol.online.completion
        return message | ({"completion": ending.to_json()} if ending else {})

    def blinded_welcome(self, participant: Participant, state: str) -> dict[str, Any]:
        """Return the blinded welcome: partners are "your partner", never a label or a kind."""
        playing = participant in self.playing.values()
        if not playing:
            me = {"index": participant.index, "label": participant.label, "colour": COLOURS[0]}
            return {
                "type": "welcome",
                "label": participant.label,
                "index": participant.index,
                "role": "waiting",
                "condition": "waiting",
                "device": "pointer",
                "visible": [me],
                "trials": self.total_trials,
                "duration": self.plan.duration,
                "state": "waiting",
            }
        message = welcome(self.plan, participant, state)
        others = message["visible"][1:]
        for i, player in enumerate(others):
            player["label"] = "your partner" if len(others) == 1 else f"partner {i + 1}"
        message["trials"] = self.total_trials
        return message

    def condition(self) -> Condition:
        """Return the protocol's condition being played."""
        step = self.steps[self.step]
        return self.protocol.blocks[step.block].conditions[step.condition]

    def delay_samples(self) -> int:
        """Return the partners' visual delay of the current condition (samples of T)."""
        return round(self.condition().delay / CONTROL_PERIOD)

    def send_frames(self, trial: LabTrial) -> None:
        """Send each page its frame, the partners delayed, hidden and drawn as the condition says.

        `mirror_avatar.lab.running.partner_frames.PartnerFrames.send`; the recording keeps the
        true positions.
        """
        condition = self.condition()
        k = trial.k - 1
        hidden = any(start <= k * CONTROL_PERIOD < end for start, end in condition.occlude)
        self.frames.send(trial, self.playing, self.delay_samples(), hidden, condition.view)

    def perturbations(self) -> list[tuple[int, Perturbation]]:
        """Return the condition's changes of the avatars playing now (a person is not changed)."""
        index = {slot.label: k for k, slot in enumerate(self.plan.slots) if slot.kind == "avatar"}
        return [(index[p.player], p) for p in self.condition().perturb if p.player in index]

    def record(self, session_id: str, n: int) -> dict[str, Any]:
        """Return what trial n's sidecar records: the session, the condition, the study's part.

        The study's part (`mirror_avatar.files.trial_record.StudyRecord`): protocol, participant,
        block, condition, trial within it, the partners' delay and occlusion as played, every
        player's true kind, the people's panel identifiers (their join links') and when each
        agreed on the consent page.
        """
        step = self._step_of(n)
        condition = self.protocol.blocks[self.steps[step].block].conditions[
            self.steps[step].condition
        ]
        occlude = tuple(
            (a, b if math.isfinite(b) else self.plan.duration) for a, b in condition.occlude
        )
        study = StudyRecord(
            protocol=self.protocol.title,
            participant=self.number,
            block=self.protocol.blocks[self.steps[step].block].name,
            condition=self.steps[step].name,
            condition_trial=n - self.first_trials[step] + 1,
            delay_s=round(condition.delay / CONTROL_PERIOD) * CONTROL_PERIOD,
            occluded_s=occlude,
            partners={slot.label: slot.kind for slot in self.plan.slots},
            panel={p.label: dict(p.panel) for p in self.people if p.panel},
            consented={p.label: p.consented for p in self.people if p.consented is not None},
            partner_view=condition.view.to_json(),
        )
        lab = {"session_id": session_id, "condition": self.plan.condition}
        return lab | study.to_json()

    def questions_after(self, n: int) -> dict[str, list[str]]:
        """Return the ids of the questions asked after trial n: after the trial, after the block.

        A block's questions follow the participant's last trial in that block.
        """
        step = self._step_of(n)
        here = self.steps[step]
        block = self.protocol.blocks[here.block]
        last = n == self.first_trials[step + 1] - 1 and (
            step + 1 == len(self.steps) or self.steps[step + 1].block != here.block
        )
        return {
            "trial": list(block.conditions[here.condition].after_trial),
            "block": list(block.after_block) if last else [],
        }

    def next_in(self, n: int, complete: bool) -> float | None:
        """Return None after a trial with questions: the next trial waits for the answers."""
        after = self.questions_after(n)
        if after["trial"] or after["block"]:
            return None
        return next_in(self.plan, n, self.total_trials, complete)

    async def after_trial(self, n: int, log: Callable[[str], None]) -> None:
        """Ask the trial's (and the block's) questions and wait for every answer.

        After the run's last trial, its end is recorded (`mirror_avatar.lab.export.run_outcomes.
        write_ended`) with the completion and the people whose pages show it: those connected
        and not refused.
        """
        await self._ask(n, log)
        if n != self.total_trials:
            return
        ending = self.protocol.online.completion
        shown = [p.label for p in self.people if p.outbox is not None and p.refused is None]
        try:
            await asyncio.to_thread(
                write_ended, self.directory, ending.to_json() if ending else None, shown
            )
        except OSError as error:
            log(f"the run's end was not written: {error}")

    async def _ask(self, n: int, log: Callable[[str], None]) -> None:
        """Ask the questions after trial n and wait for every answer."""
        after = self.questions_after(n)
        ids = list(dict.fromkeys(after["trial"] + after["block"]))
        people = [p.label for p in self.playing.values()]
        if not ids or not people:
            return
        questions = {qid: self.protocol.questions[qid] for qid in ids}
        pending = {label: set(ids) for label in people}
        self.asking = Asking(n, questions, after, pending, {label: {} for label in people})
        self._write_answers(self.asking)
        for participant in self.playing.values():
            if participant.outbox is not None:
                participant.outbox.put(self._questions_message(participant.label))
        log(f"trial {n}: asking {', '.join(ids)}")
        try:
            await self.asking.done.wait()
        finally:
            self.asking = None
        log(f"trial {n}: every answer in")

    def _questions_message(self, label: str) -> dict[str, Any]:
        asking = self.asking
        assert asking is not None
        open_ = [q.to_json() for qid, q in asking.questions.items() if qid in asking.pending[label]]
        return {"type": "questions", "trial": asking.n, "questions": open_}

    def answer(self, participant: Participant, answer: Any) -> str | None:
        """Take a participant's answer; return why not, or None (every answer is written)."""
        asking = self.asking
        if not isinstance(answer, Answer) or asking is None or answer.trial != asking.n:
            return "no question is open for that trial"
        pending = asking.pending.get(participant.label, set())
        if answer.question not in pending:
            return f"{answer.question}: not an open question"
        problem = asking.questions[answer.question].problem(answer.value)
        if problem is not None:
            return problem
        stamp = datetime.now(UTC).isoformat()
        asking.answers[participant.label][answer.question] = {"value": answer.value, "utc": stamp}
        given = self.answered.setdefault(asking.n, {}).setdefault(participant.label, {})
        given[answer.question] = answer.value
        pending.discard(answer.question)
        self._write_answers(asking)
        if not any(asking.pending.values()):
            asking.done.set()
        return None

    def _write_answers(self, asking: Asking) -> None:
        step = self.steps[self._step_of(asking.n)]
        write_atomic_json(
            answers_path(self.directory, asking.n),
            {
                "trial": asking.n,
                "block": self.protocol.blocks[step.block].name,
                "condition": step.name,
                "after_trial": asking.after["trial"],
                "after_block": asking.after["block"],
                "questions": {qid: q.to_json() for qid, q in asking.questions.items()},
                "answers": asking.answers,
            },
        )

    def owed(self, participant: Participant) -> list[dict[str, Any]]:
        """Return the questions still open to a page that (re)joins."""
        if self.asking is not None and self.asking.pending.get(participant.label):
            return [self._questions_message(participant.label)]
        return []

    def status(self, status: dict[str, Any], at: int, ended: bool) -> dict[str, Any]:
        """Return the session's status, with where the participant is in the protocol.

        ``at`` is the trial the session is at; while questions are open, "where" is the trial
        they follow; nobody waits once the run has ended. Each trial's row also names its block,
        condition, partners and answers (`trial_study`).
        """
        n = at if self.asking is None else self.asking.n
        order = [step.name for step in self.steps]
        playing = self.playing.values()
        waiting = [] if ended else [p.label for p in self.people if p not in playing]
        status = dict(status)
        status["trials"] = [row | self.trial_study(row["n"]) for row in status["trials"]]
        return status | {
            "study": {
                "participant": self.number,
                "where": self.where(n),
                "order": order,
                "waiting": waiting,
                "total_trials": self.total_trials,
                "unanswered": {}
                if self.asking is None
                else {label: sorted(ids) for label, ids in self.asking.pending.items() if ids},
            }
        }

    def trial_study(self, n: int) -> dict[str, Any]:
        """Return what the console lists of trial n: its block, condition, partners and answers.

        The partners are every player's true kind; the answers those given after the trial, by
        label and question.
        """
        step = self._step_of(n)
        return {
            "block": self.protocol.blocks[self.steps[step].block].name,
            "condition": self.steps[step].name,
            "partners": {slot.label: slot.kind for slot in self.plans[step].slots},
            "answers": self.answered.get(n, {}),
        }


def answers_path(directory: Path, n: int) -> Path:
    """Return the file of the answers given after trial n."""
    return trial_file(directory, n, ANSWERS_SUFFIX)


def read_schedule(path: Path) -> dict[str, Any]:
    """Read a run's ``study.json`` through the checked reader (`mirror_avatar.files.user_files`).

    At most `mirror_avatar.files.trial_io.MAX_SIDECAR_BYTES`, a regular file (never a FIFO or a
    device, whose read could wait for ever), JSON nested at most
    `mirror_avatar.files.user_files.MAX_DEPTH` deep.

    Raises
    ------
    InputError
        One line naming the file: not a regular file, too large, not UTF-8, not JSON, nested
        too deeply, or not a JSON object.
    """
    try:
        recorded = parse_json(read_sidecar_text(path), path)
    except InputError as error:
        raise InputError(
            path, f"this folder holds no readable study ({error.problem}; move the folder away)"
        ) from None
    if not isinstance(recorded, dict):
        raise InputError(path, "this folder holds no readable study (move the folder away)")
    return recorded


def first_unrecorded(directory: Path, total: int) -> int:
    """Return the trial a run resumes at: the first of 1..``total`` with no file on disk.

    **Choice**: a trial with no file before one with files (a gap: files deleted or moved) is
    refused rather than played out of the order recorded in ``study.json``, and so is a trial
    whose files are kept without its recording (``trial-NN_session.csv``): it is neither
    counted as played nor played again over what is left of it.

    Raises
    ------
    InputError
        A gap, naming the missing trial and the next one recorded; a recording missing,
        naming it.
    """
    recorded = [n for n in range(1, total + 1) if _recorded(directory, n)]
    following = len(recorded) + 1
    gaps = [n for n in range(1, following) if n not in recorded]
    if gaps:
        stem = trial_stem(directory, gaps[0]).name
        later = next(n for n in recorded if n > gaps[0])
        raise InputError(
            directory,
            f"trial {gaps[0]} has no files ({stem}_*) but trial {later} has: restore "
            f"{stem}'s files, or move the folder away to run the participant afresh",
        )
    lost = [n for n in recorded if not trial_file(directory, n, SESSION_SUFFIX).is_file()]
    if lost:
        raise _lost_recording(directory, lost[0], last=lost[0] == recorded[-1])
    return following


def _lost_recording(directory: Path, n: int, last: bool) -> InputError:
    """Say that trial n's recording is missing beside its other files, and what to do."""
    stem = trial_stem(directory, n).name
    again = (
        "move its other files away to play it again"
        if last
        else "move the folder away to run the participant afresh"
    )
    return InputError(
        trial_file(directory, n, SESSION_SUFFIX),
        f"missing, but trial {n}'s other files ({stem}_*) are kept: the trial is not recorded; "
        f"restore its recording, or {again}",
    )


def _recorded(directory: Path, n: int) -> bool:
    """Whether any file of trial n is on disk."""
    stem = trial_stem(directory, n)
    return any(stem.parent.glob(f"{stem.name}_*"))
