"""``signature --groups``: two groups of people compared by their signatures (issue 38.6)."""

from __future__ import annotations

import html
import json
import re

import numpy as np
import pytest

from mirror_avatar.cli import main

LABELS = [f"{style}-{k}" for style in ("fast", "slow") for k in range(1, 10)]


def write_map(path, groups, header="trial,group", separator=","):
    rows = [header] + [
        f"{label}{separator}{group}" for label, group in zip(LABELS, groups, strict=True)
    ]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.long
def test_fast_and_slow_people_are_told_apart(tmp_path, capsys):
    table = write_map(tmp_path / "groups.tsv", [lab.split("-")[0] for lab in LABELS],
                      "trial\tgroup", "\t")  # fmt: skip
    out = tmp_path / "out"
    assert main(["signature", "--bundled", "--groups", str(table), "--out", str(out)]) == 0
    result = json.loads((out / "groups.json").read_text())
    assert result["groups"] == ["fast", "slow"] and len(result["people"]) == 18
    assert result["accuracy"] == result["sensitivity"] == result["specificity"] == 1.0
    assert result["separation"]["p_value"] < 0.01 and result["chance"]["p_value"] < 0.01
    assert abs(result["chance"]["null_mean"] - 0.5) < 0.1
    assert result["between"] > 3 * result["within"]
    assert result["seed"] == 0
    assert result["classifier"]["auc"] > 0.95 and result["classifier"]["test"]["p_value"] < 0.01
    assert (out / "groups.png").read_bytes().startswith(b"\x89PNG")
    printed = capsys.readouterr().out
    assert "each is a person" in printed and "classified 100% right" in printed
    page = html.unescape((out / "report.html").read_text())
    lead = re.search(r'<p class="lead">(.*?)</p>', page).group(1)
    assert "Groups: fast (9 people) and slow (9 people): different" in lead


@pytest.mark.long
def test_shuffled_labels_are_at_chance(tmp_path):
    """Labels shuffled within each style, so that neither group holds more of one style."""
    rng = np.random.default_rng(7)
    shuffled = [*rng.permutation(["a"] * 5 + ["b"] * 4), *rng.permutation(["a"] * 4 + ["b"] * 5)]
    table = write_map(tmp_path / "groups.csv", shuffled)
    out = tmp_path / "out"
    assert main(["signature", "--bundled", "--groups", str(table), "--out", str(out)]) == 0
    result = json.loads((out / "groups.json").read_text())
    assert result["separation"]["p_value"] > 0.05 and result["chance"]["p_value"] > 0.05
    assert 0.2 <= result["accuracy"] <= 0.8
    assert abs(result["chance"]["null_mean"] - 0.5) < 0.1
    assert result["classifier"]["test"]["p_value"] > 0.05


def test_people_by_their_group_by_folder(zhai_trials, tmp_path):
    """A person column maps --group-by groups: the bundled styles as two people each."""
    root = tmp_path / "data"
    for trial in zhai_trials:
        person = f"{trial.group}{int(trial.label.split('-')[1]) % 2}"
        (root / person).mkdir(parents=True, exist_ok=True)
        data = np.column_stack([trial.times, trial.positions])
        np.savetxt(root / person / f"{trial.label}.csv", data, delimiter=",",
                   header="time,position", comments="")  # fmt: skip
    table = tmp_path / "groups.csv"
    table.write_text("person,group\nfast0,F\nfast1,F\nslow0,S\nslow1,S\n")
    out = tmp_path / "out"
    assert main(["signature", str(root), "--groups", str(table), "--out", str(out)]) == 0
    result = json.loads((out / "groups.json").read_text())
    assert sorted(result["people"]) == ["fast0", "fast1", "slow0", "slow1"]
    assert result["accuracy"] == 1.0
    assert result["chance"]["exact"]  # 4 choose 2 relabellings, all tried
    classifier = result["classifier"]
    assert classifier["n_reference"] == classifier["n_candidate"] == 2  # people, not trials
    assert classifier["test"]["exact"] and classifier["folds"] == 2


@pytest.mark.parametrize(
    ("table", "problem"),
    [
        ("name,group\nfast-1,a\n", "needs a column group and a column person or trial"),
        ("trial,group\nfast-1,a\n", "'fast-2' (person 'fast') is not in --groups"),
        (
            "trial,group\n" + "".join(f"{lab},{lab[-1]}\n" for lab in LABELS),
            "--groups compares two",
        ),
        ("person,group\nfast,a\nslow,b\n", "group 'a' has 1 person"),
        ("trial,group\nfast-1,a\nfast-1,b\n", "given twice with different groups"),
    ],
)
def test_bad_group_tables_are_one_line_exit_2(tmp_path, capsys, table, problem):
    path = tmp_path / "groups.csv"
    path.write_text(table)
    out = tmp_path / "out"
    assert main(["signature", "--bundled", "--groups", str(path), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert problem in error and error.count("\n") == 1 and str(path) in error
