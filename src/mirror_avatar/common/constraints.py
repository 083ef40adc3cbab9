"""Constraints declared as data: what a setting accepts, checked and described from one record.

A setting's allowed values are declared once, as an `Interval` (numbers between two ends, each
open or closed, finite, whole numbers or not, multiples of a step or not), as `Options` (a fixed
set of words), as a `Flag`, or as `Either` of these (``auto`` or a whole number), in the style of
scikit-learn's ``sklearn/utils/_param_validation.py``. The declaration checks a value (`check`),
describes the allowed values for help texts and documents (``str``), and names values it refuses
(`Interval.refused`, `Options.refused`, ...), from which the refusal tests are generated.

A refused value raises `ConstraintError`: an `InputError` of one line naming the setting, the
value and what is allowed, which carries the setting's key, the value and the constraint as
data, so that callers never read them back out of the message.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from dataclasses import dataclass
from os import PathLike
from typing import Any, Literal

from mirror_avatar.common.errors import InputError

Closed = Literal["both", "left", "right", "neither"]
"""Which ends of an `Interval` belong to it."""


@dataclass(frozen=True)
class Interval:
    """Finite numbers between ``low`` and ``high``, whole numbers only if ``kind`` is `int`.

    Parameters
    ----------
    kind
        `int` (integers only; bools are refused) or `float` (any finite real number).
    low, high
        The ends; None for no end on that side.
    closed
        Which ends are allowed values themselves.
    unit
        Unit of the values, for the description (``"s"``); empty for none.
    multiple_of
        Whole numbers only: the step every value is a multiple of (2: even numbers); 1 for any.
    """

    kind: type[int] | type[float]
    low: float | None
    high: float | None
    closed: Closed = "both"
    unit: str = ""
    multiple_of: int = 1

    def __contains__(self, value: object) -> bool:
        """Say whether ``value`` is an allowed number (NaN and infinities never are)."""
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return False
        if isinstance(value, numbers.Integral):
            number: int | float = int(value)
        elif self.kind is int or not math.isfinite(number := float(value)):
            return False
        low_ok = self.low is None or (
            number >= self.low if self.closed in ("both", "left") else number > self.low
        )
        high_ok = self.high is None or (
            number <= self.high if self.closed in ("both", "right") else number < self.high
        )
        return low_ok and high_ok and (self.multiple_of == 1 or number % self.multiple_of == 0)

    def __str__(self) -> str:
        """Describe the allowed values, e.g. ``a number in (0, 600] s``."""
        what = "a whole number" if self.kind is int else "a number"
        if self.multiple_of != 1:
            what = f"a multiple of {self.multiple_of}"
        left = "[" if self.closed in ("both", "left") and self.low is not None else "("
        right = "]" if self.closed in ("both", "right") and self.high is not None else ")"
        low = "-inf" if self.low is None else self._shown(self.low)
        high = "inf" if self.high is None else self._shown(self.high)
        unit = f" {self.unit}" if self.unit else ""
        return f"{what} in {left}{low}, {high}{right}{unit}"

    def _shown(self, end: float) -> str:
        return str(int(end)) if self.kind is int else f"{end:g}"

    def parse(self, text: str) -> float:
        """Read a number of this interval's kind from ``text`` (not yet checked).

        Raises
        ------
        ValueError
            ``text`` is not a number (a whole one for `int`).
        """
        return int(text) if self.kind is int else float(text)

    def refused(self) -> list[float]:
        """Values this interval refuses: NaN, infinities, beyond each end, open ends themselves.

        With a step, also a number next to the low end (or to zero) that is not its multiple.
        """
        out = [math.nan, math.inf, -math.inf] if self.kind is float else []
        if self.multiple_of != 1:
            start = self.kind(self.low or 0)
            out.append(start if start % self.multiple_of else start + 1)
        for end, step, included in (
            (self.low, -1, self.closed in ("both", "left")),
            (self.high, 1, self.closed in ("both", "right")),
        ):
            if end is None:
                continue
            out.append(self.kind(end + step * max(1.0, abs(end))))
            if not included:
                out.append(self.kind(end))
        return out


@dataclass(frozen=True)
class Options:
    """One of a fixed set of words."""

    values: tuple[str, ...]

    def __contains__(self, value: object) -> bool:
        """Say whether ``value`` is one of the words."""
        return value in self.values

    def __str__(self) -> str:
        """Describe the allowed values, e.g. ``one of shift, pseudo``."""
        return "one of " + ", ".join(self.values)

    def refused(self) -> list[str]:
        """Values these options refuse: the empty word and a word not among them."""
        return ["", "|".join(self.values) + "|"]


@dataclass(frozen=True)
class Flag:
    """True or false (a boolean; numbers and words are refused)."""

    def __contains__(self, value: object) -> bool:
        """Say whether ``value`` is a boolean."""
        return isinstance(value, bool)

    def __str__(self) -> str:
        """Describe the allowed values."""
        return "true or false"

    def refused(self) -> list[object]:
        """Values a flag refuses: a number and a word."""
        return [1, "yes"]


@dataclass(frozen=True)
class Either:
    """A value that one of several constraints allows, e.g. ``auto`` or a whole number."""

    choices: tuple[Interval | Options | Flag, ...]

    def __contains__(self, value: object) -> bool:
        """Say whether one of the choices allows ``value``."""
        return any(value in choice for choice in self.choices)

    def __str__(self) -> str:
        """Describe the allowed values, e.g. ``auto or a whole number in [2, 4096]``."""
        return " or ".join(
            " or ".join(choice.values) if isinstance(choice, Options) else str(choice)
            for choice in self.choices
        )

    def refused(self) -> list[object]:
        """Values every choice refuses, from those each choice names as refused."""
        return [value for choice in self.choices for value in choice.refused() if value not in self]


Constraint = Interval | Options | Flag | Either
"""Any declared constraint."""


REQUIRED = object()
"""The default of a `Setting` that must be given."""


@dataclass(frozen=True)
class Setting:
    """A key of a file (a protocol, a plan) declared once: what it means, allows and defaults to.

    Parameters
    ----------
    key
        The key as the file spells it.
    meaning
        What it sets, in a few words (for the documents' tables).
    constraint
        What it allows, or None for a structured value (a list, a table) that its own reader
        checks, described by ``allowed``.
    default
        Its value when left out; `REQUIRED` when it must be given, None when it is drawn or
        left unset.
    allowed
        The allowed values in words, for a key without a ``constraint``.
    default_shown
        The default in words, when its value does not say it (``drawn and recorded``).
    """

    key: str
    meaning: str
    constraint: Constraint | None = None
    default: Any = REQUIRED
    allowed: str = ""
    default_shown: str = ""

    def read(self, data: dict[str, Any], where: str = "") -> Any:
        """Return the key's value in ``data`` (its default when absent), checked.

        Raises
        ------
        ConstraintError
            The value is outside the constraint, or absent when required; its ``key`` is
            ``where.key`` (the key alone when ``where`` is empty). A key without a constraint
            is returned as it is (None when absent and required), for its reader to check.
        """
        key = f"{where}.{self.key}" if where else self.key
        if self.key not in data:
            if self.default is REQUIRED and self.constraint is not None:
                raise ConstraintError(key, None, self.constraint)
            return None if self.default is REQUIRED else self.default
        value = data[self.key]
        return value if self.constraint is None else check(key, value, self.constraint)

    def described(self) -> str:
        """Describe the allowed values (the constraint's words, or ``allowed``)."""
        return str(self.constraint) if self.constraint is not None else self.allowed

    def default_text(self) -> str:
        """Describe the default: ``required``, ``default_shown``, or the value as TOML writes it."""
        if self.default_shown:
            return self.default_shown
        if self.default is REQUIRED:
            return "required"
        if self.default is None:
            return "none"
        if isinstance(self.default, bool):
            return str(self.default).lower()
        return f'"{self.default}"' if isinstance(self.default, str) else f"{self.default:g}"


def settings_table(settings: tuple[Setting, ...]) -> str:
    """Write declared settings as a Markdown table: key, meaning, allowed values, default."""
    rows = ["| key | sets | allowed | default |", "|---|---|---|---|"]
    rows += [
        f"| `{s.key}` | {s.meaning} | {s.described()} | {s.default_text()} |" for s in settings
    ]
    return "\n".join(rows) + "\n"


class ConstraintError(InputError):
    """A value outside its declared constraint: one line naming the key, the value, the range.

    ``KEY: VALUE is not allowed; give ALLOWED``, or ``SOURCE: KEY: ...`` when the value was read
    from a file; a long value is shown cut (`reprlib.repr`).

    Attributes
    ----------
    key
        The setting (an option such as ``--trim``, or a key of a file).
    value
        The value refused.
    constraint
        What is allowed.
    """

    def __init__(
        self,
        key: str,
        value: Any,
        constraint: Constraint,
        source: str | PathLike[str] | None = None,
    ) -> None:
        self.key = key
        self.value = value
        self.constraint = constraint
        refusal = f"{reprlib.repr(value)} is not allowed; give {constraint}"
        if source is None:
            super().__init__(key, refusal)
        else:
            super().__init__(source, f"{key}: {refusal}")


def check(key: str, value: Any, constraint: Constraint) -> Any:
    """Return ``value`` if ``constraint`` allows it.

    Raises
    ------
    ConstraintError
        Otherwise, naming ``key``.
    """
    if value not in constraint:
        raise ConstraintError(key, value, constraint)
    return value
