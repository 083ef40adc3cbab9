"""Figures, one module per subject, each function returning a `matplotlib.figure.Figure`.

`signatures` (IMS, similarity space, stroke moments, groups of people), `people` (many people's
signatures with labels that never overlap), `sessions` (positions, relative phase, group
synchrony), `learning` (learning curves, progress, bars), `graphs` (who observes whom), on the
common `style`.
"""
