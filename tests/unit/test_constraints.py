"""Declared constraints: membership, descriptions, refused values and the error's data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirror_avatar.common.constraints import (
    ConstraintError,
    Either,
    Flag,
    Interval,
    Options,
    Setting,
    check,
    settings_table,
)
from mirror_avatar.common.errors import InputError


def test_an_interval_admits_finite_numbers_between_its_ends():
    seconds = Interval(float, 0.0, 600.0, "right", "s")
    assert 0.5 in seconds and 600.0 in seconds and np.float64(3.0) in seconds and 2 in seconds
    for refused in (0.0, -1.0, 600.5, math.nan, math.inf, -math.inf, "3", None, True):
        assert refused not in seconds
    assert str(seconds) == "a number in (0, 600] s"


def test_an_integer_interval_admits_integers_only():
    count = Interval(int, 0, 9999)
    assert 0 in count and 9999 in count and np.int64(7) in count
    for refused in (-1, 10_000, 2.0, 0.5, math.nan, False, 10**400):
        assert refused not in count
    assert str(count) == "a whole number in [0, 9999]"


def test_open_and_unbounded_ends_are_described_and_refused():
    positive = Interval(float, 0.0, None, "neither")
    assert str(positive) == "a number in (0, inf)" and 1e300 in positive
    assert 0.0 in positive.refused() and -1.0 in positive.refused()
    anywhere = Interval(float, None, None)
    assert str(anywhere) == "a number in (-inf, inf)" and 1e308 in anywhere


@pytest.mark.parametrize(
    "constraint",
    [
        Interval(float, 0.0, 1.0),
        Interval(float, -1.0, 1.0, "neither"),
        Interval(float, 0.0, None, "left"),
        Interval(int, 2, 64),
        Interval(int, 1, None),
        Options(("shift", "pseudo")),
        Options(("pointer",)),
        Flag(),
        Interval(int, 4, 4096, multiple_of=2),
        Interval(int, None, 9, multiple_of=3),
        Either((Options(("auto",)), Interval(int, 2, 4096))),
    ],
)
def test_every_value_a_constraint_names_as_refused_is_refused(constraint):
    assert constraint.refused()
    for value in constraint.refused():
        assert value not in constraint


def test_a_setting_reads_its_value_or_default_and_names_its_path_when_refused():
    trials = Setting("trials", "trials", Interval(int, 1, 100), 1)
    game = Setting("game", "the game", Options(("solo", "joint")))
    assert trials.read({}) == 1 and trials.read({"trials": 4}, "blocks[0]") == 4
    with pytest.raises(ConstraintError) as caught:
        trials.read({"trials": 0}, "blocks[0]")
    assert (caught.value.key, caught.value.value) == ("blocks[0].trials", 0)
    with pytest.raises(ConstraintError, match="game: None is not allowed"):
        game.read({})
    assert Setting("graph", "who sees whom", default="complete", allowed="a name").read({}) == (
        "complete"
    )


def test_settings_are_tabled_with_their_meaning_allowed_values_and_default():
    table = settings_table((
        Setting("trials", "trials of the condition", Interval(int, 1, 100), 1),
        Setting("show_metrics", "the end screen shows metrics", Flag(), True),
        Setting("seed", "the seed", Interval(int, 0, 9), None, default_shown="drawn"),
        Setting("game", "what is played", Options(("solo", "joint"))),
    ))  # fmt: skip
    assert table.splitlines() == [
        "| key | sets | allowed | default |",
        "|---|---|---|---|",
        "| `trials` | trials of the condition | a whole number in [1, 100] | 1 |",
        "| `show_metrics` | the end screen shows metrics | true or false | true |",
        "| `seed` | the seed | a whole number in [0, 9] | drawn |",
        "| `game` | what is played | one of solo, joint | required |",
    ]


def test_options_admit_their_words_only():
    kinds = Options(("shift", "pseudo"))
    assert "shift" in kinds and "pseudo" in kinds and "Shift" not in kinds and 0 not in kinds
    assert str(kinds) == "one of shift, pseudo"


def test_a_refusal_is_one_input_error_line_carrying_its_key_value_and_constraint():
    share = Interval(float, 0.0, 1.0)
    assert check("--leader-share", 0.6, share) == 0.6
    with pytest.raises(ConstraintError) as caught:
        check("--leader-share", math.nan, share)
    error = caught.value
    assert isinstance(error, InputError)
    assert (error.key, error.constraint) == ("--leader-share", share) and math.isnan(error.value)
    assert str(error) == "--leader-share: nan is not allowed; give a number in [0, 1]"


def test_an_interval_with_a_step_admits_its_multiples_only():
    even = Interval(int, 4, 64, multiple_of=2)
    assert 4 in even and 64 in even and np.int64(10) in even
    for refused in (5, 63, 2, 66, 10.0):
        assert refused not in even
    assert str(even) == "a multiple of 2 in [4, 64]"
    assert 5 in even.refused()


def test_either_admits_what_one_of_its_choices_admits():
    size = Either((Options(("auto",)), Interval(int, 2, 4096)))
    assert "auto" in size and 2 in size and np.int64(4096) in size
    for refused in ("Auto", "", 1, 4097, 2.5, None, True):
        assert refused not in size
    assert str(size) == "auto or a whole number in [2, 4096]"
    assert size.refused() == ["", "auto|", 0, 8192]


def test_a_refusal_read_from_a_file_names_the_file_then_the_key_and_cuts_long_values():
    error = ConstraintError("window", 10**4000, Interval(int, 4, 64), "model.npz")
    assert (error.source, error.key, error.value) == ("model.npz", "window", 10**4000)
    text = str(error)
    assert text.startswith("model.npz: window: 1000") and len(text) < 120
    assert text.endswith(" is not allowed; give a whole number in [4, 64]")
