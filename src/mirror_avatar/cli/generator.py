"""``mirror-avatar generator``: fit a motion model on trial files and sample new trials."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import numpy as np
import pandas as pd

from mirror_avatar.cli.constrained import RATE_HZ, SEED, SESSION_SECONDS, ranged
from mirror_avatar.cli.outputs import check_output_dir, check_output_file
from mirror_avatar.cli.reading import import_options, read_and_report
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.datasets import BUNDLED_STYLES, load_zhai2017
from mirror_avatar.files.atomic import write_atomic_json, write_atomic_text
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.files.model_files import read_archive
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.files.trials import Trial
from mirror_avatar.motion.codebook_size import sweep_codebook
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.hyperparameters import CODEBOOK_SIZES, KMEANS_SEEDS
from mirror_avatar.motion.models import DEFAULT_KIND, MODEL_KINDS, MotionModel, load_motion
from mirror_avatar.motion.sharing import DEFAULT_GROUP_SIZE, shareable
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.signatures.likeness import Likeness, compare_motion, trial_velocity
from mirror_avatar.training.curriculum import FORMAT_NAME as STAGE_FORMAT
from mirror_avatar.training.curriculum import StageMotion, load_stage


@click.group()
def generator() -> None:
    """Learn a person's motion (stroke or IMS generator) and generate motion with it."""


@generator.command()
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option(
    "--out", "out_path", required=True, type=click.Path(path_type=Path), help="Model file (.npz)."
)
@click.option(
    "--symbols",
    default="auto",
    show_default=True,
    **ranged(
        "Codebook size N, or auto: chosen by cross-validation on the trials (the paper: 256).",
        CODEBOOK_SIZES,
    ),
)
@click.option(
    "--kind",
    type=click.Choice(tuple(MODEL_KINDS)),
    default=DEFAULT_KIND,
    show_default=True,
    help="strokes: chain the person's strokes (METHODS section 4b); ims: the paper's Markov "
    "chain over STFT frames (METHODS section 4).",
)
@click.option(
    "--seed", default=0, show_default=True, **ranged("Seed of the fit and sampling.", KMEANS_SEEDS)
)
@click.option(
    "--bundled",
    type=click.Choice(BUNDLED_STYLES),
    help="Fit on the bundled Zhai 2017 trials of this style (as well as any files).",
)
@click.option(
    "--sweep",
    is_flag=True,
    help="Also sweep codebook sizes 32-256 on a 2/3 : 1/3 split of the trials and write "
    "MODEL.sweep.csv (--kind ims).",
)
@click.option(
    "--likeness/--no-likeness",
    default=True,
    show_default=True,
    help="Check generated motion against held-out trials with the human-likeness battery "
    "(up to 5 trials held out in turn, each fold refitted) and write MODEL.likeness.json.",
)
@import_options
def fit(
    paths: tuple[Path, ...],
    out_path: Path,
    symbols: int | str,
    kind: str,
    seed: int,
    bundled: str | None,
    sweep: bool,
    likeness: bool,
    options: ImportOptions,
) -> None:
    """Fit a generator on the trials in FILE_OR_DIR... (CSV, MAT, Parquet, BIDS motion)."""
    if kind != "ims" and (sweep or symbols != "auto"):
        option = "--sweep" if sweep else "--symbols"
        raise InputError(option, "sets the IMS generator's codebook: give --kind ims")
    beside = [path for path, wanted in ((sweep_path, sweep), (likeness_path, likeness)) if wanted]
    check_output_file(out_path, ".npz", beside=[path(out_path) for path in beside])
    if not paths and bundled is None:
        raise InputError(None, "give trial files or directories, or --bundled fast|slow")
    trials = read_and_report(paths, "none", options) if paths else []
    trials += [t for t in load_zhai2017() if t.group == bundled] if bundled else []
    model: MotionModel
    if kind == "ims":
        model = IMSGenerator(n_symbols=symbols, random_state=seed).fit(trials)
    else:
        model = StrokeGenerator(random_state=seed).fit(trials)
    model.save(out_path)
    click.echo(_describe_fit(model, len(trials), out_path))
    if likeness:
        _report_likeness(trials, model, seed, out_path)
    if sweep:
        table = _sweep(trials, seed)
        write_atomic_text(sweep_path(out_path), table.to_csv())
        click.echo(table.to_string())
        click.echo(f"sweep -> {sweep_path(out_path)}")


def _describe_fit(model: MotionModel, n_trials: int, out_path: Path) -> str:
    """Describe the fit in a line (with the codebook size's choice for an IMS generator)."""
    summary = model.training_summary_
    holds = "; the file holds the training {}, from which the trials can be rebuilt: share it as "
    holds += "you would share the recordings"
    if isinstance(model, StrokeGenerator):
        return (
            f"{n_trials} trials, {summary['n_strokes']} strokes -> {out_path}"
            + holds.format("strokes")
            + ", or write a file without them with `generator share`"
        )
    choice = summary["complexity"]
    lines = [_describe_choice(choice)] if choice["rule"] != "fixed" else []
    lines.append(
        f"{n_trials} trials, {summary['n_frames']} frames, {model.n_symbols_} symbols, "
        f"distortion {summary['distortion']:.4g} -> {out_path}"
        + (holds.format("frames") if model.emission == "exemplar" else "")
    )
    return "\n".join(lines)


def sweep_path(model: Path) -> Path:
    """Where ``generator fit --sweep`` writes its table: ``MODEL.sweep.csv``."""
    return model.with_name(model.stem + ".sweep.csv")


def likeness_path(model: Path) -> Path:
    """Where ``generator fit`` writes its human-likeness battery: ``MODEL.likeness.json``."""
    return model.with_name(model.stem + ".likeness.json")


LIKENESS_FOLDS = 5
"""Most trials ``generator fit`` holds out in turn for the battery, spread over the order."""

SAMPLES_PER_FOLD = 1
"""Trials each fold's generator makes, as long as its held-out trial (**choice**: one, so that
each generated trial comes from its own model as each held-out trial is its own recording, and
the permutation tests relabel independent units)."""


def _report_likeness(trials: list[Trial], model: MotionModel, seed: int, out_path: Path) -> None:
    """Print and write the battery of generated against held-out trials (or why it is not run)."""
    if len(trials) < 2:
        click.echo("likeness not measured: it needs 2 trials, one to hold out")
        return
    try:
        result = held_out_likeness(trials, model, seed)
    except InputError as error:
        click.echo(f"likeness not measured: {error}")
        return
    write_atomic_json(likeness_path(out_path), result.to_json_dict())
    click.echo("generated trials against held-out ones (each fold refitted without its trial):")
    click.echo(result.table().to_string(float_format=lambda v: f"{v:.4g}", na_rep="-"))
    click.echo(f"likeness: {result.verdict()} -> {likeness_path(out_path)}")


def held_out_likeness(trials: list[Trial], model: MotionModel, seed: int) -> Likeness:
    """Run the human-likeness battery on generated trials against held-out ones.

    Up to `LIKENESS_FOLDS` trials, spread over the order, are held out in turn; a generator
    with ``model``'s settings (and codebook size) is fitted on the others and makes
    `SAMPLES_PER_FOLD` trials as long as the held-out one. The person's own variability is that
    of all their trials. Fold ``k`` is seeded by ``draw_seeds([seed, 38], folds)[k]``.
    """
    held = np.unique(np.linspace(0, len(trials) - 1, min(len(trials), LIKENESS_FOLDS)).round())
    reference, generated = [], []
    for k, fold_seed in zip(held.astype(int), draw_seeds([seed, 38], held.size), strict=True):
        fitted = model.unfitted(fold_seed).fit(trials[:k] + trials[k + 1 :])
        reference.append(trial_velocity(trials[k], model.rate))
        samples = fitted.sample(trials[k].duration, SAMPLES_PER_FOLD, random_state=fold_seed)
        generated += [trial_velocity(t, model.rate) for t in samples]
    own = [trial_velocity(t, model.rate) for t in trials]
    return compare_motion(reference, generated, own=own, rate=model.rate, seed=seed)


def _describe_choice(complexity: dict[str, Any]) -> str:
    """One line per codebook size tried: its cross-validated EMD, and which was chosen."""
    lines = [
        f"codebook size by {complexity['rule']} over {complexity['folds']} folds (EMD of "
        "generated to held-out IMS; between the person's own trials: "
        f"{complexity['human_emd']:.4f})"
    ]
    for size, mean, se in zip(
        complexity["candidates"], complexity["emd_mean"], complexity["emd_se"], strict=True
    ):
        chosen = "  <- chosen" if size == complexity["chosen"] else ""
        lines.append(f"  {size:4d} symbols: {mean:.4f} +- {se:.4f}{chosen}")
    return "\n".join(lines)


GROUP_SIZES = Interval(int, 2, 100)
"""Strokes averaged into each stroke of a shared model (``--group-size``)."""


SHARED_HOLDS = (
    "the file holds no stroke of the person's trials, and no trial can be rebuilt from it"
)
"""What a shared file holds, as ``generator share`` and ``avatar share`` say it."""


def share_options(what: str) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Return the options of a command that writes a shareable file.

    They are ``--out`` (``what``: the file's description for its help) and ``--group-size``.
    """
    out = click.option(
        "--out", "out_path", required=True, type=click.Path(path_type=Path), help=what
    )
    group_size = click.option(
        "--group-size", default=DEFAULT_GROUP_SIZE, show_default=True,
        **ranged("Fewest of the person's strokes averaged into each stroke of the file "
                 "(microaggregation's k; METHODS section 4c).", GROUP_SIZES),
    )  # fmt: skip
    return lambda command: out(group_size(command))


@generator.command()
@click.argument("model_path", type=click.Path(path_type=Path))
@share_options("The shareable model file (.npz).")
def share(model_path: Path, out_path: Path, group_size: int) -> None:
    """Write a stroke model that does not hold the person's trials (strokes averaged in groups).

    MODEL_PATH is a stroke generator fitted by ``generator fit``; OUT samples as a generator
    does, from averages of GROUP_SIZE or more of the person's strokes (METHODS section 4c).
    """
    check_output_file(out_path, ".npz")
    model = load_motion(model_path)
    if not isinstance(model, StrokeGenerator):
        raise InputError(
            model_path,
            "an IMS generator's frames are the person's recordings: only a stroke generator "
            "can be shared (generator fit --kind strokes)",
        )
    shared = shareable(model, group_size)
    shared.save(out_path)
    click.echo(
        f"{model.lengths_.size} strokes averaged into {shared.lengths_.size}, each of "
        f"{group_size} or more -> {out_path}; {SHARED_HOLDS}"
    )


@generator.command()
@click.argument("model_path", type=click.Path(path_type=Path))
@click.option(
    "--duration", default=60.0, show_default=True, **ranged("Seconds per trial.", SESSION_SECONDS)
)
@click.option("--count", default=1, show_default=True,
              **ranged("Number of trials.", Interval(int, 1, 100_000)))  # fmt: skip
@click.option(
    "--out", "out_dir", required=True, type=click.Path(path_type=Path), help="Output directory."
)
@click.option("--seed", default=0, show_default=True, **ranged("Seed of the sampling.", SEED))
@click.option(
    "--rate", default=100.0, show_default=True, **ranged("Rate of the written files.", RATE_HZ)
)
def sample(
    model_path: Path, duration: float, count: int, out_dir: Path, seed: int, rate: float
) -> None:
    """Generate COUNT trials with the generator (or curriculum stage) in MODEL_PATH, as CSV files.

    Also writes ``samples.json`` (model, seed, duration, rate and file names).
    """
    names = [f"generated-{k + 1:03d}.csv" for k in range(count)]
    check_output_dir(out_dir, files=[*names, "samples.json"])
    model = _load_sampler(model_path)
    trials = model.sample(duration, n=count, random_state=seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    for trial, name in zip(trials, names, strict=True):
        same = math.isclose(trial.rate, rate, rel_tol=1e-6) and trial.is_uniform
        write_csv_trial(trial if same else trial.resampled(rate), out_dir / name)
    manifest = {
        "model": str(model_path),
        "seed": seed,
        "duration": duration,
        "rate": rate,
        "files": names,
    }
    write_atomic_json(out_dir / "samples.json", manifest)
    click.echo(f"{count} trials of {duration:g} s -> {out_dir}")


def _load_sampler(path: Path) -> MotionModel | StageMotion:
    """Load a generator, or a curriculum stage (its motion sampled alone), by the file's format."""
    _, metadata = read_archive(path)
    return load_stage(path) if metadata.get("format") == STAGE_FORMAT else load_motion(path)


def _sweep(trials: list[Trial], seed: int) -> pd.DataFrame:
    if len(trials) < 2:
        raise InputError("--sweep", "needs at least 2 trials (2/3 to fit, 1/3 to compare)")
    order = np.random.default_rng(seed).permutation(len(trials))
    n_train = min(max(round(2 * len(trials) / 3), 1), len(trials) - 1)
    train = [trials[i] for i in order[:n_train]]
    test = [trials[i] for i in order[n_train:]]
    make = IMSGenerator(random_state=seed).with_symbols
    return sweep_codebook(make, train, test, random_state=seed)
