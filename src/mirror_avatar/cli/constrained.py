"""Click parameter types built from declared constraints (`mirror_avatar.common.constraints`).

`constrained_type` turns an `Interval` into a number type that refuses, in one line naming the
option, any value outside it (NaN and infinities included), `Options` into a `click.Choice`
and `Either` into a type that reads a word or a number (``auto`` or a codebook size);
`with_range` adds the allowed values to an option's help, so that the help and
the command-line reference state every option's range from the same declaration.
"""

from __future__ import annotations

from contextlib import suppress
from typing import Any

import click

from mirror_avatar.common.constraints import (
    Constraint,
    ConstraintError,
    Either,
    Flag,
    Interval,
    Options,
    check,
)


def _key(param: click.Parameter | None) -> str:
    """Return the option's name for an error line (``--symbols``)."""
    return param.opts[0] if param is not None and param.opts else "value"


class ConstrainedNumber(click.ParamType):
    """A number that must lie in an `Interval`."""

    def __init__(self, interval: Interval) -> None:
        self.interval = interval
        self.name = "integer" if interval.kind is int else "float"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        """Read ``value`` and check it against the interval; fail in one line otherwise."""
        key = _key(param)
        try:
            number = value if isinstance(value, int | float) else self.interval.parse(str(value))
            return check(key, number, self.interval)
        except ValueError as error:
            problem = error.problem if isinstance(error, ConstraintError) else None
            shown = problem or f"{value!r} is not {self.interval}"
            self.fail(shown, param, ctx)


class ConstrainedEither(click.ParamType):
    """A word or a number that one of an `Either`'s constraints allows (``auto`` or a size)."""

    def __init__(self, either: Either) -> None:
        self.either = either
        self.name = "|".join(
            "|".join(c.values) if isinstance(c, Options) else constrained_type(c).name
            for c in either.choices
        )

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        """Read ``value`` as it is or as a number of an interval choice; fail in one line."""
        read = value
        if isinstance(value, str) and value not in self.either:
            for choice in self.either.choices:
                if isinstance(choice, Interval):
                    with suppress(ValueError):
                        read = choice.parse(value)
                        break
        try:
            return check(_key(param), read, self.either)
        except ConstraintError as error:
            self.fail(error.problem, param, ctx)


def constrained_type(constraint: Constraint) -> click.ParamType:
    """Make the click type of an option whose values ``constraint`` declares."""
    if isinstance(constraint, Options):
        return click.Choice(constraint.values)
    if isinstance(constraint, Flag):
        return click.BOOL
    if isinstance(constraint, Either):
        return ConstrainedEither(constraint)
    return ConstrainedNumber(constraint)


def with_range(text: str, constraint: Constraint) -> str:
    """Add the allowed values to an option's help ``text``."""
    return f"{text} Allowed: {constraint}."


def ranged(text: str, constraint: Constraint) -> dict[str, Any]:
    """Return an option's ``type`` and ``help`` keywords from its declared ``constraint``."""
    return {"type": constrained_type(constraint), "help": with_range(text, constraint)}


SEED = Interval(int, 0, 2**63 - 1)
"""A seed given on the command line."""

JOBS = Interval(int, 1, 256)
"""Local threads."""

SESSIONS = Interval(int, 1, 10_000_000)
"""Training sessions."""

SESSION_SECONDS = Interval(float, 0.0, 86_400.0, "right", "s")
"""Length of a played or generated session (s)."""

RATE_HZ = Interval(float, 1.0, 10_000.0, unit="Hz")
"""A sampling rate a command writes or analyses at."""

TRIM_RANGE = Interval(float, 0.0, None, "left", "s")
"""Seconds left out at the start of a session's metrics."""
