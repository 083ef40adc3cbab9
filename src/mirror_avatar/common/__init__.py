"""What every part shares: errors, constraints, seeds, progress bars, interruptions.

`errors` (`InputError`, the one exception bad input raises), `constraints` (a setting's allowed
values declared once as data), `seeds` (every random choice from one integer), `progress`
(progress bars on long work), `interruptions` (Ctrl+C, SIGTERM and SIGHUP stop a command as
Ctrl+C would).
"""
