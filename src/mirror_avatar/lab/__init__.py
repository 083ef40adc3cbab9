"""Lab sessions (METHODS section 9): several people at their own screens and avatars on one clock.

`plan` describes a session (condition, slots, graph, trials), `inputs` the human players'
input devices, `trial` one trial on the engine's clock with its recordings, `lsl` the Lab
Streaming Layer outlet and input device, `bids` the BIDS-Motion export, and `server` the
researcher's console, its HTTP/JSON API and the participants' pages.
"""
