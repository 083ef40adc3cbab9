"""``mirror-avatar avatar create``: a person's avatar from their solo trials, in one step."""

from __future__ import annotations

import time
from pathlib import Path

import click

from mirror_avatar import __version__
from mirror_avatar.cli.cluster import scheduler_option
from mirror_avatar.cli.constrained import JOBS, SEED, SESSIONS, ranged
from mirror_avatar.cli.generator import SHARED_HOLDS, share_options
from mirror_avatar.cli.outputs import check_output_file
from mirror_avatar.cli.reading import import_options, read_and_report
from mirror_avatar.cli.train import load_generator
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments.avatar_holdout import MAX_FOLDS, MIN_TRIALS_TO_HOLD_OUT
from mirror_avatar.experiments.avatar_proof import find_person
from mirror_avatar.experiments.personal_avatar import (
    DEFAULT_DQN_SESSIONS,
    DEFAULT_SESSIONS,
    avatar_card_path,
    create_avatar,
    default_partners,
    save_avatar,
)
from mirror_avatar.files.importing import ImportOptions, excerpt
from mirror_avatar.learning.acceleration_player import Agent
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.training.agents import AGENTS
from mirror_avatar.training.avatar import MAX_NAME_CHARS, load_avatar, shareable_avatar


@click.group()
def avatar() -> None:
    """Personal avatars: a person's motor signature and cyber players in one file."""


@avatar.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--name", required=True, help="Whom the avatar stands for.")
@click.option(
    "--partners",
    "partner_specs",
    multiple=True,
    help="Partners (generator .npz or bundled:STYLE; repeat or separate with commas): all but "
    "the last train the avatar, the last is kept for validation. [default: six virtual "
    "trainers of the bundled trials, three trials each; the sixth unseen]",
)
@click.option(
    "--sessions", default=None,
    **ranged(f"Training sessions per role. [default: {DEFAULT_SESSIONS}; "
             f"{DEFAULT_DQN_SESSIONS} with --agent dqn]", SESSIONS),
)  # fmt: skip
@click.option(
    "--agent", type=click.Choice(AGENTS), default="tabular", show_default=True,
    help="tabular: the paper's Q-tables; dqn: deep Q-networks (METHODS section 8).",
)  # fmt: skip
@click.option(
    "--holdout", default=None,
    **ranged("Solo trials kept out of fitting the avatar, in one split, to check it against (0: "
             "no check). [default: the avatar fitted on every trial, each held out in turn from "
             f"an avatar built without it: leave-one-out up to {MAX_FOLDS} trials, {MAX_FOLDS} "
             f"folds above; {MIN_TRIALS_TO_HOLD_OUT} trials or more]", Interval(int, 0, 1000)),
)  # fmt: skip
@click.option(
    "--with-partner", "partner_paths", multiple=True, type=click.Path(path_type=Path),
    help="A dyad session file the person played (repeatable): the avatar plays it again in "
    "their place against the partner's recorded track, and its CV, RMS and lag are set beside "
    "theirs.",
)  # fmt: skip
@click.option(
    "--person-label", default=None,
    help="The person's label in the --with-partner sessions (LABEL or 'person LABEL'). "
    "[default: --name]",
)  # fmt: skip
@click.option("--seed", default=0, show_default=True, **ranged("Seed of everything.", SEED))
@click.option("--jobs", default=2, show_default=True, **ranged("Local threads.", JOBS))
@scheduler_option()
@click.option(
    "--out", "out_path", required=True, type=click.Path(path_type=Path),
    help="The avatar file (.npz); its card is written beside it (.html).",
)  # fmt: skip
@import_options
def create(
    paths: tuple[Path, ...],
    name: str,
    partner_specs: tuple[str, ...],
    sessions: int | None,
    agent: Agent,
    holdout: int | None,
    partner_paths: tuple[Path, ...],
    person_label: str | None,
    seed: int,
    jobs: int,
    scheduler: str | None,
    out_path: Path,
    options: ImportOptions,
) -> None:
    """Build a person's avatar from their solo trials in FILE_OR_DIR....

    Fits their motion model (a stroke generator), trains their cyber player as follower and as
    leader against the partners, validates it against their own virtual trainer (the last
    partner unseen), checks it against the person in every role (each trial held out in turn,
    sessions with a partner) and writes OUT (playable as a SPEC: the session's role picks the
    player) and OUT's card, the same name with .html.
    """
    check_output_file(out_path, ".npz", beside=[avatar_card_path(out_path)])
    if not 0 < len(name.strip()) <= MAX_NAME_CHARS:
        raise InputError(
            "--name", f"{excerpt(name)} is not a name of 1-{MAX_NAME_CHARS} characters"
        )
    dyads = [
        find_person(str(path), load_session(path), person_label or name) for path in partner_paths
    ]
    specs = [s.strip() for spec in partner_specs for s in spec.split(",") if s.strip()]
    partners = [(spec, load_generator(spec, options)) for spec in specs]
    partners = partners or default_partners(seed)
    trials = read_and_report(paths, "none", options)
    began = time.perf_counter()
    built, card = create_avatar(
        trials, name, partners, sessions, seed=seed, n_jobs=jobs, agent=agent, scheduler=scheduler,
        n_held_out=holdout, partner_sessions=dyads,
        progress=lambda stage: click.echo(f"avatar: {stage} ...", err=True),
    )  # fmt: skip
    seconds = round(time.perf_counter() - began, 3)
    metadata = {"version": __version__, "seed": seed, "seconds": seconds}
    card_path = save_avatar(built, card, out_path, metadata)
    for role, result in built.summary["roles"].items():
        click.echo(
            f"{role}: against the unseen partner, CV {result['unseen_cv_difference']:+.3f} and "
            f"RMS {result['unseen_rms_difference']:+.3f} from {name}'s virtual trainer; EMD to "
            f"{name} {result['emd_to_person']:.4f}; the paper's criteria "
            f"{'met' if result['criteria_met'] else 'not all met'} (see the card)"
        )
    held = built.summary["proof"]["held_out"]
    for result in (held or {}).get("roles", {}).values():
        click.echo(result["verdict"])
    click.echo(built.summary["verdict"])
    click.echo(f"wrote {out_path.resolve()} and {card_path.resolve()}")
    click.echo(
        "the avatar file holds the person's strokes, from which their trials can be rebuilt: "
        "share it as you would share the recordings, or write one without them with "
        "`avatar share`"
    )


@avatar.command()
@click.argument("avatar_path", type=click.Path(path_type=Path))
@share_options("The shareable avatar file (.npz).")
def share(avatar_path: Path, out_path: Path, group_size: int) -> None:
    """Write the avatar without the person's strokes: its motion model averaged in groups.

    The players are kept; the motion model (and the references the players read) becomes
    averages of GROUP_SIZE or more of the person's strokes (METHODS section 4c), and the card's
    trial names their number. The card is not copied: it names what the person recorded.
    """
    check_output_file(out_path, ".npz")
    shared = shareable_avatar(load_avatar(avatar_path), group_size)
    shared.save(out_path)
    click.echo(
        f"{shared.name}'s avatar with its strokes averaged in groups of {group_size} or more -> "
        f"{out_path}; {SHARED_HOLDS}"
    )
