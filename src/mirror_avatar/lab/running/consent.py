"""A participant's pages before the game: the instructions, the consent and its answer recorded.

What is recorded is in docs/METHODS.md, section 9 (*Served on the internet*).

A protocol's ``[online]`` table may give an instructions page and a consent page
(`mirror_avatar.lab.design.online`). A participant's page asks for them first (`intro`) and shows
them; only after the participant agrees (`consent`) does it open its WebSocket and join its slot
(a page that has not agreed is refused: `needs_consent`). The answer and its time (UTC) are
written to ``consent-<label>.json`` in the run's folder, every answer kept, and the time of the
agreement goes into each trial's sidecar; a participant who does not agree is screened out
(`mirror_avatar.lab.running.sessions.Lab.refuse`): never played, shown the refusal code or link.

Routes (`mirror_avatar.lab.running.server`): ``GET /join/{key}/intro`` answers ``{"instructions":
text or null, "consent": text or null, "consented": bool, "refused": the refusal or null}``;
``POST /join/{key}/consent`` with ``{"agree": bool}`` answers ``{"consented": true}`` or
``{"refused": the refusal}``.
"""

from __future__ import annotations

import asyncio
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from starlette.requests import Request
from starlette.responses import Response

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.files.user_files import read_json
from mirror_avatar.lab.running.api import ApiError, json_answer, read_body, unwritable
from mirror_avatar.lab.running.participant import Participant
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.screening import online_of
from mirror_avatar.lab.running.sessions import Lab, refusal

DECLINED = "You chose not to take part. Thank you for your time."
"""What a participant who does not agree is told (with the refusal code or link)."""

MAX_CONSENT_FILE_BYTES = 64 * 1024
"""Largest ``consent-<label>.json`` read back to add an answer (bytes)."""


def needs_consent(session: LabSession, participant: Participant) -> bool:
    """Whether the person must still agree before their page may join."""
    return online_of(session).consent is not None and participant.consented is None


def _found(lab: Lab, request: Request) -> tuple[LabSession, Participant]:
    found = lab.find(request.path_params["key"])
    if found is None:
        raise ApiError(404, "this link is not valid or its session has ended")
    return found


async def intro(lab: Lab, request: Request) -> Response:
    """Answer the pages shown before the game, and whether the person agreed or was refused."""
    session, participant = _found(lab, request)
    online = online_of(session)
    refused = participant.refused
    return json_answer(
        {
            "instructions": online.instructions,
            "consent": online.consent,
            "consented": participant.consented is not None,
            "refused": None if refused is None else refusal(session, refused),
        }
    )


async def consent(lab: Lab, request: Request) -> Response:
    """Record the person's answer to the consent page; screen them out if they do not agree.

    Their first answer counts (a page sending another is told the state it left); a run
    resumed after a restart asks again, and the file keeps every answer.
    """
    session, participant = _found(lab, request)
    if online_of(session).consent is None:
        raise ApiError(409, "this study has no consent page")
    data = await read_body(request)
    agree = data.get("agree") if isinstance(data, dict) else None
    if not isinstance(agree, bool):
        raise ApiError(400, 'the body must be {"agree": true or false}')
    if participant.refused is None and participant.consented is None:
        stamp = datetime.now(UTC).isoformat()
        if agree:
            participant.consented = stamp
        try:
            await asyncio.to_thread(
                record_answer, session.directory, participant.label, agree, stamp
            )
        except OSError as error:
            participant.consented = None
            raise unwritable(error) from None
        except InputError as error:
            participant.consented = None
            raise ApiError(500, str(error)) from None
        session.log(f"{participant.label} {'agreed' if agree else 'did not agree'} to take part")
        if not agree:
            lab.refuse(participant.key, DECLINED)
    if participant.refused is not None:
        return json_answer({"refused": refusal(session, participant.refused)})
    return json_answer({"consented": True})


def consent_path(directory: Path, label: str) -> Path:
    """Return the file of a person's consent answers in a run's folder."""
    return directory / f"consent-{label}.json"


def record_answer(directory: Path, label: str, agree: bool, stamp: str) -> None:
    """Add an answer (``agree`` at UTC ``stamp``) to the person's consent file (blocking).

    Raises
    ------
    InputError
        The file there is not one this module wrote (read by the checked reader).
    """
    path = consent_path(directory, label)
    answers: list[dict[str, Any]] = []
    if path.exists():
        kept = read_json(path, MAX_CONSENT_FILE_BYTES)
        if not isinstance(kept, dict) or not isinstance(kept.get("answers"), list):
            raise InputError(path, "not a consent record (move it away)")
        answers = kept["answers"]
    answers.append({"agree": agree, "utc": stamp})
    write_atomic_json(path, {"label": label, "answers": answers})
