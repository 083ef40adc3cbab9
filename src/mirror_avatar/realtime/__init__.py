"""The real-time core shared by the live game (``play``) and the lab (``lab``).

- `mirror_avatar.realtime.messages`: what pages send (a position), validated;
- `mirror_avatar.realtime.inputs`: a person's input device (a page, an LSL stream) read by the
  clock, its samples held, never invented, and its liveness judged from what it delivers;
- `mirror_avatar.realtime.trial`: a clocked trial recording every sample with its true time;
- `mirror_avatar.realtime.clock`: `run_on_clock`, ticking a trial on absolute deadlines, and
  the bounds ending a trial that cannot keep real time;
- `mirror_avatar.realtime.latency`: round trips measured for every ping;
- `mirror_avatar.realtime.outbox`: messages to a page that a slow page cannot make wait;
- `mirror_avatar.realtime.gates`, `mirror_avatar.realtime.rates`: who may connect, and how
  often, as stacked ASGI middleware;
- `mirror_avatar.realtime.transport`: the servers' sockets and secret-free logs.
"""
