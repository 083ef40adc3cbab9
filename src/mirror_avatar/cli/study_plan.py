"""``mirror-avatar study plan``: a study's registered analysis plan, from its protocol."""

from __future__ import annotations

from pathlib import Path

import click

from mirror_avatar.analysis.plan import PLAN_FILES, registered_plan, write_plan
from mirror_avatar.analysis.power_file import read_power
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.lab.design.protocol import load_protocol


@click.command()
@click.option("--protocol", "protocol_file", type=click.Path(path_type=Path), required=True,
              help="The study's protocol, with its [analysis].")  # fmt: skip
@click.option("--power", "power_dir", type=click.Path(path_type=Path), default=None,
              help="The folder `study power --out` wrote: the sample size's justification "
                   "[default: none].")  # fmt: skip
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Folder for plan.md and plan.json.")  # fmt: skip
def plan(protocol_file: Path, power_dir: Path | None, out_dir: Path) -> None:
    """Write the study's preregistration from its protocol: plan.md, and plan.json with its hash.

    The plan states the hypotheses (primary measures, direction, contrast, smallest effect of
    interest, alpha), the design (blocks, conditions, their order, trials, durations), the
    measures with their labels and units, the exclusions the report applies, the models, and
    the sample size with its justification from a `study power` output. plan.json holds the
    plan and the SHA-256 of its canonical JSON; `study report --plan` checks the analysis it
    runs against it.
    """
    check_output_dir(out_dir, files=PLAN_FILES)
    power = None if power_dir is None else read_power(power_dir)
    sha256 = write_plan(registered_plan(load_protocol(protocol_file), power), out_dir)
    click.echo(f"wrote {out_dir.resolve()}: plan SHA-256 {sha256}")
