"""The declared hypothesis's test on pilots through the real lab server: power and false positives.

Protocol (issue 50; docs/METHODS.md section 15):

- **Study**: two leader-follower conditions, ``near`` (the avatar leader drawn at once on the
  page) and ``far`` (drawn `DELAY` s late), one trial of `DURATION` s each, in a Latin square
  across participants; the avatar leads (``bundled:slow``), the virtual participant follows
  (stand-in ``bundled:slow``). Arm ``effect``: as said; arm ``none``: ``far`` drawn at once too,
  so the conditions differ in their name only.
- **Hypothesis** (`ANALYSIS`): RMSE higher in ``far`` than in ``near`` (one-sided), smallest
  effect of interest `SMALLEST` playing range units, alpha 0.05.
- **Seeds**: each pilot's seed (`mirror_avatar.lab.running.pilot.run_pilot`: the stand-ins'
  draws) is 1, 2, ...; each plays ``--participants`` virtual participants in turn, in real time.
- **Test**: the study table of the pilot's run folders (no surrogates: RMSE needs none), the
  persons' rows, `mirror_avatar.analysis.hypothesis.confirm` (the paired t-test ``study report
  --protocol`` leads with). Found: supported (significant and at least the smallest effect);
  a false positive: significant with no effect.

Run: ``python benchmarks/hypothesis_pilots.py --arm effect --seeds 20`` and ``--arm none``
(prints one Markdown row per seed and the count; about 20 s per participant).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from mirror_avatar.analysis.hypothesis import ConfirmatoryTest, confirm
from mirror_avatar.analysis.table import study_table
from mirror_avatar.analysis.trials import read_study_trials
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.pilot import run_pilot

DELAY = 0.6
"""The far condition's delay in arm ``effect`` (s; issue 50's pilot: 0.6 s late)."""

DURATION = 6
"""Each trial's length (s): one trimmed second, five measured."""

SMALLEST = 0.005
"""The smallest effect of interest (playing range units)."""

CONDITION = """
[[blocks.conditions]]
name = "{name}"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "bundled:slow" }},
]
leaders = ["A1"]
duration = {duration}
pause = 0
show_metrics = false
delay = {delay}
"""

ANALYSIS = f"""
[analysis]
primary = "rmse"
direction = "higher"
contrast = ["far", "near"]
smallest_effect = {SMALLEST}
"""


def protocol_text(delay: float) -> str:
    """Write the study's protocol, ``far`` drawn ``delay`` s late."""
    conditions = "".join(
        CONDITION.format(name=name, duration=DURATION, delay=late)
        for name, late in (("near", 0.0), ("far", delay))
    )
    return f'title = "near or far"\nseed = 7\n[[blocks]]\norder = "latin"\n{conditions}{ANALYSIS}'


def pilot_test(protocol_file: Path, out: Path, participants: int, seed: int) -> ConfirmatoryTest:
    """Play one pilot and return its confirmatory test."""
    protocol = load_protocol(protocol_file)
    assert protocol.analysis is not None
    run_pilot(protocol_file, out, range(participants), {"P1": "bundled:slow"}, seed)
    rows = study_table(read_study_trials([out]), surrogates=0)
    (test,) = confirm(rows[rows["player_kind"] == "person"], protocol.analysis)
    return test


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arm", choices=("effect", "none"), required=True)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--participants", type=int, default=4)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        protocol_file = Path(folder) / "near_far.toml"
        protocol_file.write_text(protocol_text(DELAY if args.arm == "effect" else 0.0))
        print("| arm | seed | n | RMSE near | RMSE far | difference | 90 % CI | p | supported |")
        print("|---|---|---|---|---|---|---|---|---|")
        found, started = [], time.monotonic()
        for seed in range(1, args.seeds + 1):
            t = pilot_test(protocol_file, Path(folder) / f"seed-{seed}", args.participants, seed)
            found.append(t.supported if args.arm == "effect" else t.significant)
            print(f"| {args.arm} | {seed} | {t.participants} | {t.reference_mean:.4f} | "
                  f"{t.condition_mean:.4f} | {t.estimate:+.4f} | {t.ci_low:.4f} to "
                  f"{t.ci_high:.4f} | {t.p:.3g} | {t.supported} |", flush=True)  # fmt: skip
    what = "supported" if args.arm == "effect" else "significant (false positives)"
    print(f"\n{args.arm}: {sum(found)} of {len(found)} {what}; "
          f"{time.monotonic() - started:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
