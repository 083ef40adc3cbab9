"""BIDS-Motion: one set of rules for the names, sidecars, channels and values of recordings.

`names` holds the file-name rules (entities, labels, a recording's identity); `reading` reads
a ``_motion.tsv`` as one participant's trial or as a lab trial's N players; `writing` writes
the files (values, tables, sidecars). `mirror_avatar.lab.export.bids` exports lab sessions with
them.
"""
