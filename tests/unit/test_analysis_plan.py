"""A registered analysis plan: written from the protocol, its hash, and the report's check.

The plan's SHA-256 is the same on every run and changes with any edit; `study report --plan`
says nothing more than that it followed the plan when the protocol still declares the registered
hypothesis, and names each difference (direction, primary measure) or an edited plan.json.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from study_tables import make_study_rows, write_study_table
from test_analysis_hypothesis import ANALYSIS, protocol_text

from mirror_avatar.analysis.plan import plan_hash, read_plan, registered_plan
from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import protocol_from_text

LOWER_PHASE_LOCKING = ANALYSIS


def protocol_file(folder: Path, analysis: str = LOWER_PHASE_LOCKING) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "delay.toml"
    path.write_text(protocol_text(analysis))
    return path


def write_plan(folder: Path, protocol: Path, *options: str) -> Path:
    out = folder / "plan"
    assert main(["study", "plan", "--protocol", str(protocol), *options, "--out", str(out)]) == 0
    return out


def test_the_plan_states_the_hypothesis_and_the_design(tmp_path: Path) -> None:
    out = write_plan(tmp_path, protocol_file(tmp_path))
    written = json.loads((out / "plan.json").read_text())
    plan = written["plan"]
    assert plan["hypothesis"]["primary"] == ["phase_locking"]
    assert plan["hypothesis"]["direction"] == "lower"
    assert [c["name"] for c in plan["design"]["blocks"][0]["conditions"]] == [
        "delay 0.5 s", "no delay",
    ]  # fmt: skip
    assert plan["measures"][0]["label"] != "phase_locking"
    assert plan["sample_size"]["participants"] is None
    assert written["sha256"] == plan_hash(plan)
    markdown = (out / "plan.md").read_text()
    assert written["sha256"] in markdown and "## Exclusions" in markdown


def test_the_hash_is_stable_and_changed_by_an_edit() -> None:
    protocol = protocol_from_text(protocol_text(), "delay.toml")
    first, second = registered_plan(protocol, None), registered_plan(protocol, None)
    assert plan_hash(first) == plan_hash(second)
    edited = first | {"hypothesis": first["hypothesis"] | {"smallest_effect": 0.04}}
    assert plan_hash(edited) != plan_hash(first)


def test_a_protocol_without_analysis_has_no_plan() -> None:
    with pytest.raises(InputError, match="no \\[analysis\\]"):
        registered_plan(protocol_from_text(protocol_text(analysis=""), "plain.toml"), None)


def test_the_plan_takes_its_sample_size_from_a_power_analysis(tmp_path: Path) -> None:
    protocol = protocol_file(tmp_path)
    table = write_study_table(make_study_rows(seed=3, participants=6), tmp_path / "table")
    power = tmp_path / "power"
    arguments = ["study", "power", str(table), "--protocol", str(protocol), "--participants",
                 "4,30", "--simulations", "200", "--out", str(power)]  # fmt: skip
    assert main(arguments) == 0
    size = json.loads((write_plan(tmp_path, protocol, "--power", str(power)) / "plan.json")
                      .read_text())["plan"]["sample_size"]  # fmt: skip
    assert (
        size["participants"]
        == json.loads((power / "power.json").read_text())["smallest_participants"]
    )
    assert size["pilot_table_sha256"] and "study power" in size["justification"]


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A table, and the plan registered from the protocol."""
    folder = tmp_path_factory.mktemp("registered")
    table = write_study_table(make_study_rows(seed=5, participants=8), folder / "table")
    return table, write_plan(folder, protocol_file(folder / "registered"))


def run_report(table: Path, protocol: Path, plan: Path, out: Path) -> tuple[list[str], str]:
    arguments = [
        "study",
        "report",
        str(table),
        "--protocol",
        str(protocol),
        "--plan",
        str(plan / "plan.json"),
        "--resamples",
        "200",
        "--out",
        str(out),
    ]
    assert main(arguments) == 0
    return json.loads((out / "results.json").read_text())["deviations_from_plan"], (
        out / "report.html"
    ).read_text()


def test_report_following_the_plan_says_nothing_more(
    study: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table, plan = study
    deviations, html = run_report(table, protocol_file(tmp_path), plan, tmp_path / "r")
    assert deviations == []
    assert "Deviation" not in capsys.readouterr().err
    assert "The analysis run follows the registered plan." in html


@pytest.mark.parametrize(
    ("edit", "named"),
    [
        (('direction = "lower"', 'direction = "two-sided"'), ["direction: registered 'lower'"]),
        (("smallest_effect = 0.05", "smallest_effect = 0.02"), ["smallest_effect: registered"]),
        (('contrast = ["delay 0.5 s", "no delay"]', 'contrast = ["no delay", "delay 0.5 s"]'),
         ["condition: registered 'delay 0.5 s'", "reference: registered 'no delay'"]),
    ],
)  # fmt: skip
def test_report_flags_an_edited_hypothesis(
    study: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    edit: tuple[str, str],
    named: list[str],
) -> None:
    table, plan = study
    protocol = protocol_file(tmp_path, LOWER_PHASE_LOCKING.replace(*edit))
    deviations, html = run_report(table, protocol, plan, tmp_path / "r")
    assert len(deviations) == len(named)
    assert all(line.startswith(start) for line, start in zip(deviations, named, strict=True))
    assert "Deviation from the registered plan" in capsys.readouterr().err
    assert "Deviation from the registered plan" in html


def test_report_flags_an_edited_plan(study: tuple[Path, Path], tmp_path: Path) -> None:
    table, plan = study
    edited = tmp_path / "edited"
    edited.mkdir()
    document = json.loads((plan / "plan.json").read_text())
    document["plan"]["hypothesis"]["smallest_effect"] = 0.01
    (edited / "plan.json").write_text(json.dumps(document))
    assert not read_plan(edited).intact
    deviations, _ = run_report(table, protocol_file(tmp_path), edited, tmp_path / "r")
    assert "edited after it was written" in deviations[0]
    assert any(line.startswith("smallest_effect: registered 0.01") for line in deviations)
