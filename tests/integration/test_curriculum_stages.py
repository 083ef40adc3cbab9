"""Curriculum stages on the bundled data: the issue's criteria for both methods."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.curriculum import measure_stages, own_emd
from mirror_avatar.motion.generator import IMSGenerator


@pytest.mark.slow  # minutes of work: `make test-all` runs it
def test_stages_move_from_the_patient_to_the_target() -> None:
    """EMD to the patient strictly rising and to the target strictly falling, the first stage
    within the patient's trial-to-trial EMD and the last within the target's, strokes mostly
    human-like, and the patient-like follower still coordinating."""
    trials = load_zhai2017()
    patient = [t for t in trials if t.group == "slow"]
    target = [t for t in trials if t.group == "fast"]
    models = [IMSGenerator(random_state=0).fit(t) for t in (patient, target)]
    people = {"patient": patient, "target": target}
    table = measure_stages(models[0], models[1], people, 3, n_draws=4, n_sessions=4, seed=0)
    for method in ("mixture", "displacement"):
        rows = table.loc[method]
        assert np.all(np.diff(rows["EMD to patient"]) > 0), rows
        assert np.all(np.diff(rows["EMD to target"]) < 0), rows
        assert rows["EMD to patient"].iloc[0] <= own_emd(patient)
        assert rows["EMD to target"].iloc[-1] <= own_emd(target)
        assert (rows["strokes in human range"] > 0.7).all()
        assert (rows["CV with the patient"] > 0.75).all()
