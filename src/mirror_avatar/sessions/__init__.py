"""Sessions: the `Session` type, its coupling graph, its writer as it is played, and its readers.

`session` (the type and its files), `graphs` (who observes whom), `writer` (a recording written a
sample at a time), `loading` (every session file the toolkit writes, lab recordings and other
tools' tables).
"""
