"""``generator fit`` checks generated motion against held-out trials (the likeness battery)."""

from __future__ import annotations

import json

import pytest

from mirror_avatar.cli import main


@pytest.mark.long
def test_fit_reports_the_battery_on_held_out_trials(tmp_path, capsys):
    model = tmp_path / "slow.npz"
    args = [
        "generator",
        "fit",
        "--bundled",
        "slow",
        "--kind",
        "ims",
        "--symbols",
        "16",
        "--out",
        str(model),
    ]
    assert main(args) == 0
    result = json.loads((tmp_path / "slow.likeness.json").read_text())
    assert result["seed"] == 0
    assert set(result["distances"]) == {"velocity IMS EMD", "amplitude", "spectrum"}
    emd = result["distances"]["velocity IMS EMD"]
    assert emd["ratio"] == emd["to_reference"] / emd["own"]
    classifier = result["classifier"]
    assert classifier["n_reference"] == classifier["n_candidate"] == 5  # five folds, one each
    assert 0.0 <= classifier["auc"] <= 1.0
    printed = capsys.readouterr().out
    assert "generated trials against held-out ones" in printed
    assert f"likeness: {result['verdict']}" in printed


def test_no_likeness_writes_no_battery(tmp_path, capsys):
    model = tmp_path / "slow.npz"
    args = [
        "generator",
        "fit",
        "--bundled",
        "slow",
        "--kind",
        "ims",
        "--symbols",
        "16",
        "--no-likeness",
    ]
    assert main([*args, "--out", str(model)]) == 0
    assert not (tmp_path / "slow.likeness.json").exists()
    assert "generated trials against held-out ones" not in capsys.readouterr().out
