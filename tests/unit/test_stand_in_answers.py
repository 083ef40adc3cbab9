"""A pilot's answer rules: parsed in one line, a person-or-computer question answered at a set
detection rate, and the right guess per trial read from the protocol's schedule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.stand_in_answers import (
    AnswerRule,
    check_rules,
    detected,
    right_guesses,
)

ROOT = Path(__file__).parents[2]
TURING = load_protocol(ROOT / "examples" / "protocols" / "turing.toml")
OPTIONS = ["a person", "a computer"]


@pytest.mark.parametrize("text", ["detect", "detect:", "detect:1.5", "detect:-0.1", "detect:x",
                                  "guess:0.5", "value"])  # fmt: skip
def test_a_rule_that_is_not_one_is_refused_in_one_line(text: str) -> None:
    with pytest.raises(InputError, match="is not a rule: give random, first, value:TEXT or "):
        AnswerRule.parse(text)
    assert AnswerRule.parse("detect:0.7") == AnswerRule("detect", "0.7")


def test_the_true_kind_is_named_at_the_rate_and_mixed_partners_at_random() -> None:
    rng = np.random.default_rng(3)
    draws = 4000
    for right, named in (("person", "a person"), ("avatar", "a computer")):
        share = np.mean([detected(OPTIONS, 0.7, right, rng) == named for _ in range(draws)])
        assert share == pytest.approx(0.7, abs=4 * np.sqrt(0.7 * 0.3 / draws))
    assert {detected(OPTIONS, 1.0, "avatar", rng) for _ in range(50)} == {"a computer"}
    mixed = np.mean([detected(OPTIONS, 1.0, None, rng) == "a person" for _ in range(draws)])
    assert mixed == pytest.approx(0.5, abs=4 * np.sqrt(0.25 / draws))


def test_the_right_guess_is_the_scheduled_partner_s_motion() -> None:
    # turing.toml: a recording replayed is a person's motion, the avatar a computer's
    for participant in range(4):
        steps = TURING.schedule(participant)
        expected = {n: "person" if step.name.startswith("recording") else "avatar"
                    for n, step in enumerate(steps, start=1)}  # fmt: skip
        assert right_guesses(TURING, participant, "P1") == expected
    assert set(right_guesses(TURING, 0, "A1").values()) == {"person"}  # A1's partner is P1


def test_detect_is_refused_for_a_question_that_is_not_person_or_computer() -> None:
    check_rules(TURING, {"partner": AnswerRule("detect", "0.7")})
    with pytest.raises(InputError, match="confidence=detect:0.7: question 'confidence' is not"):
        check_rules(TURING, {"confidence": AnswerRule("detect", "0.7")})
    with pytest.raises(InputError, match="the protocol asks no question 'mood'"):
        check_rules(TURING, {"mood": AnswerRule("detect", "0.7")})
