"""What the dynamical-model partners share: parameters by name, RK4 with held inputs, the spec.

The partners of the literature (`adaptive`, `rpc`, `hkb`, `excitator`, `kuramoto`; METHODS
section "Virtual partners from the literature") are ordinary differential equations driven by
what the player observes. Every control period T each samples its neighbours at t_k, holds what
it sampled over [t_k, t_k + T] (zero-order hold, as the virtual trainer does) and integrates its
equations over the period with fixed-step RK4 (`rk4_held`, compiled once and specialised for
each model's compiled right-hand side). They run in the Python step
loop only (``plan`` returns None, so the batch engine refuses them with one line).

A partner's parameters are declared as data: a table of `Parameter` (default and allowed range,
whose sign the range states) and the pairs that must stay in order (``ORDERED``); they are
given on the command line as ``NAME:key=value,...`` (`parse_options`), each value a plain ASCII
decimal number (`parse_number`).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit, types
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.model_files import check_real
from mirror_avatar.players.base import Player

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Parameter:
    """One named parameter of a partner: default, allowed range and what it is.

    Attributes
    ----------
    default
        Value used when the spec does not give one.
    low, high
        Allowed range (inclusive).
    meaning
        What the parameter is, with its unit.
    """

    default: float
    low: float
    high: float
    meaning: str


NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
"""A plain ASCII decimal number, optionally in scientific notation (no ``_``, no other digits,
no ``inf`` or ``nan``)."""


def parse_number(text: str) -> float | None:
    """Return the number ``text`` writes (`NUMBER`, spaces around it allowed), else None."""
    text = text.strip(" ")
    return float(text) if NUMBER.fullmatch(text) else None


def parse_options(spec: str, table: Mapping[str, Parameter]) -> dict[str, float]:
    """Read ``NAME`` or ``NAME:key=value,...`` into every parameter of ``table``.

    Parameters
    ----------
    spec
        The whole spec, quoted in errors.
    table
        The partner's parameters.

    Returns
    -------
    dict
        Every parameter of ``table``: the spec's value where it gives one, else the default.

    Raises
    ------
    InputError
        ``SPEC: ...`` for an item without ``=``, an unknown key (naming the allowed keys), a
        key given twice, a value that is not a number or one outside its range.
    """
    name, _, text = spec.partition(":")
    values = {key: parameter.default for key, parameter in table.items()}
    given: set[str] = set()
    allowed = ", ".join(table)
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, equals, raw = (part.strip() for part in item.partition("="))
        if not equals:
            raise InputError(spec, f"{excerpt(item)} is not key=value; {name} takes {allowed}")
        if key not in table:
            raise InputError(spec, f"unknown parameter {excerpt(key)}; {name} takes {allowed}")
        if key in given:
            raise InputError(spec, f"{key} is given twice")
        given.add(key)
        number = parse_number(raw)
        if number is None:
            raise InputError(
                spec,
                f"{key} must be a number in ASCII decimals (e.g. 0.5 or 2e-3), not {excerpt(raw)}",
            )
        parameter = table[key]
        values[key] = check_real(spec, key, number, parameter.low, parameter.high)
    return values


def describe_parameters(table: Mapping[str, Parameter]) -> str:
    """One line per parameter: ``key (default, low..high): meaning``, for help texts."""
    return "\n".join(
        f"{key} (default {p.default:g}, {p.low:g}..{p.high:g}): {p.meaning}"
        for key, p in table.items()
    )


RATES_SIGNATURE = types.void(
    types.float64, types.float64[:], types.float64[:], types.float64[:], types.float64[:]
)
"""The signature every model's compiled ``rates(t, y, params, inputs, out)`` is declared with.

Declared, the rates reach `rk4_held` as a function of this type: numba keys a cached
specialisation on its argument types, and the type of an undeclared compiled function is the
object itself, new in every process, so each process compiled `rk4_held` again and added it to
the cache on disk without end (and saving that cache could fail once an earlier process's object
was gone)."""


@njit(
    types.void(
        types.FunctionType(RATES_SIGNATURE),
        types.float64[:],
        types.float64[:],
        types.float64[:],
        types.float64,
        types.float64,
        types.int64,
    ),
    cache=True,
    nogil=True,
)
def rk4_held(
    rates: Callable[..., None],
    y: Array,
    params: Array,
    inputs: Array,
    t: float,
    period: float,
    n_substeps: int,
) -> None:
    """Advance ``y`` in place over one period with the inputs held (classical RK4).

    Parameters
    ----------
    rates
        Compiled ``rates(t, y, params, inputs, out)`` writing dy/dt into ``out``, declared with
        `RATES_SIGNATURE`. Pass it from Python (a compiled caller naming it as a global could
        not be cached).
    y
        The state at time ``t``, shape (n,); the state at ``t + period`` on return.
    params, inputs
        The model's parameters and what it sampled at ``t``, held over the period.
    t
        Time at the start of the period (s).
    period
        Length of the period (s).
    n_substeps
        Number of RK4 steps of ``period / n_substeps``.
    """
    h = period / n_substeps
    k1 = np.empty_like(y)
    k2 = np.empty_like(y)
    k3 = np.empty_like(y)
    k4 = np.empty_like(y)
    for i in range(n_substeps):
        s = t + i * h
        rates(s, y, params, inputs, k1)
        rates(s + 0.5 * h, y + 0.5 * h * k1, params, inputs, k2)
        rates(s + 0.5 * h, y + 0.5 * h * k2, params, inputs, k3)
        rates(s + h, y + h * k3, params, inputs, k4)
        y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


class ModelPartner(Player):
    """A partner whose motion is a model's equations: its parameters, seed and description.

    Subclasses set ``PARAMETERS`` (name -> `Parameter`) and ``NAME`` (the default label), and
    implement `reset` and `step`, which read their kernel's parameters as ``params``
    (`kernel_parameters`: every parameter in the order of ``PARAMETERS`` unless a subclass says
    otherwise); the model is deterministic, so ``reset(seed)`` ignores the seed.

    Parameters
    ----------
    options
        Values of some of ``PARAMETERS`` by name (the others take their defaults); checked
        against their ranges.
    label
        The player's name in sessions.
    """

    PARAMETERS: Mapping[str, Parameter] = {}
    ORDERED: tuple[tuple[str, str], ...] = ()
    """Pairs of parameters ``(lower, higher)`` whose values must satisfy lower < higher."""
    NAME = "model partner"
    FIXED_IN_TRIAL: tuple[str, ...] = ()
    """Parameters that cannot change mid-trial: initial values, or scales whose change would
    move the player at once (the others may: `mirror_avatar.players.base.Player.take_over`)."""

    def __init__(self, options: Mapping[str, float] | None = None, label: str = "") -> None:
        given = dict(options or {})
        unknown = sorted(set(given) - set(self.PARAMETERS))
        if unknown:
            raise InputError(
                type(self).__name__,
                f"unknown parameter {unknown[0]}; it takes {', '.join(self.PARAMETERS)}",
            )
        self.options = {
            key: check_real(type(self).__name__, key, given.get(key, p.default), p.low, p.high)
            for key, p in self.PARAMETERS.items()
        }
        for lower, higher in self.ORDERED:
            if not self.options[lower] < self.options[higher]:
                raise InputError(
                    type(self).__name__,
                    f"{lower} {self.options[lower]:g} must be below {higher} "
                    f"{self.options[higher]:g}",
                )
        self.label = label or self.NAME
        self.last_control = math.nan
        self.last_reference = math.nan

    @functools.cached_property
    def params(self) -> Array:
        """The parameters the model's kernel reads (`kernel_parameters`), built when first read."""
        return self.kernel_parameters()

    def kernel_parameters(self) -> Array:
        """Return the parameters the model's kernel reads, in its order (default: all)."""
        return self.parameter_array(tuple(self.PARAMETERS))

    def parameter_array(self, names: tuple[str, ...]) -> Array:
        """Return the named parameters as a float array in that order (for the kernels)."""
        return np.array([self.options[name] for name in names], dtype=np.float64)

    def given(self) -> str:
        """Say which parameters differ from their defaults, and the defaults ("" if none)."""
        changed = [
            f"{key}={value:g} (default {self.PARAMETERS[key].default:g})"
            for key, value in self.options.items()
            if value != self.PARAMETERS[key].default
        ]
        return f"parameters given: {', '.join(changed)}" if changed else ""

    def describe(self) -> dict[str, Any]:
        """Class, label and parameters."""
        return super().describe() | {"params": dict(self.options)}
