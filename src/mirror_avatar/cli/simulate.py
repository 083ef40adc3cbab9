"""``mirror-avatar simulate``: play two players and write the session, metrics and figures."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click

from mirror_avatar.cli.constrained import SEED, SESSION_SECONDS, TRIM_RANGE, ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import import_options
from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.loop import play
from mirror_avatar.figures.sessions import SESSION_FIGURES, plot_session
from mirror_avatar.files.atomic import write_atomic_bytes, write_atomic_json
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.files.trials import PLAYING_RANGE, Trial
from mirror_avatar.metrics import TRIM, session_metrics
from mirror_avatar.metrics.registry import (
    GROUP_PLAYER,
    is_metric,
    label,
    measure,
    registry_order,
    symbol,
)
from mirror_avatar.players import Player, RecordedPlayer, VirtualTrainer
from mirror_avatar.report import render_png
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import load_player

SPEC_HELP = (
    "A player spec: bundled:fast, bundled:slow, a generator or cyber-player .npz, a recorded "
    "trial file (replayed), vt:TRIAL_FILE, or a partner from the literature: adaptive, rpc, hkb, "
    "excitator or kuramoto, with parameters as NAME:key=value,... (defaults and ranges: METHODS "
    "section 13). A spec whose player diverges in a 5 s dry run is refused."
)


def format_metrics(metrics: dict[str, Any]) -> str:
    """Render `mirror_avatar.metrics.session_metrics` output as aligned text tables.

    A group (three or more players) gets its synchronisation and one row per player.
    """
    if "players" in metrics:
        return format_group_metrics(metrics)
    keys = sorted((key for key in metrics if is_metric(key)), key=registry_order)
    rows = [(key, label(key), measure(key).unit) for key in keys]
    width = max(len(description) for _, description, _ in rows)
    lines = []
    for key, description, unit in rows:
        value = metrics.get(key)
        shown = "-" if value is None else f"{value:.4f}"
        lines.append(f"{description:<{width}}  {shown:>8}  {unit}".rstrip())
    return "\n".join(lines)


def format_group_metrics(metrics: dict[str, Any]) -> str:
    """Render the metrics of a group: synchronisation, then a table of the players."""
    lines = [
        "group synchronisation (rho_g, 1 = synchronised)  "
        f"{metrics['group_synchronisation']:.4f} +- {metrics['group_synchronisation_sd']:.4f}",
        f"Kuramoto order parameter                        {metrics['kuramoto_order']:.4f}",
        "player  " + "".join(f"{symbol(key):>8}" for key in GROUP_PLAYER) + "  neighbours",
    ]
    for k, player in enumerate(metrics["players"]):
        cells = "".join(
            f"{'-' if player.get(key) is None else format(player[key], '.4f'):>8}"
            for key in GROUP_PLAYER
        )
        lines.append(f"{k:<6}  {cells}  {player['neighbours']} {player['label']}")
    lines.append("(CV, RMSE in units, lag in s and cross-correlation against the neighbours' mean)")
    for k in range(len(metrics["players"])):
        if f"emd_target_{k}" in metrics:
            lines.append(f"player {k}: EMD to its target's IMS {metrics[f'emd_target_{k}']:.4f}")
    return "\n".join(lines)


def session_options(command: Callable[..., None]) -> Callable[..., None]:
    """Add the options of a simulated session: duration, seed, trim and output folder."""
    options = [
        click.option(
            "--duration", default=60.0, show_default=True,
            **ranged("Session length.", SESSION_SECONDS),
        ),
        click.option("--seed", default=None, **ranged("Session seed (default: fresh).", SEED)),
        click.option(
            "--trim", default=TRIM, show_default=True,
            **ranged("Seconds left out of the metrics.", TRIM_RANGE),
        ),
        click.option(
            "--out", "out_dir", required=True, type=click.Path(path_type=Path),
            help="Directory for session.parquet/.csv/.json and metrics.json.",
        ),
    ]  # fmt: skip
    for option in reversed(options):
        command = option(command)
    return command


EXTEND_HELP = (
    "Let recordings shorter than --duration go on: a replayed player holds its last position, a "
    "recorded reference velocity repeats."
)


def check_recordings(
    players: Sequence[Player], specs: Sequence[str], duration: float, extend: bool
) -> None:
    """Refuse recordings shorter than the session unless ``extend`` (one line naming the spec).

    A recording's length is the span of its samples, first to last; one short of the session
    by at most one of its sampling intervals (or one control period) is its full length: 600
    samples at 10 Hz span 59.9 s and make a 60 s recording. A replayed recording whose
    positions leave the playing range (they are clipped) is warned of on standard error.
    """
    for player, spec in zip(players, specs, strict=True):
        if isinstance(player, RecordedPlayer) and player.outside > 0:
            click.echo(
                f"warning: {spec}: {player.outside:.1%} of the recording's positions lie outside "
                f"the playing range [{PLAYING_RANGE[0]:g}, {PLAYING_RANGE[1]:g}] and are held at "
                "its edge: move them with --centre or --offset",
                err=True,
            )
    if extend:
        return
    for player, spec in zip(players, specs, strict=True):
        if isinstance(player, RecordedPlayer):
            length, step = player.recording
        elif isinstance(player, VirtualTrainer) and isinstance(player.reference, Trial):
            length, step = player.reference.duration, player.reference.recorded_step
        else:
            continue
        if duration - length > max(step, player.period) * (1 + 1e-9):
            raise InputError(
                spec,
                f"the recording lasts {length:.4g} s ({1 / step:.4g} Hz), the session "
                f"{duration:g} s: shorten --duration, or give --extend-recordings",
            )


SESSION_OUTPUTS = (
    "session.parquet",
    "session.csv",
    "session.json",
    "metrics.json",
    *(f"{name}.png" for name in SESSION_FIGURES),
)
"""Every file `write_outputs` may write in its folder (checked before a session is played)."""


def write_outputs(session: Session, out_dir: Path, summary: dict[str, Any]) -> Path:
    """Write the session (Parquet, CSV, sidecar), ``metrics.json`` and its figures (PNG).

    Every file is one of `SESSION_OUTPUTS`. Returns the path of ``metrics.json``.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    parquet, csv, _, metrics = SESSION_OUTPUTS[:4]
    session.save(out_dir / parquet)
    session.save_csv(out_dir / csv)
    metrics_path = out_dir / metrics
    write_atomic_json(metrics_path, summary)
    for name, figure in plot_session(session, summary["trim"]).items():
        write_atomic_bytes(out_dir / f"{name}.png", render_png(figure))
    return metrics_path


@click.command()
@click.option("--leader", "leader_spec", required=True, help=f"Player 0. {SPEC_HELP}")
@click.option("--follower", "follower_spec", required=True, help=f"Player 1. {SPEC_HELP}")
@click.option(
    "--joint",
    is_flag=True,
    help="Joint improvisation: both virtual trainers take the joint preset, neither leads.",
)
@session_options
@click.option("--extend-recordings", is_flag=True, help=EXTEND_HELP)
@import_options
def simulate(
    leader_spec: str,
    follower_spec: str,
    joint: bool,
    duration: float,
    seed: int | None,
    trim: float,
    out_dir: Path,
    extend_recordings: bool,
    options: ImportOptions,
) -> None:
    """Play a session between two players and write it with its metrics.

    Player 0 is the --leader, player 1 the --follower; virtual trainers take the leader and
    follower presets (both the joint preset with --joint). Relative phase and time lag are
    player 0 minus player 1: positive when player 0 is ahead.
    """
    check_output_dir(out_dir, files=SESSION_OUTPUTS)
    if not trim < duration:
        raise InputError("--trim", f"must lie in [0, duration) = [0, {duration:g}) s, got {trim:g}")
    roles = ("joint", "joint") if joint else ("leader", "follower")
    players = [
        load_player(spec, role, options)
        for spec, role in zip((leader_spec, follower_spec), roles, strict=True)
    ]
    check_recordings(players, (leader_spec, follower_spec), duration, extend_recordings)
    session = play(players, duration=duration, seed=seed, roles=roles)
    session.metadata["specs"] = [leader_spec, follower_spec]
    metrics = session_metrics(session, trim=trim)
    summary = {
        "seed": session.metadata["seed"],
        "specs": {"player 0": leader_spec, "player 1": follower_spec},
        "roles": list(roles),
        "duration": session.duration,
        "trim": trim,
        "convention": "relative phase and time lag: player 0 minus player 1, positive = 0 ahead",
        "metrics": metrics,
    }
    metrics_path = write_outputs(session, out_dir, summary)
    click.echo(
        f"player 0 ({roles[0]}): {leader_spec}; player 1 ({roles[1]}): {follower_spec}; "
        f"{session.duration:g} s, seed {summary['seed']}"
    )
    click.echo(format_metrics(metrics))
    click.echo(f"wrote {metrics_path.parent.resolve()}")
