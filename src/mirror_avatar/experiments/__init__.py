"""The paper's validations, each a function from data to a report `Section`.

`EXPERIMENTS` lists them in report order; ``mirror-avatar reproduce`` runs them all. Each entry is
called as ``run(trials, quick=..., seed=...)`` with the bundled (or given) solo trials.
"""
