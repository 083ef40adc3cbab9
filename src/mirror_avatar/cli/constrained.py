"""Click parameter types built from declared constraints (`mirror_avatar.constraints`).

`constrained_type` turns an `Interval` into a number type that refuses, in one line naming the
option, any value outside it (NaN and infinities included), and `Options` into a
`click.Choice`; `with_range` adds the allowed values to an option's help, so that the help and
the command-line reference state every option's range from the same declaration.
"""

from __future__ import annotations

from typing import Any

import click

from mirror_avatar.constraints import (
    Constraint,
    ConstraintError,
    Flag,
    Interval,
    Options,
    check,
)


class ConstrainedNumber(click.ParamType):
    """A number that must lie in an `Interval`."""

    def __init__(self, interval: Interval) -> None:
        self.interval = interval
        self.name = "integer" if interval.kind is int else "float"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        """Read ``value`` and check it against the interval; fail in one line otherwise."""
        key = param.opts[0] if param is not None and param.opts else "value"
        try:
            number = value if isinstance(value, int | float) else self.interval.parse(str(value))
            return check(key, number, self.interval)
        except ValueError as error:
            problem = error.problem if isinstance(error, ConstraintError) else None
            shown = problem or f"{value!r} is not {self.interval}"
            self.fail(shown, param, ctx)


def constrained_type(constraint: Constraint) -> click.ParamType:
    """Make the click type of an option whose values ``constraint`` declares."""
    if isinstance(constraint, Options):
        return click.Choice(constraint.values)
    if isinstance(constraint, Flag):
        return click.BOOL
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
