"""Partners checked when made (ranges, orders, plain numbers, a dry run) and a diverging player
ending its session at the sample it diverged, naming it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.engine.loop import Engine, play
from mirror_avatar.players.base import (
    DRY_RUN_MAX_SPEED,
    Observation,
    Player,
    PlayerDiverged,
    dry_run,
)
from mirror_avatar.players.dynamical import parse_number
from mirror_avatar.specs import MODEL_PARTNERS, load_player

DIVERGING = [
    ("excitator:a=-10,b=10,tau=0.01", "tau=0.01 (default 1)"),
    ("hkb:a=1000,b=-1000,alpha=0,beta=0,gamma=-100,omega=100", "a=1000 (default -1)"),
    ("rpc:k=10000,lam=1000,omega_low=0,omega_high=100", "lam=1000 (default 0.01)"),
]


class Exploding(Player):
    """A player whose position is multiplied by 1e200 at every step: infinite by its third."""

    label = "exploding"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        self.x = 0.1
        return self.x, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        self.x *= 1e200
        return self.x, 0.0


class Still(Player):
    """A player standing at 0."""

    label = "still"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return 0.0, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        return 0.0, 0.0


@pytest.mark.parametrize(("spec", "given"), DIVERGING)
def test_a_diverging_partner_is_refused_when_made_naming_its_parameters(spec, given):
    with pytest.raises(InputError) as error:
        load_player(spec, "follower")
    text = str(error.value)
    assert text.startswith(f"{spec}: diverges: ") and given in text and "\n" not in text, text


def test_the_rpc_frequencies_must_be_in_order():
    with pytest.raises(InputError) as error:
        load_player("rpc:k=10000,lam=1000,omega_low=100,omega_high=0", "follower")
    assert str(error.value) == (
        "rpc:k=10000,lam=1000,omega_low=100,omega_high=0: omega_low 100 must be below omega_high 0"
    )


@pytest.mark.parametrize(
    "raw", ["1_0", "\u0661\u0660", "\u0661", "inf", "nan", "0x10", "1e", ".", ""]
)
def test_spec_numbers_other_than_plain_ascii_decimals_are_refused(raw):
    assert parse_number(raw) is None
    with pytest.raises(InputError, match=r"^hkb:a=.*: a must be a number in ASCII decimals"):
        load_player(f"hkb:a={raw}", "follower")


@pytest.mark.parametrize(
    ("raw", "value"), [("-2", -2.0), ("+.5", 0.5), ("3e-2", 0.03), ("1E+1", 10.0), ("2.", 2.0)]
)
def test_plain_decimal_numbers_are_read(raw, value):
    assert parse_number(f" {raw} ") == value
    assert load_player(f"hkb:a={raw}", "follower").options["a"] == value  # type: ignore[attr-defined]


def test_the_adaptive_player_on_a_stiff_spring_stays_finite():
    """Its RK4 substeps once ignored the spring force: NaN at sample 577 of this leader."""
    spec = "adaptive:alpha=1000,beta=1000,gamma=-100,omega=100,cp=10000"
    player = load_player(spec, "follower")
    leader = load_zhai2017()[3].resampled(1 / player.period)
    x, v = leader.positions, leader.velocity()
    player.reset(seed=0)
    states = [
        player.step(Observation.of_partner(k, x[k], v[k], x[max(k - 1, 0)])) for k in range(700)
    ]
    assert np.isfinite(states).all()


def test_the_engine_ends_a_session_at_the_sample_a_player_diverges():
    engine = Engine([Still(), Exploding()])
    engine.reset(seed=0, n_samples=10)
    with pytest.raises(PlayerDiverged) as error:
        engine.step()
    assert str(error.value) == (
        "player 1 (exploding): diverged at sample 1 (0.03 s): it returned position 1e+199 and "
        "velocity 0.0, not finite or beyond 1e+06; the session ends there (give its spec "
        "parameters nearer their defaults)"
    )
    assert (error.value.index, error.value.sample) == (1, 1)
    session = engine.session()
    assert session.n_samples == 1 and np.isfinite(session.positions).all()
    with pytest.raises(PlayerDiverged, match=r"^player 1 \(exploding\): diverged at sample 1"):
        play([Still(), Exploding()], duration=1.0, seed=0)


def test_a_dry_run_refuses_a_player_outrunning_its_bound():
    class Racing(Still):
        def step(self, observation: Observation) -> tuple[float, float]:
            return 0.0, 2 * DRY_RUN_MAX_SPEED

    with pytest.raises(InputError, match=r"^racer: diverges: 0.03 s into a dry run .* speed 200"):
        dry_run(Racing(), "racer")
    with pytest.raises(
        InputError, match=r"^boom: diverges: .* 1e\+199 left the playing range -0.5..0.5 \(hint\)$"
    ):
        dry_run(Exploding(), "boom", "hint")
    dry_run(Still(), "still")
    assert math.isfinite(load_player("bundled:slow", "follower").reset(seed=1)[0])


def test_the_methods_list_every_partners_parameter_with_its_default_and_range():
    methods = (Path(__file__).parents[2] / "docs" / "METHODS.md").read_text()
    for name, kind in MODEL_PARTNERS.items():
        for key, p in kind.PARAMETERS.items():
            meaning = p.meaning.replace("|", "\\|")
            row = f"| `{name}` | `{key}` | {p.default:g} | {p.low:g} .. {p.high:g} | {meaning} |"
            assert row in methods, row
