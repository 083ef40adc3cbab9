"""Train a stable-baselines3 DQN agent in the mirror game's Gymnasium environment.

The agent takes the place of virtual trainer VT5 following a leader (the paper's follower task):
each episode is one 60 s session that the virtual trainers played on the batch engine, and the
agent is rewarded for moving like VT5 did (`mirror_avatar.rl.env.MirrorGameEnv`). After training it
replays held-out sessions greedily; its RMS to VT5 is printed beside that of a player that never
accelerates and that of mirror-avatar's own DQN player trained on the same sessions (which also
sees its own reference velocity, here VT5's, which the Gymnasium observation does not hold).

Needs stable-baselines3 and PyTorch (``pip install stable-baselines3``; from PyPI, PyTorch's
Linux wheels pull the CUDA libraries, several GB), which mirror-avatar itself does not use.

    python examples/sb3_dqn.py --steps 100000
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np
from stable_baselines3 import DQN

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.rl.env import MirrorGameEnv
from mirror_avatar.training.cast import cast_virtual_trainers
from mirror_avatar.training.imitation import (
    derive_seeds,
    make_cyber_player,
    make_pairs,
    score_avatar,
    train_cyber_player,
)


def held_out_rms(sessions: list, template, predict) -> float:  # noqa: ANN001
    """Mean over the sessions of the RMS between the agent's position and the target's."""
    env = MirrorGameEnv(iter(sessions), template)
    values = []
    for _ in sessions:
        obs, info = env.reset()
        squares, truncated = [], False
        while not truncated:
            obs, _, _, truncated, info = env.step(predict(obs))
            squares.append((env._agent.state[0] - info["target"][0]) ** 2)
        values.append(np.sqrt(np.mean(squares)))
    return float(np.mean(values))


def main() -> None:
    """Train, then compare on held-out sessions."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="environment steps")
    parser.add_argument("--sessions", type=int, default=100, help="training sessions")
    args = parser.parse_args()
    cast = cast_virtual_trainers(load_zhai2017())
    target = cast.trainers[cast.target].generator
    partners = [cast.trainers[i].generator for i in cast.seen]
    pairs = make_pairs(target, partners, "follower")
    train_seed, test_seed = derive_seeds(0)
    sessions = [s for chunk in run_sessions(pairs, args.sessions, seed=train_seed) for s in chunk]
    held_out = [s for chunk in run_sessions(pairs, 8, seed=test_seed) for s in chunk]
    template = make_cyber_player("follower")  # the end effector, actions and reward weight

    env = MirrorGameEnv(itertools.cycle(sessions), template)
    model = DQN("MlpPolicy", env, policy_kwargs={"net_arch": [100, 50, 50]}, gamma=0.95,
                batch_size=32, buffer_size=200_000, target_update_interval=150,
                exploration_fraction=0.2, exploration_final_eps=0.1, learning_starts=1000,
                seed=0, verbose=0)  # fmt: skip
    start = time.perf_counter()
    model.learn(total_timesteps=args.steps, progress_bar=False)
    seconds = time.perf_counter() - start

    trained = held_out_rms(
        held_out, template, lambda o: int(model.predict(o, deterministic=True)[0])
    )
    untrained = held_out_rms(held_out, template, lambda o: 4)  # action 4: no acceleration
    ours, _ = train_cyber_player(target, partners, n_sessions=args.sessions, agent="dqn")
    print(f"stable-baselines3 DQN: {args.steps} steps in {seconds:.0f} s")
    print(f"held-out RMS to VT5 (units): SB3 DQN {trained:.4f}, no acceleration {untrained:.4f}, "
          f"mirror-avatar DQN on {args.sessions} sessions (sees VT5's reference) "
          f"{score_avatar(ours, held_out)[1].mean():.4f}")  # fmt: skip


if __name__ == "__main__":
    main()
