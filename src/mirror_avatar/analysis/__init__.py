"""A study's results: its recordings gathered into one table, the statistics a paper reports.

The layer above the lab: it reads what the lab records (run folders and BIDS exports) and never
runs a trial.
"""
