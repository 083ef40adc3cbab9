"""The adaptive player against the authors' own MATLAB controller, transcribed as an oracle.

The oracle is a slow, line-by-line Python reading of Zhai, Alderisio et al.'s public MirrorGame
code (GitHub diBernardoGroup/MirrorGame, commit 0b78206, folder ``Adaptive Control/``): the
functions of ``controllers/`` and ``simulation/HKB.m`` one by one, and the loop of
``simulation/simulationHC.m`` with its wall-clock step ``dt`` replaced by a fixed step and the
mouse or Leap Motion replaced by a recorded leader. Parameters from ``parameters/parametersHC.m``,
``parameters/simulationParameters.m`` and ``simulationHC.m`` (``coupMax``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import play
from mirror_avatar.files.trials import Trial
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.players.adaptive import PARAMETERS, AdaptivePlayer

PUBLISHED = {
    "alpha": 10.0,  # parametersHC.m: a = 10
    "beta": 20.0,  # parametersHC.m: b = 20
    "gamma": -1.0,  # parametersHC.m: g = -1
    "omega": 0.1,  # parametersHC.m: w = .1
    "cp": 40.0,  # parametersHC.m: Cp = 40
    "delta": 0.25,  # parametersHC.m: d = .25
    "eta": 30.0,  # parametersHC.m: etaAL = 30
    "a0": -5.0,  # simulationParameters.m: aee = -5
    "b0": -5.0,  # simulationParameters.m: bee = -5
    "bound": 5.0,  # simulationHC.m: coupMax = 5
}


def hkb(x: list[float], u: float, p: dict[str, float]) -> list[float]:
    """``simulation/HKB.m``: xp = [x(2); -(a x(1)^2 + b x(2)^2 - g) x(2) - w^2 x(1) + u]."""
    a, b, g, w = p["alpha"], p["beta"], p["gamma"], p["omega"]
    return [x[1], -(a * x[0] ** 2 + b * x[1] ** 2 - g) * x[1] - w**2 * x[0] + u]


def adaptive_law_a(aee: float, x: list[float], r: list[float], p: dict[str, float]) -> float:
    """``controllers/adaptiveLawA.m``."""
    eta = p["eta"]
    return -math.exp(-2 * aee) * ((x[0] - r[0]) * (x[1] - r[1]) + eta * (x[0] - r[0]) ** 2) - eta


def adaptive_law_b(
    bee: float, x: list[float], r: list[float], u: float, p: dict[str, float]
) -> float:
    """``controllers/adaptiveLawB.m`` (its ``u`` is the ``uint`` simulationHC.m passes)."""
    a, b, g, w, eta = p["alpha"], p["beta"], p["gamma"], p["omega"], p["eta"]
    inner = w**2 * x[0] + (a * x[0] ** 2 + b * x[1] ** 2 - g) * x[1] - eta * (x[1] - r[1]) - u
    return (x[1] - r[1]) / math.exp(2 * bee) * inner - eta


def u_i(x: list[float], r: list[float], p: dict[str, float]) -> float:
    """``controllers/ul.m`` (function ``uI``) for the follower model: Cp and d."""
    return p["cp"] * math.exp(-p["delta"] * (x[1] - r[1]) ** 2) * (x[0] - r[0])


def lba(aee: float, bee: float, x: list[float], r: list[float], u_int: float) -> float:
    """``controllers/LBA.m``."""
    return (aee + bee * (x[0] - r[0]) ** 2) * (x[1] - r[1]) - u_int


def constrain(value: float, limit: float) -> float:
    """``controllers/constrain.m`` (its NaN branch draws a random sign; a NaN fails here)."""
    assert not math.isnan(value)
    return value if abs(value) <= limit else math.copysign(limit, value)


def simulation_hc(
    leader: np.ndarray, dt: float, p: dict[str, float], start: tuple[float, float] | None = None
) -> np.ndarray:
    """``simulation/simulationHC.m`` with a fixed step ``dt`` and ``leader[k]`` read at pass k.

    ``start`` is the follower's initial state; the code's is the leader's first position at rest
    (``x0 = xd0``). Returns the recorded follower states X, shape (2, len(leader)).
    """
    coup_max = p["bound"]
    aee, bee = p["a0"], p["b0"]  # simulationParameters.m
    xd = [float(leader[0]), 0.0]
    x = list(start) if start is not None else list(xd)
    aee = constrain(aee, coup_max)
    bee = constrain(bee, coup_max)
    uint0 = u_i(x, xd, p)
    u = lba(aee, bee, x, xd, uint0)
    recorded_x, recorded_xd = [list(x)], [list(xd)]  # recordHC.m
    for ti in range(1, len(leader)):
        xp = hkb(x, u, p)  # VP state
        x = [x[0] + xp[0] * dt, x[1] + xp[1] * dt]
        xd = [float(leader[ti]), (float(leader[ti]) - recorded_xd[-1][0]) / dt]  # HP state
        recorded_x.append(list(x))
        recorded_xd.append(list(xd))
        uint = u_i(recorded_x[-1], recorded_xd[-1], p)  # Control
        aeep = adaptive_law_a(aee, recorded_x[-1], recorded_xd[-1], p)
        beep = adaptive_law_b(bee, recorded_x[-1], recorded_xd[-1], uint, p)
        aee = aee + aeep * dt
        bee = bee + beep * dt
        aee = constrain(aee, coup_max)
        bee = constrain(bee, coup_max)
        u = lba(aee, bee, recorded_x[-1], recorded_xd[-1], uint)
    return np.array(recorded_x).T


def test_defaults_are_the_published_parameters() -> None:
    assert {key: PARAMETERS[key].default for key in PUBLISHED} == PUBLISHED
    assert AdaptivePlayer().hold == 1, "the public code samples on every pass of its loop"


@pytest.mark.parametrize(
    ("label", "seconds"), [("slow-2", 60.0), ("slow-5", 60.0), ("fast-1", 15.0), ("fast-9", 15.0)]
)
def test_player_follows_the_authors_controller_on_bundled_leaders(
    zhai_trials_100hz: list[Trial], label: str, seconds: float
) -> None:
    """Same leader, parameters and step (the player's Euler switch, its start at rest at 0).

    On slow leaders the two agree to rounding (3e-16) over the whole minute. On fast leaders the
    closed loop amplifies rounding (exp(-2b) at b = -5 is 2.2e4): differences of one unit in the
    last place grow past 1e-6 within a minute on some, so they are compared over 15 s.
    """
    trial = next(t for t in zhai_trials_100hz if t.label == label)
    leader = RecordedPlayer(trial, CONTROL_PERIOD).track[0][: round(seconds / CONTROL_PERIOD)]
    expected = simulation_hc(leader, CONTROL_PERIOD, PUBLISHED, start=(0.0, 0.0))
    assert np.all(np.abs(expected[0]) < 0.5), "the code has no walls: the check needs none hit"
    follower = AdaptivePlayer(euler=True)
    duration = (len(leader) - 1) * CONTROL_PERIOD
    session = play([RecordedPlayer(trial), follower], duration=duration, seed=0)
    np.testing.assert_array_equal(session.positions[0], leader)
    got = np.vstack([session.positions[1], session.velocities[1]])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)


def test_the_start_at_rest_at_0_is_forgotten_within_2_s_on_slow_leaders(
    zhai_trials_100hz: list[Trial],
) -> None:
    """The code starts at its leader's first position, the player at 0: after 2 s the authors'
    controller from either start is the same to 2e-4 on every slow leader (4e-3 after 1 s)."""
    for trial in (t for t in zhai_trials_100hz if t.group == "slow"):
        leader = RecordedPlayer(trial, CONTROL_PERIOD).track[0]
        authors = simulation_hc(leader, CONTROL_PERIOD, PUBLISHED)
        players = simulation_hc(leader, CONTROL_PERIOD, PUBLISHED, start=(0.0, 0.0))
        after = round(2.0 / CONTROL_PERIOD)
        np.testing.assert_allclose(players[0, after:], authors[0, after:], atol=1e-3)
