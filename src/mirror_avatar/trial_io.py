"""Reading and writing trial files.

Formats: CSV with header ``time,position`` (the exchange format), and the MATLAB struct format
of the bundled data (a 1xK struct array with fields ``x`` and ``v``). Every reader validates
its input and raises `InputError` with one line that names the file and the problem.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io

from mirror_avatar.errors import InputError
from mirror_avatar.trials import Trial, make_trial


def read_mat_struct(
    path: str | Path, duration: float, variable: str | None = None, group: str = ""
) -> list[Trial]:
    """Read every trial of a MATLAB struct array with a position field ``x``.

    The bundled format has no timestamps: the samples are spread evenly over ``duration``.

    Parameters
    ----------
    path
        A MATLAB v5 ``.mat`` file.
    duration
        Time the samples of each trial span (s).
    variable
        The struct variable to read; by default the only non-private variable in the file.
    group
        Group given to every trial read.

    Returns
    -------
    list of Trial
        One trial per struct element, labelled ``"<stem>-<k>"`` (k from 1), with
        ``metadata["index"] = k - 1``.
    """
    path = Path(path)
    try:
        contents = scipy.io.loadmat(path)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except Exception as error:  # scipy raises many types for corrupt files
        raise InputError(path, f"not a readable MATLAB file ({type(error).__name__})") from None
    names = [name for name in contents if not name.startswith("__")]
    if variable is None:
        if len(names) != 1:
            raise InputError(path, f"expected one variable, found {len(names)}: {names}")
        variable = names[0]
    if variable not in contents:
        raise InputError(path, f"no variable {variable!r}; it has {names}")
    struct = np.asarray(contents[variable])
    if struct.dtype.names is None or "x" not in struct.dtype.names:
        raise InputError(path, f"variable {variable!r} is not a struct array with a field 'x'")
    trials = []
    for k, element in enumerate(struct.ravel()):
        positions = np.asarray(element["x"], dtype=np.float64).ravel()
        times = np.linspace(0.0, duration, positions.size)
        trials.append(
            make_trial(
                times,
                positions,
                source=f"{path}[{k}]",
                label=f"{path.stem}-{k + 1}",
                group=group,
                metadata={"index": k},
            )
        )
    return trials
