"""Coordination metrics: functions on arrays, composed into one `session_metrics`.

`coordination` measures two position series (RMSE, relative phase, the paper's circular
variance, time lag and cross-correlation, paired t-tests; METHODS section 6), `group` the
synchronisation of N players (cluster phase, METHODS section 8), and `summary` composes them
into `session_metrics`, the one summary of a session every part of the toolkit reports.
The measures mirror-game studies report beside them (jitter, co-confidence, synchrony episodes,
leadership, transfer entropy, surrogates; METHODS section 12) have one module each, composed by
`measures.session_measures` (imported from there, since it brings pyinform). `measuring`
measures a session one way for `evaluate`, `study table` and the lab: brought to at most 100 Hz
by `analysis_rate.at_analysis_rate`, trimmed once, its surrogates drawn from its recorded seed.
Both compose one `quantities.Quantities` per session, so each shared quantity is computed once,
and
`registry` declares every key they return: its words, unit and test.
"""

from mirror_avatar.metrics.coordination import (
    TTest,
    compute_circular_sd,
    compute_cross_correlation_peak,
    compute_mean_relative_phase,
    compute_phase,
    compute_phase_locking,
    compute_relative_phase,
    compute_rmse,
    compute_time_lag,
    paired_ttest,
    wrap_phase,
)
from mirror_avatar.metrics.group import ClusterPhase, compute_cluster_phase
from mirror_avatar.metrics.summary import TRIM, session_metrics

__all__ = [
    "TRIM",
    "ClusterPhase",
    "TTest",
    "compute_circular_sd",
    "compute_cluster_phase",
    "compute_cross_correlation_peak",
    "compute_mean_relative_phase",
    "compute_phase",
    "compute_phase_locking",
    "compute_relative_phase",
    "compute_rmse",
    "compute_time_lag",
    "paired_ttest",
    "session_metrics",
    "wrap_phase",
]
