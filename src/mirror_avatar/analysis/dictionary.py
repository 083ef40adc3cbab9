"""The study table's data dictionary: every column's description, units, levels and role.

Each column of `mirror_avatar.analysis.table` is described BIDS-style (``Description``,
``Units`` where it has units, ``Levels`` for a categorical one) plus ``Role``: ``identifier``
(who and which trial), ``design`` (what the protocol set: the factors), ``measure`` (computed
from the recording) or ``answer`` (what the person answered), so a report finds its measures
and factors by role.
"""

from __future__ import annotations

from typing import Any

ROLES = ("identifier", "design", "measure", "answer")
"""What a column is, as the dictionary's ``Role`` says."""

DESIGN_COLUMNS: dict[str, dict[str, Any]] = {
    "participant": {"Description": "The study participant (pNNN: their number in the "
                    "counterbalancing), or the session id of a plain lab session",
                    "Role": "identifier"},
    "session": {"Description": "The lab session the trial was recorded in", "Role": "identifier"},
    "person": {"Description": "The player's label in the protocol (P1, A1...)",
               "Role": "identifier"},
    "player_kind": {"Description": "Who played in this slot",
                    "Levels": {"person": "a person at a page or device",
                               "avatar": "a computer player"},
                    "Role": "design"},
    "block": {"Description": "The block's position in the participant's run (1-based)",
              "Role": "design"},
    "condition": {"Description": "The study protocol's condition (a plain lab session: the "
                  "game, solo, leader_follower, joint or group)", "Role": "design"},
    "trial": {"Description": "The trial's number in the participant's run (1-based)",
              "Role": "identifier"},
    "position": {"Description": "The condition's position in the participant's order "
                 "(1-based)", "Role": "design"},
    "partners": {"Description": "The labels of every other player of the trial, joined by +",
                 "Role": "design"},
    "partner_kind": {"Description": "The true kind of the player's partners",
                     "Levels": {"person": "every partner a person",
                                "avatar": "every partner a computer player",
                                "mixed": "persons and computer players",
                                "none": "no partner (a solo trial)"},
                     "Role": "design"},
    "delay_s": {"Description": "Visual delay of the partners on the persons' pages",
                "Units": "s", "Role": "design"},
    "occluded": {"Description": "Whether the partners were hidden during part of the trial",
                 "Role": "design"},
    "perturbations": {"Description": "Changes of an avatar during the trial",
                      "Role": "design"},
}  # fmt: skip
"""The identifier and design columns, in table order."""

_UNITLESS = ""

MEASURES: dict[str, tuple[str, str]] = {
    "rmse": ("RMS of the difference of the two players' positions (a group: of the player's "
             "against its neighbours' mean)", "playing range units"),
    "phase_locking": ("Phase locking, the mean resultant length of the relative phase (the "
                      "field's CV; 1: phase locked; a group: against the neighbours' mean)",
                      _UNITLESS),
    "mean_relative_phase": ("Circular mean of the relative phase, player 0 minus player 1",
                            "rad"),
    "sd_relative_phase": ("Circular SD of the relative phase", "rad"),
    "time_lag": ("Time lag at the cross-correlation peak, positive when player 0 leads "
                 "(a group: the player against its neighbours' mean)", "s"),
    "max_cross_correlation": ("Peak of the cross-correlation of the positions", _UNITLESS),
    "emd_players": ("EMD between the two players' velocity IMS", _UNITLESS),
    "jitter_index": ("The player's jitter index: share of velocity power in the jitter band",
                     _UNITLESS),
    "co_confidence_rate": ("Share of the trial in co-confidence (moving together smoothly)",
                           _UNITLESS),
    "co_confidence_count": ("Co-confidence segments", _UNITLESS),
    "co_confidence_mean_length": ("Mean length of the co-confidence segments", "s"),
    "synchrony_share": ("Share of the trial in synchrony episodes", _UNITLESS),
    "synchrony_entries": ("Entries into synchrony", _UNITLESS),
    "synchrony_exits": ("Exits from synchrony", _UNITLESS),
    "synchrony_mean_dwell": ("Mean dwell in synchrony", "s"),
    "synchrony_mean_gap": ("Mean gap between synchrony episodes", "s"),
    "leader": ("Label of the player who led (windowed cross-correlation), none if neither",
               _UNITLESS),
    "leader_share": ("Share of windows the leader leads", _UNITLESS),
    "leader_lag_s": ("The leader's lag", "s"),
    "leadership_strength": ("Mean picked peak of the windowed cross-correlation", _UNITLESS),
    "transfer_entropy_0_to_1": ("Transfer entropy from player 0's velocity to player 1's",
                                "bits"),
    "transfer_entropy_1_to_0": ("Transfer entropy from player 1's velocity to player 0's",
                                "bits"),
    "influence": ("The player's influence: mean transfer entropy to the others", "bits"),
    "group_synchronisation": ("Group synchronisation, time mean of rho_g", _UNITLESS),
    "group_synchronisation_sd": ("SD over time of rho_g", _UNITLESS),
    "kuramoto_order": ("Time mean of the Kuramoto order parameter r", _UNITLESS),
    "synchronisation": ("The player's synchronisation to the group, rho_k", _UNITLESS),
    "relative_phase_to_group": ("The player's mean phase relative to the group", "rad"),
    "mean_phase_locking": ("Mean over the players of their phase locking to their "
                           "neighbours", _UNITLESS),
    "mean_rmse": ("Mean over the players of their RMS against their neighbours",
                  "playing range units"),
}  # fmt: skip
"""Every measure column: its key (`mirror_avatar.metrics` names), description and units."""

P_VALUE_OF = {"time_lag_p_value": "max_cross_correlation"}
"""p-value columns named after another measure than the one tested."""


def p_value_column(measure: str) -> str:
    """Return the column of a tested measure's p-value against surrogates."""
    inverse = {tested: key for key, tested in P_VALUE_OF.items()}
    return inverse.get(measure, f"{measure}_p_value")


def measure_info(column: str) -> dict[str, Any]:
    """Describe a measure column (a measure or a measure's p-value)."""
    tested = P_VALUE_OF.get(column, column.removesuffix("_p_value"))
    if column != tested:
        text = MEASURES[tested][0]
        return {"Description": f"p-value against surrogates of: {text}", "Role": "measure"}
    text, units = MEASURES[column]
    return {"Description": text} | ({"Units": units} if units else {}) | {"Role": "measure"}


GUESS_COLUMNS: dict[str, dict[str, Any]] = {
    "guess_kind": {"Description": "What the person said their partner was, from their answer "
                   "to the person-or-computer question",
                   "Levels": {"person": "a person", "avatar": "a computer"}, "Role": "answer"},
    "guess_correct": {"Description": "Whether guess_kind is the partners' true kind "
                      "(partner_kind)", "Role": "answer"},
    "guess_confidence": {"Description": "The Likert point of the confidence question asked "
                         "with the guess (empty when none was asked)", "Role": "answer"},
}  # fmt: skip
"""The columns of the person-or-computer question."""
