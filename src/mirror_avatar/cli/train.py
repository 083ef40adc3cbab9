"""``mirror-avatar train``: teach a cyber player to imitate a virtual trainer (METHODS 7)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import click

from mirror_avatar.cli.cluster import scheduler_option
from mirror_avatar.cli.constrained import JOBS, SEED, SESSION_SECONDS, SESSIONS, ranged
from mirror_avatar.cli.outputs import check_output_file
from mirror_avatar.cli.reading import import_options
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.figures.learning import plot_learning_curves
from mirror_avatar.files.atomic import write_atomic_bytes
from mirror_avatar.files.importing import DEFAULT_IMPORT, ImportOptions
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.learning.training import LearningCurve
from mirror_avatar.motion.models import MotionModel
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.players.dynamical import ModelPartner
from mirror_avatar.report import render_png
from mirror_avatar.specs import load_player
from mirror_avatar.training.agents import AGENTS
from mirror_avatar.training.imitation import (
    TRAINING_ROLES,
    Agent,
    Reference,
    checkpoint_path,
    learning_curve_path,
    train_cyber_player,
)

MODEL_HELP = "A motion model .npz (generator fit), bundled:fast, bundled:slow or vt:TRIAL_FILE."


def load_reference(spec: str, options: ImportOptions = DEFAULT_IMPORT) -> Reference:
    """Return the generator (or recorded trial) a model spec names; InputError for other players.

    The error says what to give instead: ``vt:FILE`` or a fitted model for a recording, a
    virtual-trainer model for a cyber-player policy.
    """
    player = load_player(spec, "follower", options)
    if isinstance(player, RecordedPlayer):
        raise InputError(
            spec,
            f"is a recording, which can only replay itself: give vt:{spec} (a virtual trainer "
            f"moving like it) or a model fitted on it (mirror-avatar generator fit {spec} "
            "--out MODEL.npz)",
        )
    if not isinstance(player, VirtualTrainer):
        kind = "a partner model" if isinstance(player, ModelPartner) else "a cyber-player policy"
        raise InputError(
            spec,
            f"is {kind}; training needs a virtual trainer: a motion model .npz, "
            "bundled:fast, bundled:slow or vt:TRIAL_FILE",
        )
    if not isinstance(player.reference, MotionModel | Trial):
        raise InputError(spec, "is a curriculum stage; training needs a person's generator")
    return player.reference


def load_generator(spec: str, options: ImportOptions = DEFAULT_IMPORT) -> MotionModel:
    """Return the motion model a spec names (a stroke or IMS generator .npz, or bundled:STYLE)."""
    reference = load_reference(spec, options)
    if not isinstance(reference, MotionModel):
        raise InputError(spec, "give a generator model .npz or bundled:STYLE, not a recording")
    return reference


AGENT_HELP = "tabular: the paper's Q-table; dqn: a deep Q-network (METHODS section 8)."


def training_options(
    agent: Agent = "tabular", sessions: dict[Agent, int] | None = None, agent_help: str = AGENT_HELP
) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Make the decorator adding a training run's options (sessions, duration, seed, agent...).

    ``agent`` is the default agent; ``sessions`` the default training sessions of each agent
    (None: ``--sessions`` is required; else the command receives None and picks by agent).
    """
    if sessions is None:
        count = click.option("--sessions", required=True, **ranged("Training sessions.", SESSIONS))
    else:
        defaults = ", ".join(f"{n} for {name}" for name, n in sessions.items())
        count = click.option(
            "--sessions",
            default=None,
            **ranged(f"Training sessions. [default: {defaults}]", SESSIONS),
        )
    options = [
        count,
        click.option(
            "--duration", default=60.0, show_default=True,
            **ranged("Session length.", SESSION_SECONDS),
        ),
        click.option(
            "--seed", default=0, show_default=True, **ranged("Run seed (recorded).", SEED)
        ),
        scheduler_option(),
        click.option("--jobs", default=2, show_default=True, **ranged("Local threads.", JOBS)),
        click.option(
            "--agent", type=click.Choice(AGENTS), default=agent, show_default=True,
            help=agent_help,
        ),
        click.option(
            "--checkpoint-every", default=None,
            **ranged("Also save the policy to OUT every N sessions: a stopped run leaves a usable "
                     "one.", Interval(int, 1, None)),
        ),
        click.option(
            "--out", "out_path", required=True, type=click.Path(path_type=Path),
            help="Policy .npz file.",
        ),
    ]  # fmt: skip

    def decorate(command: Callable[..., None]) -> Callable[..., None]:
        for option in reversed(options):
            command = option(command)
        return command

    return decorate


def prepare_training_output(out_path: Path, checkpoint_every: int | None) -> None:
    """Refuse an output file that cannot be written, before any work; announce checkpoints."""
    check_output_file(out_path, ".npz", beside=training_files(out_path))
    if checkpoint_every is not None:
        click.echo(
            f"checkpoints: {checkpoint_path(out_path).resolve()} is saved every "
            f"{checkpoint_every} sessions",
            err=True,
        )


def training_files(policy: Path) -> tuple[Path, Path, Path]:
    """Return the files a training run writes beside its policy: curve CSV and PNG, checkpoint."""
    curve = learning_curve_path(policy)
    return curve, curve.with_suffix(".png"), checkpoint_path(policy)


def finish_training(
    player: AccelerationPlayer, curve: LearningCurve, policy: Path, name: str
) -> Path:
    """Write the trained policy and its learning curve (CSV and PNG), drop the checkpoint.

    Returns the learning curve's path.
    """
    curve_path, figure_path, _ = training_files(policy)
    curve.save(curve_path)
    figure = plot_learning_curves({name: (curve.sessions, curve.rms)})
    write_atomic_bytes(figure_path, render_png(figure))
    player.save(policy)
    checkpoint_path(policy).unlink(missing_ok=True)
    return curve_path


@click.command()
@click.option("--target", "target_spec", required=True, help=f"The person to imitate. {MODEL_HELP}")
@click.option(
    "--partners",
    "partner_specs",
    required=True,
    multiple=True,
    help="Training partners (repeat the option or separate with commas). " + MODEL_HELP,
)
@click.option(
    "--role", type=click.Choice(TRAINING_ROLES), default="follower", show_default=True,
    help="The role the cyber player learns; the partners take the other one.",
)  # fmt: skip
@training_options()
@import_options
def train(
    target_spec: str,
    partner_specs: tuple[str, ...],
    role: str,
    sessions: int,
    duration: float,
    seed: int,
    scheduler: str | None,
    jobs: int,
    agent: Agent,
    checkpoint_every: int | None,
    out_path: Path,
    options: ImportOptions,
) -> None:
    """Train a cyber player on virtual-trainer sessions and write the policy.

    Each session, a partner (in turn) plays with the target; the cyber player watches the
    partner and is rewarded for moving like the target. Writes OUT and
    OUT.learning_curve.csv and .png (the stem of OUT, then .learning_curve.csv / .png).
    """
    prepare_training_output(out_path, checkpoint_every)
    specs = [s.strip() for spec in partner_specs for s in spec.split(",") if s.strip()]
    target = load_reference(target_spec, options)
    partners = [load_reference(spec, options) for spec in specs]
    player, curve = train_cyber_player(
        target,
        partners,
        role=role,  # type: ignore[arg-type]
        n_sessions=sessions,
        seed=seed,
        duration=duration,
        scheduler=scheduler,
        n_jobs=jobs,
        checkpoint=checkpoint_path(out_path),
        checkpoint_every=checkpoint_every,
        agent=agent,
    )
    curve_path = finish_training(player, curve, out_path, f"{agent} {role}, seed {seed}")
    click.echo(
        f"trained a {agent} {role} on {sessions} sessions (seed {seed}): RMS to the target "
        f"{curve.rms[0]:.4f} -> {curve.rms[-1]:.4f} units"
    )
    click.echo(f"wrote {out_path.resolve()} and {curve_path.resolve()} (.png)")
