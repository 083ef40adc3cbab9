import numpy as np

from mirror_avatar.datasets import load_zhai2017


def test_bundled_trials_have_honest_timestamps_and_groups(zhai_trials):
    assert len(zhai_trials) == 18
    assert [t.group for t in zhai_trials].count("fast") == 9
    assert [t.group for t in zhai_trials].count("slow") == 9
    for trial in zhai_trials:
        assert trial.n_samples == 779
        assert trial.duration == 60.0
        assert trial.metadata["license"] == "Apache-2.0"
        assert np.all(np.abs(trial.positions) <= 0.5)


def test_styles_differ_in_speed(zhai_trials_100hz):
    speed = {
        style: np.mean([np.abs(t.velocity()).mean() for t in zhai_trials_100hz if t.group == style])
        for style in ("fast", "slow")
    }
    assert 0.6 < speed["fast"] < 1.2
    assert 0.1 < speed["slow"] < 0.4


def test_loader_returns_fresh_trials():
    assert load_zhai2017()[0] is not load_zhai2017()[0]
