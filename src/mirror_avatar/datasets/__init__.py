"""Bundled real recordings and their loaders.

``zhai2017``: eighteen real solo mirror-game trials (finger over a Leap Motion sensor) published
with Zhai et al., "Design and Validation of a Virtual Player for Studying Interpersonal
Coordination in the Mirror Game", IEEE Transactions on Cybernetics 48:1018-1029 (2018),
from the repository diBernardoGroup/MirrorGame (commit 0b78206, folder "Optimal control/"),
Apache License 2.0: see ``zhai2017/LICENSE`` and ``zhai2017/README.md`` in this folder.

``synthetic``: synthetic people whose generating processes and parameters are known, split into
development and held-out people (`mirror_avatar.datasets.synthetic`).
"""

from __future__ import annotations

from importlib.resources import as_file, files

from mirror_avatar.files.trial_io import read_mat_struct
from mirror_avatar.files.trials import Trial

ZHAI2017_STYLES = {"fast": "reference1", "slow": "reference2"}
"""Style group -> file stem. ``fast``: about 1 Hz, nearly periodic; ``slow``: about 0.1 Hz."""

BUNDLED_STYLES = tuple(ZHAI2017_STYLES)
"""The styles of the bundled trials, as ``bundled:STYLE`` specs and ``--bundled`` name them."""

ZHAI2017_DURATION = 60.0
"""Each trial covers 60 s (the original software plays its 779 samples over 60 s)."""

ZHAI2017_CITATION = (
    "Zhai C, Alderisio F, Slowinski P, Tsaneva-Atanasova K, di Bernardo M (2018). Design and "
    "validation of a virtual player for studying interpersonal coordination in the mirror game. "
    "IEEE Trans Cybern 48:1018-1029. Data: github.com/diBernardoGroup/MirrorGame, commit "
    "0b7820674860ded972c694796d3dccbefaefb048, Apache-2.0."
)


def load_zhai2017() -> list[Trial]:
    """Load the 18 bundled solo trials (9 per style), at their native ~13 Hz.

    Returns
    -------
    list of Trial
        Trials labelled ``fast-1`` .. ``fast-9`` and ``slow-1`` .. ``slow-9``, with ``group``
        the style, timestamps spread evenly over 60 s, and ``metadata`` holding the source file,
        index, licence and citation. Who recorded them, and how many people, is not documented:
        treat the groups as movement styles, not as individuals.
    """
    trials = []
    for style, stem in ZHAI2017_STYLES.items():
        with as_file(files(__package__) / "zhai2017" / f"{stem}.mat") as path:
            for trial in read_mat_struct(path, ZHAI2017_DURATION, variable=stem, group=style):
                index = trial.metadata["index"]
                trial.metadata.update(
                    {
                        "source": f"zhai2017/{stem}.mat[{index}]",
                        "dataset": "zhai2017",
                        "license": "Apache-2.0",
                        "citation": ZHAI2017_CITATION,
                    }
                )
                trials.append(
                    Trial(
                        trial.times,
                        trial.positions,
                        label=f"{style}-{index + 1}",
                        group=style,
                        metadata=trial.metadata,
                    )
                )
    return trials
