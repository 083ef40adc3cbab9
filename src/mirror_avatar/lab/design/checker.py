"""The checks of a protocol file, each failing with one line: ``FILE: KEY.PATH: problem (fix)``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from mirror_avatar.common.constraints import ConstraintError, Setting
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.text import first_control
from mirror_avatar.realtime.messages import PARTICIPANT_PATTERN

MAX_TEXT_CHARS = 500
"""Longest title, name, question or option text (characters)."""


class ProtocolKeyError(InputError):
    """A protocol's key refused: ``FILE: KEY.PATH: problem (fix)``.

    ``key`` is the key's path (``blocks[1].conditions[0].trials``), ``what`` the problem and
    ``fix`` the fix, as data for whoever handles the error.
    """

    def __init__(self, source: str, key: str, what: str, fix: str) -> None:
        self.key, self.what, self.fix = key, what, fix
        super().__init__(source, f"{key}: {what} ({fix})")


class Checker:
    """Builds the errors of one protocol file: ``FILE: KEY.PATH: problem (fix)``."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, where: str, problem: str, fix: str) -> ProtocolKeyError:
        """Return the error of the key at ``where``: its problem and how to fix it."""
        return ProtocolKeyError(self.source, where, problem, fix)

    def setting(self, data: dict[str, Any], where: str, setting: Setting) -> Any:
        """Return the declared ``setting`` of the table at ``where``, checked.

        Its default when absent (`mirror_avatar.common.constraints.Setting.read`).
        """
        try:
            return setting.read(data, where)
        except ConstraintError as error:
            raise self.error(
                error.key, f"{error.value!r} is not allowed", f"give {error.constraint}"
            ) from None

    def table(self, value: object, where: str) -> dict[str, Any]:
        """Return ``value`` if it is a table."""
        if not isinstance(value, dict):
            raise self.error(where, "must be a table", "write it as { key = value, ... }")
        return value

    def keys(self, value: dict[str, Any], where: str, known: tuple[str, ...]) -> None:
        """Refuse a key of the table at ``where`` that is not ``known``."""
        for key in value:
            if key not in known:
                place = f"{where}.{key}" if where else key
                raise self.error(place, "unknown key", f"known keys: {', '.join(known)}")

    def one_of(self, value: object, where: str, choices: tuple[str, ...], noun: str = "") -> str:
        """Return ``value`` if it is one of ``choices``; the error names the ``noun`` if given."""
        if value in choices:
            return str(value)
        listed = ", ".join(choices)
        if noun:
            raise self.error(where, f"{value!r} is not a {noun}", f"one of {listed}")
        raise self.error(where, f"must be one of {listed}", "choose one")

    def array(self, value: object, where: str, most: int, fix: str) -> list[Any]:
        """Return ``value`` if it is a list of 1 to ``most`` entries."""
        if not isinstance(value, list) or not 1 <= len(value) <= most:
            raise self.error(where, f"must be a list of 1 to {most} entries", fix)
        return value

    def text(self, value: object, where: str, allow_empty: bool = False) -> str:
        """Return ``value`` if it is text of at most `MAX_TEXT_CHARS` characters on one line.

        A control character (`mirror_avatar.common.text.CONTROL`: a tab, a line break, an
        escape) is refused: names become table cells and lines of output.
        """
        if not isinstance(value, str) or len(value) > MAX_TEXT_CHARS or not (value or allow_empty):
            raise self.error(where, f"must be text of 1 to {MAX_TEXT_CHARS} characters", "quote it")
        control = first_control(value)
        if control is not None:
            raise self.error(
                where, f"holds the control character '{control}'", "write it on one line without it"
            )
        return value

    def label(self, value: object, where: str) -> str:
        """Return ``value`` if it is a player label or question id."""
        if not isinstance(value, str) or not PARTICIPANT_PATTERN.fullmatch(value):
            raise self.error(
                where,
                f"{value!r} is not a label",
                "use 1-32 letters, digits, '_' or '-', starting with a letter or digit",
            )
        return value

    def refs(self, value: object, where: str, questions: Mapping[str, object]) -> tuple[str, ...]:
        """Return ``value`` if it is a list of the ids of declared questions."""
        if not isinstance(value, list) or not all(isinstance(q, str) for q in value):
            raise self.error(where, "must be a list of question ids", 'e.g. ["partner"]')
        for q in value:
            if q not in questions:
                known = ", ".join(questions) or "none declared"
                raise self.error(
                    where, f"no question {q!r}", f"declare [questions.{q}]; known: {known}"
                )
        return tuple(value)
