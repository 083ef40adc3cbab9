"""What is checked of a protocol once its file is parsed: its avatars built, its length.

When a protocol is loaded (``lab --protocol FILE`` or the console's ``POST /api/protocol``),
each condition's avatars (``avatar`` slots and ``person-or-avatar`` slots filled by the avatar)
are built in the role they play there (`mirror_avatar.lab.design.avatars.load_avatar`: the spec
read, its parameters checked against their ranges, a dry run against a scripted partner,
`mirror_avatar.players.base.dry_run`), and so is every player a perturbation hands an avatar
over to (`mirror_avatar.lab.design.avatars.successor_players`), so that a spec that names nothing,
cannot be read or diverges is refused before any participant plays, in one line naming the
condition, the spec and the problem (`AvatarCheck`; a spec is built once per role). An avatar that
runs in the browser (``runs = "browser"``) must be of a kind the page steps
(`mirror_avatar.browser.browser_arrays`), and no perturbation may change it. A participant's run
planned over `MAX_PLANNED_HOURS` is allowed with a warning (`long_run`), and so is an avatar run
in the browser, whose page knows its partner is an avatar (`page_knows`).
"""

from __future__ import annotations

from collections.abc import Sequence

from mirror_avatar.browser import browser_arrays
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.avatars import load_avatar, successor_players
from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.lab.design.perturbation import Perturbation
from mirror_avatar.lab.design.plan import SessionPlan
from mirror_avatar.players.base import dry_run
from mirror_avatar.players.dynamical import ModelPartner

MAX_PLANNED_HOURS = 4.0
"""A participant's run planned longer than this (trials and pauses, h) is read with a warning
(**choice**: half a working day of play)."""

FIX = "fix the avatar's spec, or choose another"
"""How to fix an avatar the check refuses."""

ON_SERVER = 'set runs = "server"'
"""How to fix an avatar the browser cannot run."""


class AvatarCheck:
    """Checks the avatars of a protocol's conditions, each spec once per role.

    Parameters
    ----------
    check
        Builds the protocol's one-line errors.
    """

    def __init__(self, check: Checker) -> None:
        self.check = check
        self._seen: set[tuple[str | None, str, str | None]] = set()

    def condition(
        self, where: str, name: str, plan: SessionPlan, perturb: Sequence[Perturbation]
    ) -> None:
        """Build and dry-run every avatar of a condition and each of its successors.

        Parameters
        ----------
        where
            The condition's key path (``blocks[1].conditions[0]``).
        name
            The condition's name.
        plan
            Its plan with every ``person-or-avatar`` slot filled by the avatar.
        perturb
            Its perturbations (avatars named by label).

        Raises
        ------
        InputError
            ``FILE: WHERE.players[K].spec: condition NAME: SPEC: problem (fix)``, or
            ``WHERE.perturb`` for a successor.
        """
        for k, slot in enumerate(plan.slots):
            built = (slot.spec, plan.roles[k], slot.runs)
            if slot.spec is None or built in self._seen:
                continue
            where_k = f"{where}.players[{k}]"
            try:
                player = load_avatar(slot.spec, plan.roles[k])
            except InputError as error:
                raise self.check.error(
                    f"{where_k}.spec", f"condition {name!r}: {error}", FIX
                ) from None
            if slot.runs == "browser":
                try:
                    browser_arrays(player, 0, 1)
                except InputError as error:
                    raise self.check.error(
                        f"{where_k}.runs", f"condition {name!r}: {error}", ON_SERVER
                    ) from None
            self._seen.add(built)
        labels = [slot.label for slot in plan.slots]
        indexed = [(labels.index(p.player), p) for p in perturb]
        for k, perturbation in indexed:
            if plan.slots[k].runs == "browser":
                raise self.check.error(
                    f"{where}.perturb",
                    f"condition {name!r}: {perturbation.player} runs in the browser, where no "
                    "perturbation can change it",
                    f"{ON_SERVER} on {perturbation.player}, or leave out its perturbations",
                )
        try:
            successors = successor_players(plan, indexed)
        except InputError as error:
            raise self.check.error(
                f"{where}.perturb", f"condition {name!r}: {error}", FIX
            ) from None
        for k, perturbation, player in successors:
            spec = f"{plan.slots[k].spec} with {perturbation.change} at {perturbation.at:g} s"
            hint = player.given() if isinstance(player, ModelPartner) else ""
            try:
                dry_run(player, spec, hint)
            except InputError as error:
                raise self.check.error(
                    f"{where}.perturb", f"condition {name!r}: {error}", "change the values set"
                ) from None


def long_run(source: str, plans: Sequence[SessionPlan]) -> tuple[str, ...]:
    """Warn of a participant's run, the conditions' ``plans``, planned over `MAX_PLANNED_HOURS`.

    The planned time is every condition's trials and the pauses between them.
    """
    hours = sum(p.trials * p.duration + (p.trials - 1) * p.pause for p in plans) / 3600.0
    if hours <= MAX_PLANNED_HOURS:
        return ()
    return (
        f"{source}: a participant's run is planned to last {hours:.1f} h ({hours / 24.0:.1f} "
        f"days) of trials and pauses, over {MAX_PLANNED_HOURS:g} h: check the trials, durations "
        "and pauses",
    )


def metrics_shown(source: str, where: str, plan: SessionPlan) -> tuple[str, ...]:
    """Warn of a condition at ``where`` whose end screens show a trial's metrics to partners.

    **Choice**: a warning, not a refusal: a study that tells its participants who their
    partners are may show them how they did.
    """
    if not plan.show_metrics or plan.condition == "solo":
        return ()
    return (
        f"{source}: {where}.show_metrics = true tells the participants who led and how long they "
        "moved together, which may give away a partner's kind: leave it out to keep them blind",
    )


def page_knows(source: str, where: str, plan: SessionPlan) -> tuple[str, ...]:
    """Warn of a condition at ``where`` whose avatar runs in its person's page.

    **Choice**: a warning, not a refusal: the page receives the avatar's player to step it, so a
    participant who reads the page's messages can tell their partner is an avatar.
    """
    in_page = [slot.label for slot in plan.slots if slot.runs == "browser"]
    if not in_page:
        return ()
    return (
        f"{source}: {where}: {in_page[0]} runs in the browser, so its person's page receives "
        "the avatar's player and could tell the partner's kind: set runs = \"server\" to keep "
        "the page blind",
    )
