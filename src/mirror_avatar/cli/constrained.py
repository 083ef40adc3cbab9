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
