"""How a condition's pages draw the partners when the people's links differ.

A condition declares it with these keys (`mirror_avatar.lab.design.protocol_keys.CONDITION`)::

    partner_view = "equalised"   # or "as_arrives" (the default), "predicted"
    view_lag = 0.2               # equalised: every page draws a sample 0.2 s after it was taken
    view_horizon = 0.15          # predicted: partners drawn 0.15 s ahead of their last sample
    delay_jitter = 0.05          # the condition's `delay` varied by a jitter of SD 0.05 s
    jitter_distribution = "exponential"  # or "normal" (the default), "uniform"

``view_lag`` left out: the slowest page's one-way delay (half the 95th percentile of its round
trips), measured while the trial runs;
``view_horizon`` left out: each page's own one-way delay. What each handling does is
`mirror_avatar.realtime.partner_view`'s (METHODS section 19); a lag or a horizon given to
another handling is refused, as is any handling but ``as_arrives`` for a condition whose
avatar runs in the page (the page draws it as it steps it), as is a jitter there or a
distribution without a jitter (`mirror_avatar.realtime.partner_view.jitter_draw`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.lab.design.protocol_keys import CONDITION

KEYS = {"view_lag": "equalised", "view_horizon": "predicted"}
"""Each handling's own key, and the handling it belongs to."""


@dataclass(frozen=True)
class PartnerView:
    """How the pages draw the partners: ``handling`` and its lag or horizon (s; None: measured).

    ``handling`` is one of `mirror_avatar.realtime.partner_view.HANDLINGS`; ``jitter_s`` the SD
    (s) of the jitter added to the condition's delay, drawn from ``jitter_distribution`` (one
    of `mirror_avatar.realtime.partner_view.JITTERS`).
    """

    handling: str = "as_arrives"
    lag_s: float | None = None
    horizon_s: float | None = None
    jitter_s: float = 0.0
    jitter_distribution: str = "normal"

    def to_json(self) -> dict[str, Any]:
        """Return the view as a trial's sidecar records it (``lab.partner_view``)."""
        return {
            "handling": self.handling,
            "lag_s": self.lag_s,
            "horizon_s": self.horizon_s,
            "jitter_s": self.jitter_s,
            "jitter_distribution": self.jitter_distribution,
        }


def parse_partner_view(
    check: Checker, data: dict[str, Any], where: str, in_page: str | None
) -> PartnerView:
    """Read a condition's ``partner_view``, ``view_lag`` and ``view_horizon`` (see the module).

    ``in_page`` is the label of the condition's avatar that runs in the page, or None.
    """
    handling, lag, horizon, jitter, distribution = (
        check.setting(data, where, CONDITION[key])
        for key in ("partner_view", "view_lag", "view_horizon", "delay_jitter",
                    "jitter_distribution")
    )  # fmt: skip
    if "jitter_distribution" in data and not jitter:
        raise check.error(
            f"{where}.jitter_distribution",
            "is the distribution of a jitter this condition does not have",
            "set delay_jitter or leave out jitter_distribution",
        )
    for key, owner in KEYS.items():
        if key in data and handling != owner:
            raise check.error(
                f"{where}.{key}",
                f"belongs to partner_view = {owner!r}, not {handling!r}",
                f'set partner_view = "{owner}" or leave out {key}',
            )
    changed = [key for key in ("partner_view", "delay_jitter") if key in data]
    if in_page is not None and changed:
        raise check.error(
            f"{where}.{changed[0]}",
            f"{in_page} runs in the browser, whose page draws it as it steps it",
            f'leave out {changed[0]}, or set runs = "server" on {in_page}',
        )
    return PartnerView(str(handling), lag, horizon, float(jitter), str(distribution))
