"""``mirror-avatar evaluate`` on a long high-rate pair: peak memory and time, default options.

- A 1 kHz x 1 h pair (3.6 million rows of ``time, position_0, position_1``, player 1 repeating
  player 0's band-limited motion 0.2 s later; 1 kHz x 5 min with ``--quick``) is evaluated with
  the default options (99 circular-shift surrogates) by the real command line in a fresh child
  process, which prints its peak resident memory (``ru_maxrss``). Baseline, in the same run: the
  same command on a 60 s pair at 100 Hz (an ordinary session). Value = the long pair's wall
  time (interpreter start and imports included); ratio = long / baseline. A second row gives
  peak memory the same way.
- Refusal: ``--surrogates 1000000000`` on the 60 s pair: its wall time, exit code and error
  line, against the baseline's wall time.

Children are started through `bench_reading`'s launcher, so that their ``ru_maxrss`` is theirs
alone (Linux counts a child's starter's peak in it).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).parent))
from bench_reading import MB, run_cli, shorten  # noqa: E402

DELAY = 0.2
"""Player 1 repeats player 0 this many seconds later (s)."""

CHUNK_ROWS = 100_000


def write_pair(path: Path, seconds: float, rate: float, seed: int = 0) -> int:
    """Write a pair of ``seconds`` at ``rate`` Hz as CSV, in chunks; return its number of rows."""
    rng = np.random.default_rng(seed)
    n, delay = round(seconds * rate), round(DELAY * rate)
    sos = signal.butter(4, 1.0, fs=rate, output="sos")
    s = signal.sosfiltfilt(sos, rng.normal(size=n + delay + 2000))[1000 : 1000 + n + delay]
    s = 0.3 * s / s.std()
    times = np.arange(n) / rate
    with path.open("w", encoding="utf-8") as handle:
        handle.write("time,position_0,position_1\n")
        for first in range(0, n, CHUNK_ROWS):
            last = min(n, first + CHUNK_ROWS)
            rows = np.column_stack(
                [times[first:last], s[first + delay : last + delay], s[first:last]]
            )
            np.savetxt(handle, rows, fmt="%.6f", delimiter=",")
    return n


def run(quick: bool) -> list[dict]:
    seconds = 300.0 if quick else 3600.0
    with tempfile.TemporaryDirectory(prefix="bench_evaluate_", dir="/tmp") as name:
        folder = Path(name)
        long_pair, short_pair = folder / "long.csv", folder / "short.csv"
        rows = write_pair(long_pair, seconds, 1000.0)
        write_pair(short_pair, 60.0, 100.0)
        baseline = run_cli("evaluate", str(short_pair))
        long = run_cli("evaluate", str(long_pair))
        refused = run_cli("evaluate", str(short_pair), "--surrogates", "1000000000")
        size = long_pair.stat().st_size / MB
    for done, what in ((baseline, "60 s pair"), (long, "long pair")):
        if done.exit_code != 0:
            raise RuntimeError(f"evaluate on the {what} failed: {done.error[-500:]}")
    conditions = (
        f"1 kHz x {seconds / 60:g} min pair ({rows:,} rows, {size:.0f} MB CSV), default options "
        "(99 shift surrogates), analysed at 100 Hz; baseline = a 60 s pair at 100 Hz, same "
        "options, same run; times include interpreter start and imports"
    )
    return [
        {
            "name": "evaluate, 1 kHz pair, default options: wall time",
            "value": round(long.seconds, 1),
            "unit": "s",
            "baseline": round(baseline.seconds, 1),
            "ratio": round(long.seconds / baseline.seconds, 2),
            "peak_memory_mb": round(long.peak_kb / 1024, 1),
            "note": conditions,
        },
        {
            "name": "evaluate, 1 kHz pair, default options: peak memory",
            "value": round(long.peak_kb / 1024, 1),
            "unit": "MB",
            "baseline": round(baseline.peak_kb / 1024, 1),
            "ratio": round(long.peak_kb / baseline.peak_kb, 2),
            "peak_memory_mb": round(long.peak_kb / 1024, 1),
            "note": f"peak resident memory of the child (ru_maxrss); {conditions}",
        },
        {
            "name": "evaluate --surrogates 1000000000 refused",
            "value": round(refused.seconds, 2),
            "unit": "s",
            "baseline": round(baseline.seconds, 1),
            "ratio": round(refused.seconds / baseline.seconds, 3),
            "peak_memory_mb": round(refused.peak_kb / 1024, 1),
            "note": (
                f"exit code {refused.exit_code} (expected 2): {shorten(refused.error, folder)}; "
                "baseline = the 60 s pair evaluated"
            ),
        },
    ]
