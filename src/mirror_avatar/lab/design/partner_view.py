"""How a condition's pages draw the partners when the people's links differ.

A condition declares it with three keys (`mirror_avatar.lab.design.protocol_keys.CONDITION`)::

    partner_view = "equalised"   # or "as_arrives" (the default), "predicted"
    view_lag = 0.2               # equalised: every page draws a sample 0.2 s after it was taken
    view_horizon = 0.15          # predicted: partners drawn 0.15 s ahead of their last sample

``view_lag`` left out: the slowest page's one-way delay (half the 95th percentile of its round
trips), measured while the trial runs;
``view_horizon`` left out: each page's own one-way delay. What each handling does is
`mirror_avatar.realtime.partner_view`'s (METHODS section 19); a lag or a horizon given to
another handling is refused, as is any handling but ``as_arrives`` for a condition whose
avatar runs in the page (the page draws it as it steps it).
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

    ``handling`` is one of `mirror_avatar.realtime.partner_view.HANDLINGS`.
    """

    handling: str = "as_arrives"
    lag_s: float | None = None
    horizon_s: float | None = None

    def to_json(self) -> dict[str, Any]:
        """Return the view as a trial's sidecar records it (``lab.partner_view``)."""
        return {"handling": self.handling, "lag_s": self.lag_s, "horizon_s": self.horizon_s}


def parse_partner_view(
    check: Checker, data: dict[str, Any], where: str, in_page: str | None
) -> PartnerView:
    """Read a condition's ``partner_view``, ``view_lag`` and ``view_horizon`` (see the module).

    ``in_page`` is the label of the condition's avatar that runs in the page, or None.
    """
    handling, lag, horizon = (
        check.setting(data, where, CONDITION[key])
        for key in ("partner_view", "view_lag", "view_horizon")
    )
    for key, owner in KEYS.items():
        if key in data and handling != owner:
            raise check.error(
                f"{where}.{key}",
                f"belongs to partner_view = {owner!r}, not {handling!r}",
                f'set partner_view = "{owner}" or leave out {key}',
            )
    if in_page is not None and handling != "as_arrives":
        raise check.error(
            f"{where}.partner_view",
            f"{in_page} runs in the browser, whose page draws it as it steps it",
            f'leave out partner_view, or set runs = "server" on {in_page}',
        )
    return PartnerView(str(handling), lag, horizon)
