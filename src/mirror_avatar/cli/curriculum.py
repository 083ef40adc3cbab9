"""``mirror-avatar curriculum``: stage avatars moving from a patient's motion to a target's."""

from __future__ import annotations

import math
from pathlib import Path

import click
import pandas as pd

from mirror_avatar import __version__
from mirror_avatar.cli.constrained import SEED, ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import import_options
from mirror_avatar.cli.train import load_generator
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments.curriculum import (
    DURATION,
    N_DRAWS,
    N_SESSIONS,
    STAGES,
    curriculum_section,
    measure_stages,
    own_emd,
)
from mirror_avatar.experiments.verdicts import section_verdict
from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.files.importing import ImportOptions, excerpt
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.report import REPORT_FILES, write_report
from mirror_avatar.training.curriculum import METHODS, StageMotion, save_stage

MAX_STAGES = 50
PERSON_HELP = "A generator model .npz or bundled:STYLE."


@click.command()
@click.option(
    "--patient",
    "patient_spec",
    required=True,
    help="The patient: a generator .npz or bundled:STYLE.",
)
@click.option(
    "--target",
    "target_spec",
    required=True,
    help="The target person: a generator .npz or bundled:STYLE.",
)
@click.option("--stages", default=STAGES, show_default=True,
              **ranged("Stages K.", Interval(int, 2, MAX_STAGES)))  # fmt: skip
@click.option(
    "--method", type=click.Choice(METHODS), default="displacement", show_default=True,
    help="How the stages move between the two people (METHODS section 10).",
)  # fmt: skip
@click.option("--seed", default=0, show_default=True, **ranged("Seed of the measurements.", SEED))
@click.option("--out", "out_dir", required=True, type=click.Path(path_type=Path), help="Folder.")
@import_options
def curriculum(
    patient_spec: str,
    target_spec: str,
    stages: int,
    method: str,
    seed: int,
    out_dir: Path,
    options: ImportOptions,
) -> None:
    """Write K stage avatars from the patient's motion (stage 1) to the target's (stage K).

    Writes OUT/stage-1.npz ... stage-K.npz (each a player SPEC, and a model generator sample
    takes), plan.json (weights and, per stage, the EMD to both people, strokes and how a
    patient-like virtual trainer coordinates with it) and report.html with both methods.
    """
    names = [f"stage-{k}.npz" for k in range(1, stages + 1)]
    check_output_dir(out_dir, files=[*names, "plan.json", *REPORT_FILES])
    patient = _ims_generator("--patient", patient_spec, options)
    target = _ims_generator("--target", target_spec, options)
    if not math.isclose(patient.rate, target.rate):
        raise InputError(
            "--target",
            f"{excerpt(target_spec)} moves at {target.rate:g} Hz and --patient "
            f"{excerpt(patient_spec)} at {patient.rate:g} Hz: fit both at one rate",
        )
    people = {
        name: model.sample(DURATION, N_DRAWS, random_state=seed)
        for name, model in (("patient", patient), ("target", target))
    }
    table = measure_stages(patient, target, people, stages, N_DRAWS, N_SESSIONS, seed)
    own = {name: own_emd(trials) for name, trials in people.items()}
    out_dir.mkdir(parents=True, exist_ok=True)
    plan = []
    rows = pd.DataFrame(table.loc[method]).to_dict(orient="records")
    for k, (name, row) in enumerate(zip(names, rows, strict=True), start=1):
        info = {"index": k, "of": stages, "patient": patient_spec, "target": target_spec}
        motion = StageMotion(patient, target, row["weight"], method)  # type: ignore[arg-type]
        save_stage(motion, out_dir / name, info)
        plan.append({"file": name, "stage": k} | row)
    write_atomic_json(
        out_dir / "plan.json",
        {"patient": patient_spec, "target": target_spec, "method": method, "seed": seed,
         "own_emd": own, "stages": plan},
    )  # fmt: skip
    section = curriculum_section(table, own, patient_spec, target_spec)
    section.verdict = section_verdict("curriculum", section.metrics)
    metadata = {"version": __version__, "seed": seed}
    report = write_report([section], out_dir, "Curriculum", metadata, lead=section.verdict)
    click.echo(table.loc[method].round(4).to_string())
    click.echo(f"{stages} stages ({method}) -> {out_dir}; report {report}")


def _ims_generator(option: str, spec: str, options: ImportOptions) -> IMSGenerator:
    """Return the IMS generator a spec names; InputError for a stroke generator."""
    model = load_generator(spec, options)
    if not isinstance(model, IMSGenerator):
        raise InputError(
            option,
            f"{excerpt(spec)} is a stroke generator: curriculum stages blend IMS generators "
            "(mirror-avatar generator fit --kind ims)",
        )
    return model
