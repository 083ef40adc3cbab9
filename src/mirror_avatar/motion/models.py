"""The package's motion models, by kind: which a model file holds, and how to read it back.

``strokes`` (`mirror_avatar.motion.strokes.StrokeGenerator`, the default for a person's avatar)
chains the person's strokes; ``ims`` (`mirror_avatar.motion.generator.IMSGenerator`, the paper's)
walks a Markov chain over STFT frames. A model's metadata names its kind; a file or an avatar part
without one holds an IMS generator (written before the stroke generator existed).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.model_files import read_archive
from mirror_avatar.motion import generator, strokes
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.strokes import StrokeGenerator

MotionModel = StrokeGenerator | IMSGenerator
"""A fitted model of a person's solo motion."""

MODEL_KINDS: dict[str, type[StrokeGenerator] | type[IMSGenerator]] = {
    "strokes": StrokeGenerator,
    "ims": IMSGenerator,
}
"""Kind -> class; the first is the default."""

DEFAULT_KIND = "strokes"
"""The kind ``generator fit`` and ``avatar create`` fit unless told otherwise."""

_FORMATS: dict[object, type[StrokeGenerator] | type[IMSGenerator]] = {
    strokes.FORMAT_NAME: StrokeGenerator,
    generator.FORMAT_NAME: IMSGenerator,
}


def kind_of(model: MotionModel) -> str:
    """Return a model's kind (a key of `MODEL_KINDS`)."""
    return "strokes" if isinstance(model, StrokeGenerator) else "ims"


def model_arrays(model: MotionModel) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Return a model's arrays and metadata (its ``to_arrays``), the metadata naming its kind."""
    arrays, metadata = model.to_arrays()
    return arrays, metadata | {"kind": kind_of(model)}


def motion_from_arrays(
    arrays: Mapping[str, NDArray[Any]],
    metadata: Mapping[str, Any],
    source: str | os.PathLike[str] | None,
) -> MotionModel:
    """Rebuild a model from `model_arrays` output with the loader its kind names.

    Raises
    ------
    InputError
        ``source: problem`` for an unknown kind, or what the kind's ``from_arrays`` refuses.
    """
    kind = metadata.get("kind", "ims")
    if not isinstance(kind, str) or kind not in MODEL_KINDS:
        raise InputError(
            source, f"unknown motion model kind {excerpt(kind)}: one of {', '.join(MODEL_KINDS)}"
        )
    return MODEL_KINDS[kind].from_arrays(arrays, metadata, source)


def load_motion(path: str | os.PathLike[str]) -> MotionModel:
    """Read a model file of either kind, by the format its metadata names.

    Raises
    ------
    InputError
        The file is missing, corrupt, of another format or inconsistent.
    """
    _, metadata = read_archive(path)
    loader = _FORMATS.get(metadata.get("format"), IMSGenerator)
    return loader.load(path)
