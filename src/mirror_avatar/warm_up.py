"""Compile the numeric kernels once, when the package is installed, not in a first command.

The kernels are compiled by numba with ``cache=True``: the first process that calls one compiles
it (seconds each, a minute for all) and writes it beside its module (``__pycache__``), and every
later process loads it from there. ``python -m mirror_avatar.warm_up`` (`make` runs it after
installing) calls every kernel of the package once on tiny inputs through the code that uses
them - a generator fitted and sampled, signatures, sessions of every kind of player, both
learners trained, and the compiled loops that play a trained player beside a virtual trainer
or a recording, as the experiments and the avatar's checks do - so that a person's first
``mirror-avatar`` command finds them compiled.
A kernel whose cache is already on disk is loaded, so running it again takes seconds.
"""

from __future__ import annotations

import time

from mirror_avatar.common.progress import silenced
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.dynamics import (
    CONTROL_PERIOD,
    FOLLOWER,
    LEADER,
    MAX_NEWTON,
    N_SUBSTEPS,
    NEWTON_TOLERANCE,
    integrate_hkb,
    solve_interval,
)
from mirror_avatar.engine.batch import play_compiled, run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.signatures.likeness import compare_motion, trial_velocity
from mirror_avatar.signatures.signature import analyse_signatures
from mirror_avatar.specs import MODEL_PARTNERS, model_partner
from mirror_avatar.training.imitation import train_cyber_player, train_group_cyber_player

DURATION = 1.0
"""Length (s) of the sessions played to reach the kernels: long enough to call each once."""

N_SAMPLES = round(DURATION / CONTROL_PERIOD)
"""Samples of the sessions played in the compiled loop (`DURATION` at the control rate)."""


def warm_up() -> None:
    """Call every compiled kernel of the package once, so numba caches it on disk (silently)."""
    with silenced():
        _warm_up()


def _warm_up() -> None:
    """Call the kernels: a generator, signatures, sessions of every kind of player, trainings."""
    trials = [trial.resampled(100.0) for trial in load_zhai2017()[:3]]
    motion = IMSGenerator(n_symbols=8, random_state=0).fit(trials[:2])
    generated = motion.sample(trials[2].duration, n=2, random_state=0)
    compare_motion([trial_velocity(trials[2])], [trial_velocity(t) for t in generated])
    analyse_signatures(trials)
    pair = [VirtualTrainer(LEADER, motion), VirtualTrainer(FOLLOWER, motion)]
    play(pair, duration=DURATION, seed=0)
    for _ in run_sessions([pair], 2, duration=DURATION, n_jobs=1, progress=False):
        pass
    for name in MODEL_PARTNERS:
        play([VirtualTrainer(LEADER, motion), model_partner(name)], duration=DURATION, seed=0)
    recorded_pair = [RecordedPlayer(trials[0]), VirtualTrainer(FOLLOWER, motion)]
    play(recorded_pair, duration=DURATION, seed=0)
    play_compiled(recorded_pair, N_SAMPLES, seed=0)
    for agent in ("tabular", "dqn"):
        follower, _ = train_cyber_player(
            motion, [motion], n_sessions=2, duration=DURATION, n_jobs=1, agent=agent
        )
        play([VirtualTrainer(LEADER, motion), follower], duration=DURATION, seed=0)
        for partner in (VirtualTrainer(LEADER, motion), RecordedPlayer(trials[0])):
            play_compiled([partner, follower], N_SAMPLES, seed=0)
        train_group_cyber_player(
            motion, [motion] * 2, n_sessions=2, duration=DURATION, n_jobs=1, agent=agent
        )
    _warm_public_kernels()


def _warm_public_kernels() -> None:
    """Call the kernels that scripts and the RL environments call directly, as they do."""
    record = LEADER.record()
    solve_interval(0.0, 0.0, 0.1, 0.0, 0.0, record, True, N_SUBSTEPS, MAX_NEWTON, NEWTON_TOLERANCE)
    integrate_hkb(0.0, 0.0, 0.0, record[0], N_SUBSTEPS)


def main() -> None:
    """Compile the kernels and say how long it took."""
    print("mirror-avatar: compiling the numeric kernels (a minute or two, once)", flush=True)
    start = time.perf_counter()
    warm_up()
    print(f"mirror-avatar: kernels compiled and cached ({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
