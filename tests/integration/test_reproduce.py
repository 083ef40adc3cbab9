import json

from mirror_avatar.cli import main


def test_reproduce_quick_writes_report(tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["reproduce", "--out", str(out), "--quick", "--seed", "3"]) == 0
    last_line = capsys.readouterr().out.strip().splitlines()[-1]
    assert last_line == str(out / "report.html")
    html = (out / "report.html").read_text()
    assert 'id="signature"' in html and "data:image/png;base64," in html
    metrics = json.loads((out / "metrics.json").read_text())
    signature = metrics["signature"]
    assert signature["seed"] == 3 and signature["styles_distinct"] is True
    assert signature["between_within_ratio"] > 3
    metadata = metrics["metadata"]
    assert metadata["seed"] == 3 and metadata["quick"] is True
    assert metadata["command"].startswith("mirror-avatar reproduce --out")
    assert metadata["wall_time_s"] > 0 and "version" in metadata


def test_reproduce_refuses_a_file_as_output(tmp_path, capsys):
    target = tmp_path / "taken"
    target.write_text("x")
    assert main(["reproduce", "--out", str(target), "--quick"]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_signature_experiment_tells_styles_apart_for_any_seed(zhai_trials):
    from mirror_avatar.experiments.signature import run

    for seed in range(5):
        section = run(zhai_trials, seed=seed)
        metrics = section.metrics
        assert metrics["styles_distinct"] is True, seed
        assert metrics["max_between_overlap"] < metrics["min_half_overlap"]
        assert len(section.figures) == 3 and len(section.tables) == 4


def test_signature_experiment_without_a_second_style(zhai_trials):
    from mirror_avatar.experiments.signature import run

    fast = [trial for trial in zhai_trials if trial.group == "fast"]
    assert run(fast).metrics["styles_distinct"] is None
    few_slow = fast[:4] + [trial for trial in zhai_trials if trial.group == "slow"][:2]
    metrics = run(few_slow).metrics
    assert metrics["styles_distinct"] is None
    assert metrics["mean_between_emd"] > metrics["mean_within_emd"]
