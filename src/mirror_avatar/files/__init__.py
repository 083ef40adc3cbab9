"""Files: trials and their formats, BIDS-Motion, model archives, records, safe reading and writing.

`trials` (one player's time series, validated, resampled, its velocity), `trial_io` (CSV, Parquet
and MATLAB trial files, with `mat_check` walking MATLAB files before SciPy reads them),
`importing` (a researcher's file conventions), `bids/` (BIDS-Motion), `trial_files` (any trial
file by its name), `trial_record` (the declared record of a lab trial), `model_files` (``.npz``
archives with JSON metadata, never pickled), `user_files` (the one way a file a user names is
opened) and `atomic` (writes that fail cleanly).
"""
