"""Partners from the literature: each step against solve_ivp, the protocol, specs, groups."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.players import Observation, RecordedPlayer, check_player
from mirror_avatar.players.adaptive import AdaptivePlayer
from mirror_avatar.players.excitator import ExcitatorPartner
from mirror_avatar.players.hkb_partner import HKBPartner
from mirror_avatar.players.kuramoto import KuramotoPlayer
from mirror_avatar.players.rpc import ReactivePredictivePlayer
from mirror_avatar.specs import MODEL_PARTNERS, load_player

T = CONTROL_PERIOD
N_STEPS = 120
TIGHT = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-13}


def leader(k: int) -> tuple[float, float, float]:
    """A smooth leader well inside the range: position, velocity at t_k and position at t_k-1."""

    def position(j: int) -> float:
        return 0.15 * math.sin(1.7 * j * T) + 0.05 * math.sin(4.1 * j * T)

    velocity = 0.15 * 1.7 * math.cos(1.7 * k * T) + 0.05 * 4.1 * math.cos(4.1 * k * T)
    return position(k), velocity, position(max(k - 1, 0))


def play_against_leader(player: object) -> np.ndarray:
    """The player's (x, v) after each step against `leader`, shape (N_STEPS, 2)."""
    player.reset(seed=0)  # type: ignore[attr-defined]
    out = []
    for k in range(N_STEPS):
        out.append(player.step(Observation.of_partner(k, *leader(k))))  # type: ignore[attr-defined]
    states = np.array(out)
    assert np.all(np.abs(states[:, 0]) < 0.5), "the check needs a trajectory off the walls"
    return states


def integrate(rates, y0: np.ndarray, t0: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    return solve_ivp(rates, (t0, t0 + T), y0, **TIGHT).y[:, -1]


def test_rpc_step_matches_solve_ivp() -> None:
    """Zhai et al.'s equations (section 6.3.1) with their published parameters."""
    player = ReactivePredictivePlayer()
    omegas = np.array([0.025, 0.05, 0.075, 0.1, 0.125])
    k_gain, lam = 30.0, 0.01

    def rates(t: float, y: np.ndarray, r_v: float) -> np.ndarray:
        sines, cosines = np.sin(omegas * t), np.cos(omegas * t)
        amplitudes = y[3:8]
        error = r_v - amplitudes @ sines
        return np.concatenate(
            [
                [y[1], amplitudes @ (omegas * cosines) + y[2], k_gain * (r_v - y[1])],
                lam * error * sines,
            ]
        )

    y = np.zeros(8)
    expected = []
    for k in range(N_STEPS):
        _, r_v, _ = leader(k)
        y = integrate(lambda t, z, b=r_v: rates(t, z, b), y, k * T)
        expected.append([y[0], y[1]])
    np.testing.assert_allclose(play_against_leader(player), expected, rtol=0, atol=1e-6)


def test_hkb_partner_step_matches_solve_ivp() -> None:
    alpha, beta, gamma, omega, a, b = 1.0, 1.0, 1.0, math.pi, -1.0, -10.0

    def rates(t: float, y: np.ndarray, r_p: float, r_v: float) -> list[float]:
        x, v = y
        coupling = (v - r_v) * (a + b * (x - r_p) ** 2)
        return [v, -(alpha * x**2 + beta * v**2 - gamma) * v - omega**2 * x + coupling]

    y = np.array([0.1, 0.0])
    expected = []
    for k in range(N_STEPS):
        r_p, r_v, _ = leader(k)
        y = integrate(lambda t, z, p=r_p, q=r_v: rates(t, z, p, q), y, k * T)
        expected.append(y.copy())
    np.testing.assert_allclose(play_against_leader(HKBPartner()), expected, rtol=0, atol=1e-6)


def test_excitator_step_matches_solve_ivp() -> None:
    a, b, tau, c, s = 1.05, 0.0, 1.0, 10.0, 0.25

    def rates(t: float, y: np.ndarray, r_p: float) -> list[float]:
        u, w = y
        return [tau * (u - u**3 / 3 + w) + c * (r_p / s - u), -(u - a + b * w) / tau]

    y = np.array([a, -(a - a**3 / 3)])
    expected = []
    for k in range(N_STEPS):
        r_p = leader(k)[0]
        y = integrate(lambda t, z, p=r_p: rates(t, z, p), y, k * T)
        expected.append([s * y[0], s * rates(0.0, y, r_p)[0]])
    np.testing.assert_allclose(play_against_leader(ExcitatorPartner()), expected, atol=1e-6)


def test_kuramoto_step_matches_solve_ivp() -> None:
    omega, coupling, amplitude = math.pi, 2.0, 0.3
    theta = np.array([0.0])
    expected = []
    for k in range(N_STEPS):
        x, v, _ = leader(k)
        phase = math.atan2(-v / omega, x)
        theta = integrate(lambda t, z, p=phase: [omega + coupling * math.sin(p - z[0])], theta, 0)
        rate = omega + coupling * math.sin(phase - theta[0])
        expected.append([amplitude * math.cos(theta[0]), -amplitude * rate * math.sin(theta[0])])
    np.testing.assert_allclose(play_against_leader(KuramotoPlayer()), expected, atol=1e-6)


def test_adaptive_step_matches_solve_ivp() -> None:
    """The sampled-data controller held over three periods, the HKB under it by solve_ivp."""
    alpha, beta, gamma, omega = 10.0, 20.0, -1.0, 0.1
    cp, delta, eta, bound = 40.0, 0.25, 30.0, 5.0
    hold = 3
    interval = hold * T
    x, v, a, b, u, sampled = 0.0, 0.0, -5.0, -5.0, 0.0, None
    expected = []
    for k in range(N_STEPS):
        if k % hold == 0:
            r_p = leader(k)[0]
            r_v = 0.0 if sampled is None else (r_p - sampled) / interval
            e, ev = x - r_p, v - r_v
            u_i = cp * math.exp(-delta * ev**2) * e
            if sampled is not None:
                da = -math.exp(-2 * a) * (e * ev + eta * e**2) - eta
                inner = omega**2 * x + (alpha * x**2 + beta * v**2 - gamma) * v - eta * ev - u_i
                db = ev * math.exp(-2 * b) * inner - eta
                a = float(np.clip(a + interval * da, -bound, bound))
                b = float(np.clip(b + interval * db, -bound, bound))
            u = (a + b * e**2) * ev - u_i
            sampled = r_p

        def rates(t: float, y: np.ndarray, held: float = u) -> list[float]:
            return [
                y[1],
                -(alpha * y[0] ** 2 + beta * y[1] ** 2 - gamma) * y[1] - omega**2 * y[0] + held,
            ]

        x, v = integrate(rates, np.array([x, v]), 0.0)
        expected.append([x, v])
    player = AdaptivePlayer({"sampling": interval})
    np.testing.assert_allclose(play_against_leader(player), expected, atol=1e-6)


@pytest.mark.parametrize("name", list(MODEL_PARTNERS))
def test_every_partner_passes_the_player_checks(name: str) -> None:
    check_player(lambda: load_player(name, "follower"))
    check_player(lambda: load_player(name, "group_leader"), n_steps=60)


@pytest.mark.parametrize("name", list(MODEL_PARTNERS))
def test_every_partner_plays_in_a_group(name: str) -> None:
    players = [load_player(spec, "group") for spec in (name, name, "kuramoto:omega=2.5")]
    session = play(players, duration=3.0, seed=1)
    assert session.positions.shape == (3, 101)
    assert np.all(np.isfinite(session.positions))
    assert np.ptp(session.positions[0]) > 0.0


def test_batch_engine_refuses_partners_in_one_line() -> None:
    players = [load_player("adaptive", "leader"), load_player("hkb", "follower")]
    with pytest.raises(InputError, match="batch engine cannot run AdaptivePlayer"):
        list(run_sessions([players], 1, duration=1.0, n_jobs=1, progress=False))


def test_spec_parameters_are_read_and_checked() -> None:
    player = load_player("adaptive:cp=30, delta=0.5,sampling=0.03", "follower")
    assert isinstance(player, AdaptivePlayer)
    assert (player.cp, player.delta, player.hold) == (30.0, 0.5, 1)
    assert load_player("adaptive:leader_cp=12", "leader").cp == 12.0  # type: ignore[attr-defined]
    with pytest.raises(InputError, match=r"^rpc:kk=3: unknown parameter 'kk'; rpc takes k, lam"):
        load_player("rpc:kk=3", "follower")
    with pytest.raises(InputError, match="hkb:gamma=x: gamma must be a number"):
        load_player("hkb:gamma=x", "follower")
    with pytest.raises(InputError, match="amplitude 0.9 is outside"):
        load_player("kuramoto:amplitude=0.9", "group")
    with pytest.raises(InputError, match="is not key=value"):
        load_player("excitator:a", "follower")
    with pytest.raises(InputError, match="given twice"):
        load_player("excitator:a=1,a=2", "follower")


def test_rpc_oscillates_around_its_leader(zhai_trials_100hz: list) -> None:  # type: ignore[type-arg]
    """Velocity integral feedback: the follower's velocity swings round its leader's at sqrt(k)."""
    trial = next(t for t in zhai_trials_100hz if t.group == "slow")
    session = play([RecordedPlayer(trial), load_player("rpc", "follower")], duration=30.0, seed=0)
    for error in (
        session.velocities[1] - session.velocities[0],
        session.positions[1] - session.positions[0],
    ):
        spectrum = np.abs(np.fft.rfft(error - error.mean()))
        frequencies = np.fft.rfftfreq(error.size, T)
        peak = frequencies[np.argmax(spectrum[1:]) + 1]
        assert abs(2 * math.pi * peak - math.sqrt(30.0)) < 1.0
        crossings = np.count_nonzero(np.diff(np.sign(error)) != 0)
        assert crossings > 30  # the error changes sign again and again: an oscillation, not a lag
