"""``mirror-avatar group``: groups of players on a coupling graph (METHODS section 8)."""

from __future__ import annotations

from pathlib import Path

import click

from mirror_avatar.cli.constrained import ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import import_options
from mirror_avatar.cli.simulate import (
    EXTEND_HELP,
    SESSION_OUTPUTS,
    SPEC_HELP,
    check_recordings,
    format_metrics,
    session_options,
    write_outputs,
)
from mirror_avatar.cli.train import (
    finish_training,
    load_reference,
    prepare_training_output,
    training_options,
)
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.loop import play
from mirror_avatar.experiments.group import TRAINING_SESSIONS
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.metrics import session_metrics
from mirror_avatar.sessions.graphs import TOPOLOGIES, graph_source
from mirror_avatar.specs import load_player
from mirror_avatar.training.imitation import Agent, checkpoint_path, train_group_cyber_player

GRAPH_HELP = (
    f"Who observes whom: {', '.join(TOPOLOGIES)} (random: a new connected graph per session) "
    "or an adjacency matrix file (.csv rows of 0/1, or .json)."
)


GROUP_AGENT_HELP = (
    "dqn: a deep Q-network with dynamic input, the group player of the published group system "
    "(METHODS section 8); tabular: the paper's dyadic Q-table, which observes only the mean of "
    "its neighbours and does not meet the group criteria."
)


@click.group()
def group() -> None:
    """Play, measure and train players in groups on a coupling graph."""


@group.command()
@click.option("--player", "player_specs", multiple=True, required=True, help=SPEC_HELP)
@click.option(
    "--leader",
    "leaders",
    multiple=True,
    **ranged(
        "Index of a player that leads (the group-leader preset); repeatable.",
        Interval(int, 0, None),
    ),  # fmt: skip
)
@click.option("--graph", "graph_spec", default="complete", show_default=True, help=GRAPH_HELP)
@session_options
@click.option("--extend-recordings", is_flag=True, help=EXTEND_HELP)
@import_options
def simulate(
    player_specs: tuple[str, ...],
    leaders: tuple[int, ...],
    graph_spec: str,
    duration: float,
    seed: int | None,
    trim: float,
    out_dir: Path,
    extend_recordings: bool,
    options: ImportOptions,
) -> None:
    """Play a group session of the --player SPECs (player 0, 1, ...) and write it with metrics.

    Virtual trainers take the group preset of METHODS section 8 (theta_p 0.85, theta_s 0.1,
    theta_v 0.05), leaders the group-leader preset (theta_p 0.2, theta_s 0.8); each responds to
    the mean of the players it observes.
    """
    check_output_dir(out_dir, files=SESSION_OUTPUTS)
    n = len(player_specs)
    if n < 2:
        raise InputError("--player", "a group needs at least two players")
    if any(not 0 <= k < n for k in leaders):
        raise InputError("--leader", f"player indices run from 0 to {n - 1}")
    if not 0.0 <= trim < duration:
        raise InputError("--trim", f"must lie in [0, --duration) = [0, {duration:g}) s")
    roles = ["group_leader" if k in leaders else "group" for k in range(n)]
    players = [
        load_player(spec, role, options) for spec, role in zip(player_specs, roles, strict=True)
    ]
    check_recordings(players, player_specs, duration, extend_recordings)
    session = play(players, duration, seed, roles, graph_source(graph_spec, n))
    session.metadata["specs"] = list(player_specs)
    metrics = session_metrics(session, trim=trim)
    summary = {
        "seed": session.metadata["seed"],
        "specs": {f"player {k}": spec for k, spec in enumerate(player_specs)},
        "roles": roles,
        "graph": session.graph.tolist(),
        "duration": session.duration,
        "trim": trim,
        "metrics": metrics,
    }
    path = write_outputs(session, out_dir, summary)
    click.echo(
        f"{n} players on a {graph_spec} graph; {session.duration:g} s, seed {summary['seed']}"
    )
    click.echo(format_metrics(metrics))
    click.echo(f"wrote {path.parent.resolve()}")


@group.command()
@click.option("--target", "target_spec", required=True, help="The person to imitate (a model).")
@click.option(
    "--player",
    "player_specs",
    multiple=True,
    required=True,
    help="The other members of the group (models); repeatable.",
)
@click.option("--graph", "graph_spec", default="random", show_default=True, help=GRAPH_HELP)
@training_options("dqn", TRAINING_SESSIONS, GROUP_AGENT_HELP)
@import_options
def train(
    target_spec: str,
    player_specs: tuple[str, ...],
    graph_spec: str,
    sessions: int | None,
    duration: float,
    seed: int,
    scheduler: str | None,
    jobs: int,
    agent: Agent,
    checkpoint_every: int | None,
    out_path: Path,
    options: ImportOptions,
) -> None:
    """Train a cyber player to take the target's place in a group.

    Every session the --player models and the target (the last member) improvise together on
    --graph; the cyber player learns from what the target did. A MODEL is an IMS generator
    .npz, bundled:fast, bundled:slow or vt:TRIAL_FILE. Writes OUT (playable as a player SPEC,
    in groups and dyads) and OUT.learning_curve.csv and .png.
    """
    sessions = TRAINING_SESSIONS[agent] if sessions is None else sessions
    prepare_training_output(out_path, checkpoint_every)
    target = load_reference(target_spec, options)
    partners = [load_reference(spec, options) for spec in player_specs]
    player, curve = train_group_cyber_player(
        target,
        partners,
        n_sessions=sessions,
        seed=seed,
        duration=duration,
        graph=graph_source(graph_spec, len(partners) + 1),
        scheduler=scheduler,
        n_jobs=jobs,
        checkpoint=checkpoint_path(out_path),
        checkpoint_every=checkpoint_every,
        agent=agent,
    )
    name = f"{agent} member of a group of {len(partners) + 1}, seed {seed}"
    curve_path = finish_training(player, curve, out_path, name)
    click.echo(
        f"trained a {agent} group member on {sessions} sessions (seed {seed}): RMS to the target "
        f"{curve.rms[0]:.4f} -> {curve.rms[-1]:.4f} units"
    )
    click.echo(f"wrote {out_path.resolve()} and {curve_path.resolve()} (.png)")
