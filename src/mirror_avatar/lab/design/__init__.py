"""The design of a study: protocols, plans, orders, balance, perturbations and their checks."""
