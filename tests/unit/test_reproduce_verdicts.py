"""The reproduction report's answers and its mode in words (issue 39.3: "quick False / sweeps
quick" was shown unexplained, and the verdicts were buried in each section's prose)."""

from __future__ import annotations

from mirror_avatar.experiments.verdicts import describe_mode, section_verdict


def test_the_mode_says_what_quick_and_full_change() -> None:
    quick = describe_mode(quick=True, full=False, agent="tabular")
    assert "quick run" in quick and "300 sessions instead of 4000" in quick
    assert "not expected to be met" in quick and "without --quick" in quick
    default = describe_mode(quick=False, full=False, agent="tabular")
    assert "long sweeps" in default and "give --full" in default
    assert "full size" in describe_mode(quick=False, full=True, agent="dqn")


def test_signature_verdict() -> None:
    metrics = {"styles_distinct": True, "between_within_ratio": 5.94, "groups": ["fast", "slow"],
               "max_between_overlap": 0.0, "min_half_overlap": 0.372}  # fmt: skip
    assert section_verdict("signature", metrics) == (
        "the 2 groups are told apart: their regions overlap at most 0.00, a group with its own "
        "halves at least 0.37; EMD between groups 5.9 x within"
    )
    unsure = section_verdict("signature", metrics | {"styles_distinct": None})
    assert unsure.startswith("EMD between groups 5.9 x within; no verdict")


def test_generator_verdict_names_the_failed_checks() -> None:
    metrics = {"checks": {"emd_within_1.5x_human": True, "all_identified": False},
               "identification_accuracy": 0.5}  # fmt: skip
    assert section_verdict("generator", metrics) == (
        "generated motion passes 1 of 2 checks (fails: all identified); 50% of generated "
        "trials identified as their style"
    )


def test_cyber_player_verdict_counts_partners_and_says_a_quick_run() -> None:
    def role(met: list[bool]) -> dict:
        return {"criteria": {f"VT{k}": {"all": ok} for k, ok in enumerate(met)}}

    metrics = {"follower": role([True, False, False]), "leader": role([True, True, False]),
               "training_sessions": 300, "agent": "tabular"}  # fmt: skip
    assert section_verdict("cyber_player", metrics) == (
        "reproduction criteria met as follower against 1 of 3 partners, as leader against 2 of "
        "3 partners (trained 300 sessions, a quick run; full: 4000)"
    )
    full = section_verdict("cyber_player", metrics | {"training_sessions": 4000})
    assert full.endswith("2 of 3 partners")


def test_curriculum_verdict_compares_the_ends_with_each_person() -> None:
    metrics = {"own_emd": {"patient": 0.02, "target": 0.005}, "stages": [
        {"method": "mixture", "EMD to patient": 0.01, "EMD to target": 0.09},
        {"method": "mixture", "EMD to patient": 0.09, "EMD to target": 0.004},
        {"method": "displacement", "EMD to patient": 0.03, "EMD to target": 0.09},
        {"method": "displacement", "EMD to patient": 0.09, "EMD to target": 0.006}]}  # fmt: skip
    assert section_verdict("curriculum", metrics) == (
        "mixture starts within the patient's variability, ends within the target's; "
        "displacement does NOT start within the patient's variability, does NOT end within "
        "the target's"
    )


def test_a_skipped_experiment_has_no_verdict() -> None:
    assert section_verdict("generator_complexity", {}) == ""
    assert section_verdict("unknown", {"x": 1}) == ""
