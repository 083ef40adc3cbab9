"""A registered analysis plan: a study's preregistration, written from its protocol, and checked.

`registered_plan` gathers from a protocol and its ``[analysis]`` what a preregistration states
(hypotheses, design, measures, exclusions, models, sample size and its justification from a
``study power`` output); `plan_hash` is the SHA-256 of its canonical JSON (keys sorted, no
spaces, UTF-8), so any edit of the plan changes it. `plan_deviations` compares the analysis a
report runs with the registered one and says each difference. docs/METHODS.md, section 15.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from mirror_avatar.analysis.dictionary import MEASURES, column_label
from mirror_avatar.analysis.hypothesis import EXPLORATORY_MODEL, confirmatory_model
from mirror_avatar.analysis.statistics import MIXED_MODEL
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import json_text, write_atomic_files
from mirror_avatar.files.trial_io import MAX_SIDECAR_BYTES
from mirror_avatar.files.user_files import parse_json, read_text
from mirror_avatar.lab.design.protocol import Analysis, Condition, Protocol

EXCLUSIONS = (
    "Only the persons' rows are analysed: an avatar is not a participant.",
    "Trials that stopped before their end (complete false: aborted, ended by a drop or a "
    "crash) are left out.",
    "Infinite values of a measure are treated as missing.",
    "A participant without a mean in both conditions of the contrast is left out of the "
    "confirmatory test of that measure.",
)
"""What the study report leaves out (`mirror_avatar.analysis.study_report.analysed_rows`)."""


def registered_models(analysis: Analysis) -> dict[str, str]:
    """Return the models a study report runs for ``analysis``, as the plan registers them."""
    return {
        "confirmatory": confirmatory_model(analysis.primary), "mixed_model": MIXED_MODEL,
        "exploratory": EXPLORATORY_MODEL,
    }  # fmt: skip


@dataclass(frozen=True)
class RegisteredPlan:
    """A plan read back from its ``plan.json``.

    Parameters
    ----------
    content
        The plan (`registered_plan`'s).
    sha256
        The hash written with it.
    source
        Its file.
    """

    content: dict[str, Any]
    sha256: str
    source: Path

    @property
    def intact(self) -> bool:
        """Whether the content still has the hash written with it."""
        return plan_hash(self.content) == self.sha256


def registered_plan(protocol: Protocol, power: dict[str, Any] | None) -> dict[str, Any]:
    """Gather the preregistration of a protocol with an ``[analysis]``.

    ``power``: a ``study power`` output's ``power.json``, the sample size's justification.

    Raises
    ------
    InputError
        The protocol declares no ``[analysis]``, or ``power`` is of another hypothesis.
    """
    analysis = protocol.analysis
    if analysis is None:
        raise InputError(protocol.source, "no [analysis]: a plan registers a declared hypothesis")
    hypothesis = asdict(analysis) | {"primary": list(analysis.primary)}
    if power is not None and power["hypothesis"] != hypothesis:
        raise InputError("--power", "its power.json is of another hypothesis than the protocol's")
    return {
        "title": protocol.title, "protocol": Path(protocol.source).name,
        "hypothesis": hypothesis, "hypotheses": _hypotheses(analysis),
        "design": _design(protocol),
        "measures": [{"column": m, "label": column_label(m),
                      "units": MEASURES.get(m, ("", ""))[1]} for m in analysis.primary],
        "exploratory": "every other measure of the study table and every rating, each condition "
                       "against the reference",
        "exclusions": list(EXCLUSIONS), "models": registered_models(analysis),
        "sample_size": _sample_size(power),
    }  # fmt: skip


def _hypotheses(analysis: Analysis) -> list[str]:
    """Say each primary measure's hypothesis in words."""
    compared = {
        "lower": f"is lower in {analysis.condition!r} than in {analysis.reference!r}",
        "higher": f"is higher in {analysis.condition!r} than in {analysis.reference!r}",
        "two-sided": f"differs between {analysis.condition!r} and {analysis.reference!r}",
    }[analysis.direction]
    return [
        f"{column_label(m)} {compared}, by at least {analysis.smallest_effect:g} (the smallest "
        f"effect of interest), at alpha {analysis.alpha:g}"
        for m in analysis.primary
    ]


def _design(protocol: Protocol) -> dict[str, Any]:
    return {
        "block_order": protocol.block_order, "seed": protocol.seed,
        "blocks": [{"name": block.name, "order": block.order,
                    "conditions": [_condition(c) for c in block.conditions]}
                   for block in protocol.blocks],
    }  # fmt: skip


def _condition(condition: Condition) -> dict[str, Any]:
    return {
        "name": condition.name, "game": condition.game, "trials": condition.trials,
        "duration_s": condition.settings.get("duration"), "delay_s": condition.delay,
        "players": [f"{p.label} ({p.kind})" for p in condition.players],
    }  # fmt: skip


def _sample_size(power: dict[str, Any] | None) -> dict[str, Any]:
    if power is None:
        return {"participants": None, "justification": "no power analysis given"}
    return {
        "participants": power["smallest_participants"], "target_power": power["target"],
        "effect": power["effect"], "simulations": power["simulations"], "seed": power["seed"],
        "pilot_table": power["table"], "pilot_table_sha256": power["table_sha256"],
        "power": power["power"],
        "justification": f"the smallest number of participants whose simulated power of the "
                         f"declared test reaches {power['target']:g} with the planned effect "
                         f"{power['effect']:g} and the pilot's spread (`mirror-avatar study "
                         f"power`, {power['simulations']} studies per number, seed "
                         f"{power['seed']})",
    }  # fmt: skip


def plan_hash(content: dict[str, Any]) -> str:
    """Return the hex SHA-256 of the plan's canonical JSON (sorted keys, no spaces, UTF-8)."""
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=False)  # fmt: skip
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def read_plan(path: Path) -> RegisteredPlan:
    """Read a ``plan.json`` (or the folder holding it) that `study plan` wrote.

    Raises
    ------
    InputError
        No plan there, or a file that is not one.
    """
    file = path / "plan.json" if path.is_dir() else path
    if not file.is_file():
        raise InputError(path, "no plan.json: give the file `study plan` wrote")
    found = parse_json(read_text(file, MAX_SIDECAR_BYTES), file)
    if not (isinstance(found, dict) and isinstance(found.get("plan"), dict)
            and isinstance(found.get("sha256"), str)):  # fmt: skip
        raise InputError(file, "is not a registered plan (`study plan` writes plan.json)")
    return RegisteredPlan(content=found["plan"], sha256=found["sha256"], source=file)


def plan_deviations(plan: RegisteredPlan, analysis: Analysis | None) -> list[str]:
    """Say each way the analysis run differs from the registered plan; none when it follows it.

    ``analysis``: the hypothesis the report tests, None when it tests none.
    """
    found = [] if plan.intact else [
        f"{plan.source.name} was edited after it was written: its content no longer has its "
        f"SHA-256 {plan.sha256[:12]}..."
    ]  # fmt: skip
    if analysis is None:
        return [*found, "the plan registers a hypothesis, but the report tests none (no "
                "--protocol, or no [analysis] in it)"]  # fmt: skip
    run = asdict(analysis) | {"primary": list(analysis.primary)}
    registered = plan.content.get("hypothesis", {})
    found += [
        f"{key}: registered {registered.get(key)!r}, run {value!r}"
        for key, value in run.items()
        if registered.get(key) != value
    ]
    models = plan.content.get("models", {})
    found += [
        f"{key} model: registered {models.get(key)!r}, run {value!r}"
        for key, value in registered_models(analysis).items()
        if models.get(key) != value
    ]
    return found


def plan_markdown(content: dict[str, Any], sha256: str) -> str:
    """Write the plan as a Markdown document, its hash last."""
    h = content["hypothesis"]
    lines = [f"# Analysis plan: {content['title'] or content['protocol']}", "",
             f"Protocol: `{content['protocol']}`.", "", "## Hypotheses", ""]  # fmt: skip
    lines += [f"- {sentence}." for sentence in content["hypotheses"]]
    lines += ["", f"Direction: {h['direction']}; contrast {h['condition']!r} minus "
              f"{h['reference']!r}; smallest effect of interest {h['smallest_effect']:g} in the "
              f"measures' units; alpha {h['alpha']:g}.", "", "## Design", ""]  # fmt: skip
    lines += _design_lines(content["design"])
    lines += ["", "## Measures", ""]
    lines += [f"- Primary: {m['label']} (`{m['column']}`" + (f", {m['units']})" if m["units"]
              else ")") for m in content["measures"]]  # fmt: skip
    lines += [f"- Exploratory: {content['exploratory']}.", "", "## Exclusions", ""]
    lines += [f"- {rule}" for rule in content["exclusions"]]
    lines += ["", "## Models", ""]
    lines += [f"- {name.replace('_', ' ')}: {text}." for name, text in content["models"].items()]
    size = content["sample_size"]
    lines += ["", "## Sample size", "", f"Participants: {size['participants']}; "
              f"justification: {size['justification']}.", "", "## Hash", "",
              f"SHA-256 of the plan's canonical JSON (plan.json): `{sha256}`", ""]  # fmt: skip
    return "\n".join(lines)


def _design_lines(design: dict[str, Any]) -> list[str]:
    lines = [f"Blocks in {design['block_order']} order (seed {design['seed']})."]
    for block in design["blocks"]:
        lines.append(f"- {block['name']}: conditions in {block['order']} order")
        lines += [f"  - {c['name']}: {c['game']}, {c['trials']} trial(s) of "
                  f"{c['duration_s']} s, delay {c['delay_s']:g} s, players "
                  f"{', '.join(c['players'])}" for c in block["conditions"]]  # fmt: skip
    return lines


PLAN_FILES = ("plan.md", "plan.json")
"""The files `write_plan` writes in its folder."""


def write_plan(content: dict[str, Any], out_dir: Path) -> str:
    """Write `PLAN_FILES` in ``out_dir`` (created if missing), all or none; return the hash."""
    sha256 = plan_hash(content)
    out_dir.mkdir(parents=True, exist_ok=True)
    markdown, document = PLAN_FILES
    write_atomic_files(out_dir, {
        markdown: plan_markdown(content, sha256),
        document: json_text({"plan": content, "sha256": sha256}),
    })  # fmt: skip
    return sha256
