"""Crafted model files: each is refused in one `InputError` line before it can do harm.

Every hostile file is made here from a small valid model (an IMS generator, a cyber player, a
cyber player carrying its reference generator and a deep cyber player), by editing its metadata,
its arrays or the zip archive itself.
"""

from __future__ import annotations

import io
import json
import math
import struct
import tracemalloc
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.player import DeepCyberPlayer, load_deep_cyber_player
from mirror_avatar.files.importing import ECHO_CHARS
from mirror_avatar.files.model_files import (
    MAX_DIRECTORY_BYTES,
    MAX_MEMBER_BYTES,
    MAX_MEMBERS,
    MAX_METADATA_CHARS,
    MAX_TOTAL_BYTES,
)
from mirror_avatar.files.user_files import MAX_DEPTH
from mirror_avatar.learning.agent import CyberPlayer, load_cyber_player
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.signatures.signature import DEFAULT_BINS

Loader = Callable[[Path], object]
LOADERS: dict[str, Loader] = {
    "generator": IMSGenerator.load,
    "cyber": load_cyber_player,
    "reference": load_cyber_player,
    "deep": load_deep_cyber_player,
}
"""How each kind of file is loaded; ``reference`` is a cyber player holding a generator."""

GENERATOR_AT = {"generator": ("parameters",), "reference": ("reference", "parameters")}
"""Where the generator's parameters sit in the metadata of each kind of file holding one."""

ARRAY_PREFIX = {"generator": "", "reference": "reference_"}
"""Prefix of the generator's arrays in each kind of file holding one."""

HOSTILE_VALUES = [
    "x", [1], {"a": 1}, True, 10**4000, -(10**4000), math.nan, math.inf, -math.inf, 1e308, -1e308,
]  # fmt: skip
"""Values no parameter accepts (the 4001-digit integers must not be echoed in full)."""


def tiny_generator() -> IMSGenerator:
    """A valid 4-symbol generator with an 8-sample window and 6 exemplars, built without fitting."""
    n, window = 4, 8
    rng = np.random.default_rng(0)
    arrays = {
        "codebook": rng.normal(0.0, 0.1, (n, window)),
        "transmat": np.full((n, n), 1.0 / n),
        "startprob": np.full(n, 1.0 / n),
        "exemplars": rng.normal(0.0, 0.1, (6, window)),
        "exemplar_next": np.array([1, 2, -1, 4, 5, -1]),
    }
    parameters = IMSGenerator(n_symbols=n, window=window, hop=2, random_state=0).get_params()
    metadata = {"parameters": parameters, "training": {"groups": ["tiny"]}}
    return IMSGenerator.from_arrays(arrays, metadata, "tiny")


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    """One valid file of each kind."""
    tiny_generator().save(tmp_path / "generator.npz")
    cyber = CyberPlayer()
    cyber.initialise_q(0, 1.0)
    cyber.target_counts_ = np.ones(DEFAULT_BINS.n)
    reference = CyberPlayer(make_default_discretisation("reference"), reference=tiny_generator())
    reference.initialise_q(0, 1.0)
    deep = DeepCyberPlayer(hidden=(8, 4), n_slots=2)
    deep.initialise_policy(0)
    return {
        "generator": tmp_path / "generator.npz",
        "cyber": cyber.save(tmp_path / "cyber.npz"),
        "reference": reference.save(tmp_path / "reference.npz"),
        "deep": deep.save(tmp_path / "deep.npz"),
    }


def contents(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """A model file's arrays and decoded metadata."""
    with np.load(path, allow_pickle=False) as archive:
        arrays = {name: archive[name] for name in archive.files}
    return arrays, json.loads(str(arrays.pop("metadata")))


def write(path: Path, arrays: dict[str, np.ndarray], metadata: dict[str, Any] | str) -> None:
    """Write a model file as `save_model` does, with any arrays and metadata."""
    text = metadata if isinstance(metadata, str) else json.dumps(metadata)
    np.savez(path, metadata=np.array(text), **arrays)


def set_value(path: Path, keys: tuple[str, ...], value: Any) -> None:
    """Set ``metadata[keys[0]][keys[1]]...`` of a model file."""
    arrays, metadata = contents(path)
    target = metadata
    for key in keys[:-1]:
        target = target[key]
    target[keys[-1]] = value
    write(path, arrays, metadata)


def remove_value(path: Path, keys: tuple[str, ...]) -> None:
    """Delete ``metadata[keys[0]][keys[1]]...`` of a model file."""
    arrays, metadata = contents(path)
    target = metadata
    for key in keys[:-1]:
        target = target[key]
    del target[keys[-1]]
    write(path, arrays, metadata)


def set_array(path: Path, name: str, array: np.ndarray) -> None:
    """Replace or add one array of a model file."""
    arrays, metadata = contents(path)
    arrays[name] = array
    write(path, arrays, metadata)


def npy(array: np.ndarray) -> bytes:
    """The ``.npy`` bytes of any array (object arrays pickled, as an attacker may)."""
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, array, allow_pickle=True)
    return buffer.getvalue()


def npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    """A version 1.0 ``.npy`` header claiming ``shape`` and ``descr``."""
    buffer = io.BytesIO()
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue()


def set_members(path: Path, members: dict[str, bytes], method: int = zipfile.ZIP_STORED) -> None:
    """Rewrite the archive with some members (raw bytes) replaced or added."""
    with zipfile.ZipFile(path) as archive:
        kept = {info.filename: archive.read(info) for info in archive.infolist()}
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in (kept | members).items():
            archive.writestr(name, data, compress_type=method if name in members else None)


def refused(path: Path, kind: str, fragment: str) -> str:
    """Load ``path`` as ``kind``, expect one `InputError` line naming it and ``fragment``."""
    with pytest.raises(InputError) as caught:
        LOADERS[kind](path)
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    assert fragment in message, message
    return message


# --- 1. every parameter read from a file lies in its range ---------------------------------------


@pytest.mark.parametrize(
    ("key", "value", "fragment"),
    [
        ("n_substeps", 1e9, "n_substeps 1000000000 is outside 1..64"),
        ("n_substeps", 10**9, "n_substeps 1000000000 is outside 1..64"),
        ("n_substeps", 0, "n_substeps 0 is outside 1..64"),
        ("n_substeps", 2.5, "n_substeps must be an integer, not 2.5"),
        ("n_substeps", "3", "n_substeps must be an integer, not '3'"),
        ("omega", 1e9, "omega 1000000000.0 is outside 0..100"),
        ("omega", math.nan, "omega nan is outside 0..100"),
        ("omega", [0.1], "omega must be a number, not [0.1]"),
        ("alpha", -1.0, "alpha -1.0 is outside 0..1000"),
        ("beta", math.inf, "beta inf is outside 0..1000"),
        ("gamma", -1e4, "gamma -10000.0 is outside -1000..1000"),
        ("eta", 1e-300, "eta 1e-300 is outside 1e-08..10000"),
        ("eta", 0.0, "eta 0.0 is outside 1e-08..10000"),
        ("period", 1e3, "period 1000.0 is outside 0.001..1"),
        ("period", 0.0, "period 0.0 is outside 0.001..1"),
        ("theta_p", 2.0, "theta_p 2.0 is outside 0..1"),
        ("theta_v", 0.5, "theta_p + theta_v must not exceed 1"),
        ("initial_position", 0.9, "initial_position 0.9 is outside -0.5..0.5"),
        ("initial_position", None, "initial_position must be a number, not None"),
        ("speed", 1.0, "unknown parameter 'speed'"),
    ],
)
def test_cyber_parameters_outside_their_range_are_refused(files, key, value, fragment) -> None:
    set_value(files["cyber"], ("parameters", key), value)
    refused(files["cyber"], "cyber", fragment)


@pytest.mark.parametrize("key", ["omega", "n_substeps", "initial_position"])
def test_missing_cyber_parameters_are_refused(files, key) -> None:
    remove_value(files["cyber"], ("parameters", key))
    refused(files["cyber"], "cyber", f"parameters lack {key}")


@pytest.mark.parametrize("kind", ["generator", "reference"])
@pytest.mark.parametrize(
    ("key", "value", "fragment"),
    [
        ("rate", 1e308, "rate: 1e+308 is not allowed; give a number in [1, 10000] Hz"),
        ("rate", 0.0, "rate: 0.0 is not allowed"),
        ("rate", math.nan, "rate: nan is not allowed"),
        ("n_symbols", 10**6, "n_symbols: 1000000 is not allowed; give auto or a whole number"),
        ("n_symbols", 1.5, "n_symbols: 1.5 is not allowed"),
        ("window", 7, "window: 7 is not allowed; give a multiple of 2 in [4, 4096]"),
        ("window", 10**5, "window: 100000 is not allowed"),
        ("hop", 0, "hop: 0 is not allowed; give a whole number in [1, 2048]"),
        ("hop", 5, "hop: 5 is not allowed; give a whole number in [1, 4]"),
        ("pseudo_count", -1.0, "pseudo_count: -1.0 is not allowed; give a number in [1e-12, 1e+06"),
        ("n_init", 0, "n_init: 0 is not allowed; give a whole number in [1, 1000]"),
        ("random_state", -1, "random_state: -1 is not allowed; give a whole number in [0, 42949"),
        ("random_state", "seed", "random_state: 'seed' is not allowed"),
        ("colour", 1, "unknown generator parameter 'colour'"),
        ("emission", "mean", "emission: 'mean' is not allowed; give one of exemplar, centroid"),
    ],
)
def test_generator_parameters_outside_their_range_are_refused(
    files, kind, key, value, fragment
) -> None:
    set_value(files[kind], (*GENERATOR_AT[kind], key), value)
    refused(files[kind], kind, fragment)


@pytest.mark.parametrize(
    ("kind", "key"),
    [("cyber", key) for key in ("omega", "theta_p", "theta_v", "alpha", "beta", "gamma", "eta",
                                "period", "n_substeps", "initial_position")]
    + [(kind, key) for kind in ("generator", "reference")
       for key in ("n_symbols", "window", "hop", "rate", "pseudo_count", "n_init", "random_state",
                   "emission")],
)  # fmt: skip
def test_every_parameter_refuses_hostile_values_in_one_short_line(files, kind, key) -> None:
    keys = ("parameters", key) if kind == "cyber" else (*GENERATOR_AT[kind], key)
    for value in HOSTILE_VALUES:
        set_value(files[kind], keys, value)
        message = refused(files[kind], kind, key)
        assert len(message) < len(str(files[kind])) + 120 and "0" * (ECHO_CHARS + 1) not in message


@pytest.mark.parametrize(
    ("name", "array", "fragment"),
    [
        ("actions", np.array([-1e6, 0.0, 1.0]), "actions holds -1000000.0; its values must be "
                                                "finite and within -100..100"),
        ("actions", np.array([math.nan, 1.0]), "actions holds nan"),
        ("actions", np.zeros(65), "number of actions 65 is outside 1..64"),
        ("actions", np.zeros(0), "number of actions 0 is outside 1..64"),
        ("edges", np.full(27, math.inf), "edges holds inf; its values must be finite"),
        ("edges", np.arange(27.0)[::-1], "edges of feature 0 must be finite and increasing"),
        ("edges", np.zeros(27), "edges of feature 0 must be finite and increasing"),
        ("q_table", np.full((3360, 9), math.inf), "q_table holds inf"),
        ("q_table", np.zeros((5, 9)), "Q-table shape (5, 9) does not match 3360 states x 9"),
        ("target_counts", np.full(DEFAULT_BINS.n, math.nan), "target_counts holds nan"),
        ("target_counts", -np.ones(DEFAULT_BINS.n), "target_counts holds -1.0"),
        ("target_counts", np.ones(3), "target_counts has shape (3,), expected (200,)"),
    ],
)  # fmt: skip
def test_cyber_arrays_outside_their_range_are_refused(files, name, array, fragment) -> None:
    set_array(files["cyber"], name, array)
    refused(files["cyber"], "cyber", fragment)


def test_a_discretisation_beyond_the_q_table_limit_is_refused(files) -> None:
    """101^4 cells x 9 actions: refused before the Q-table's shape is even compared."""
    set_array(files["cyber"], "edges", np.tile(np.arange(100.0), 4))
    set_array(files["cyber"], "edge_counts", np.full(4, 100))
    refused(files["cyber"], "cyber", "Q-table size 936543609 is outside 1..16777216")


@pytest.mark.parametrize("kind", ["generator", "reference"])
@pytest.mark.parametrize(
    ("name", "array", "fragment"),
    [
        ("codebook", np.full((4, 8), math.nan), "codebook holds nan"),
        ("codebook", np.full((4, 8), 1e300), "codebook holds 1e+300; its values must be finite "
                                             "and within -40..40"),
        ("codebook", np.zeros((4, 9)), "codebook has shape (4, 9), expected (4, 8)"),
        ("transmat", np.full((3, 3), 1 / 3), "transmat has shape (3, 3), expected (4, 4)"),
        ("transmat", np.full((4, 4), math.inf), "transmat holds inf"),
        ("transmat", np.eye(4) * 2 - 0.25, "not valid distributions"),
        ("startprob", np.array([1.5, -0.5, 0.0, 0.0]), "not valid distributions"),
        ("startprob", np.full(4, 0.5), "not valid distributions"),
        ("exemplars", np.full((6, 8), math.nan), "exemplars holds nan"),
        ("exemplars", np.zeros((6, 9)), "exemplars has shape (6, 9), expected (6, 8)"),
        ("exemplars", np.zeros((5, 8)), "exemplars has shape (5, 8), expected (6, 8)"),
        ("exemplar_next", np.array([1, 2, -1, 4, 6, -1]), "exemplar_next holds 6"),
        ("exemplar_next", np.array([1, 2, -2, 4, 5, -1]), "exemplar_next holds -2"),
        ("exemplar_next", np.zeros((6, 1), dtype=int), "exemplar_next has shape (6, 1)"),
        ("exemplar_next", np.full(6, 0.5), "exemplar_next has dtype float64, expected integers"),
    ],
)  # fmt: skip
def test_generator_arrays_outside_their_range_are_refused(
    files, kind, name, array, fragment
) -> None:
    set_array(files[kind], ARRAY_PREFIX[kind] + name, array)
    refused(files[kind], kind, fragment)


def test_a_reference_generator_missing_an_array_is_refused(files) -> None:
    arrays, metadata = contents(files["reference"])
    del arrays["reference_codebook"]
    write(files["reference"], arrays, metadata)
    refused(files["reference"], "reference", "missing array(s) codebook")


# --- 2. archive members are bounded before they are read -----------------------------------------


def write_bomb(path: Path, members: dict[str, int]) -> Path:
    """Write valid metadata and members of so many MiB of zeros, deflated (about 1 MB per GiB)."""
    metadata = {"format": "mirror-avatar/cyber-player", "version": 1}
    chunk = bytes(2**20)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        archive.writestr("metadata.npy", npy(np.array(json.dumps(metadata))))
        for name, mebibytes in members.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                member.write(npy_header((mebibytes * 2**17,)))
                for _ in range(mebibytes):
                    member.write(chunk)
    return path


@pytest.fixture(scope="module")
def bombs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One member of 1 GiB; three members of 180 MiB each (540 MiB together)."""
    folder = tmp_path_factory.mktemp("bombs")
    return {
        "one member": write_bomb(folder / "one.npz", {"q_table": 1024}),
        "all members": write_bomb(
            folder / "all.npz", {"q_table": 180, "edges": 180, "actions": 180}
        ),
    }


@pytest.mark.parametrize("kind", ["generator", "cyber"])
@pytest.mark.parametrize(
    ("bomb", "fragment"),
    [
        ("one member", f"member q_table.npy declares {2**30 + len(npy_header((2**27,)))} "
                       f"bytes, more than the limit of {MAX_MEMBER_BYTES}"),
        ("all members", f"bytes in all, more than the limit of {MAX_TOTAL_BYTES}"),
    ],
)  # fmt: skip
def test_a_zip_bomb_is_refused_without_being_read(bombs, kind, bomb, fragment) -> None:
    assert bombs[bomb].stat().st_size < 5 * 2**20
    tracemalloc.start()
    try:
        refused(bombs[bomb], kind, fragment)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50 * 2**20


@pytest.mark.parametrize(("kind", "name"), [("generator", "codebook"), ("cyber", "q_table")])
@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        (npy_header((10**12,)) + bytes(8), "has a header claiming 8000000000000 bytes, more than "
                                           "the limit of 268435456"),
        (npy_header((100,)) + bytes(80), "has a header claiming 800 bytes of data but holds 80"),
        (npy_header((10,)) + bytes(800), "has a header claiming 80 bytes of data but holds 800"),
        (npy_header((-1,)) + bytes(8), "has a header claiming -8 bytes of data"),
        (npy(np.array([None], dtype=object)), "has dtype object; model arrays hold integers or "
                                              "floats"),
        (npy(np.zeros(3, dtype=[("a", "<f8")])), "has dtype [('a', '<f8')]"),
        (npy(np.array([1 + 1j])), "has dtype complex128"),
        (npy(np.array([True])), "has dtype bool"),
        (npy(np.array(["text"])), "has dtype <U4"),
        (b"\x93NUMPY\x03\x00" + bytes(20), "unsupported .npy version (3, 0)"),
        (b"not an npy member", "not a readable .npz model file"),
    ],
)  # fmt: skip
def test_member_headers_are_checked_before_their_data(files, kind, name, data, fragment) -> None:
    set_members(files[kind], {f"{name}.npy": data})
    refused(files[kind], kind, f"{name} {fragment}" if fragment.startswith("has") else fragment)


@pytest.mark.parametrize("kind", ["generator", "cyber"])
@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        (npy(np.array([1.0, 2.0])), "metadata is not one JSON string"),
        (npy(np.array(["{}", "{}"])), "metadata is not one JSON string"),
        (npy(np.array("{" + " " * MAX_METADATA_CHARS + "}")),
         "metadata of 1000002 characters is longer than the limit of 1000000"),
    ],
)  # fmt: skip
def test_a_metadata_member_that_is_not_one_short_string_is_refused(
    files, kind, data, fragment
) -> None:
    set_members(files[kind], {"metadata.npy": data})
    refused(files[kind], kind, fragment)


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_too_many_members_are_refused(files, kind) -> None:
    set_members(files[kind], {f"extra{i}.npy": npy(np.zeros(1)) for i in range(MAX_MEMBERS)})
    refused(files[kind], kind, f"members, more than the limit of {MAX_MEMBERS}")


def add_zip64_end(path: Path, directory_size: int | None = None) -> None:
    """Put a zip64 end record (declaring ``directory_size``, else the true size) and locator
    before the end record of the archive at ``path``."""
    data = path.read_bytes()
    at = data.rfind(b"PK\x05\x06")
    entries, size, offset = struct.unpack_from("<HLL", data, at + 10)
    declared = size if directory_size is None else directory_size
    record = struct.pack(
        "<4sQ2H2L4Q", b"PK\x06\x06", 44, 45, 45, 0, 0, entries, entries, declared, offset
    )
    locator = struct.pack("<4sLQL", b"PK\x06\x07", 0, at, 1)
    path.write_bytes(data[:at] + record + locator + data[at:])


def declare_directory(path: Path, size: int) -> None:
    """Make the end record of the archive at ``path`` declare a central directory of ``size``."""
    data = bytearray(path.read_bytes())
    struct.pack_into("<L", data, data.rfind(b"PK\x05\x06") + 12, size)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("kind", ["generator", "cyber"])
@pytest.mark.parametrize(
    "craft",
    [lambda p: declare_directory(p, 2**31), lambda p: add_zip64_end(p, 2**31)],
    ids=["end record", "zip64 end record"],
)
def test_a_huge_declared_directory_is_refused_before_listing(files, kind, craft) -> None:
    craft(files[kind])
    refused(files[kind], kind, f"declares 2147483648 bytes, more than the limit of "
                               f"{MAX_DIRECTORY_BYTES}")  # fmt: skip


def test_a_true_zip64_end_record_still_loads(files) -> None:
    add_zip64_end(files["generator"])
    assert IMSGenerator.load(files["generator"]).n_symbols == 4


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_members_neither_stored_nor_deflated_are_refused(files, kind) -> None:
    set_members(files[kind], {"extra.npy": npy(np.zeros(4))}, method=zipfile.ZIP_BZIP2)
    refused(
        files[kind], kind, "member extra.npy uses compression method 12, not stored or deflated"
    )


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_encrypted_members_are_refused(files, kind) -> None:
    data = bytearray(files[kind].read_bytes())
    data[data.find(b"PK\x01\x02") + 8] |= 0x1
    files[kind].write_bytes(bytes(data))
    refused(files[kind], kind, "member metadata.npy is encrypted")


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_members_other_than_arrays_are_refused(files, kind) -> None:
    set_members(files[kind], {"readme.txt": b"hello"})
    refused(files[kind], kind, "member readme.txt is not a .npy array")


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_duplicate_members_are_refused(files, kind) -> None:
    with zipfile.ZipFile(files[kind], "a") as archive, pytest.warns(UserWarning, match="Duplicate"):
        archive.writestr("metadata.npy", npy(np.array("{}")))
    refused(files[kind], kind, "member metadata appears more than once")


@pytest.mark.parametrize("kind", ["generator", "cyber", "reference"])
def test_deflated_models_still_load(files, kind) -> None:
    arrays, metadata = contents(files[kind])
    np.savez_compressed(files[kind], metadata=np.array(json.dumps(metadata)), **arrays)
    LOADERS[kind](files[kind])


# --- 3. the metadata JSON is bounded in length and depth -----------------------------------------


@pytest.mark.parametrize("kind", ["generator", "cyber"])
@pytest.mark.parametrize("brackets", ["[]", "{}"])
def test_deeply_nested_metadata_is_refused(files, kind, brackets) -> None:
    arrays, metadata = contents(files[kind])
    opening, closing = ('{"a":', "}") if brackets == "{}" else ("[", "]")
    deep = opening * 100_000 + "1" + closing * 100_000
    write(files[kind], arrays, json.dumps(metadata)[:-1] + f', "deep": {deep}}}')
    refused(files[kind], kind, f"metadata is JSON nested deeper than the limit of {MAX_DEPTH}")


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_metadata_at_the_depth_limit_and_brackets_in_strings_still_load(files, kind) -> None:
    arrays, metadata = contents(files[kind])
    deep = "[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1)
    text = json.dumps(metadata | {"note": "[{" * 10_000 + '\\"[['})[:-1] + f', "deep": {deep}}}'
    write(files[kind], arrays, text)
    LOADERS[kind](files[kind])


@pytest.mark.parametrize("kind", ["generator", "cyber"])
def test_metadata_longer_than_the_limit_is_refused(files, kind) -> None:
    arrays, metadata = contents(files[kind])
    write(files[kind], arrays, metadata | {"padding": "x" * MAX_METADATA_CHARS})
    refused(files[kind], kind, f"is longer than the limit of {MAX_METADATA_CHARS}")


# --- 4. integer arrays of another dtype ----------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "name", "array", "fragment"),
    [
        ("cyber", "edge_counts", np.array([9.0, 7.0, 5.0, 6.0]), "edge_counts has dtype float64, "
                                                                 "expected integers"),
        ("cyber", "edge_counts", np.array([9.5, 6.5, 5.0, 6.0]), "edge_counts has dtype float64"),
        ("cyber", "edge_counts", np.array([2**62, 2**62, 2**62, -(2**62)]), "edge_counts holds "
                                                                            "4611686018427387904"),
        ("cyber", "edge_counts", np.array([-1, 17, 5, 6]), "edge_counts holds -1; its values must "
                                                          "be finite and within 0..27"),
        ("cyber", "edge_counts", np.array([9, 7, 5, 7]), "edge_counts add up to 28, not the 27"),
        ("cyber", "actions", np.arange(-4, 5), "actions has dtype int64, expected floats"),
        ("cyber", "edges", np.arange(27), "edges has dtype int64, expected floats"),
        ("cyber", "q_table", np.zeros((3360, 9), dtype=np.int64), "q_table has dtype int64"),
        ("cyber", "target_counts", np.ones(DEFAULT_BINS.n, dtype=np.uint8), None),
        ("generator", "codebook", np.zeros((4, 8), dtype=np.int32), "codebook has dtype int32"),
        ("generator", "startprob", np.array([1, 0, 0, 0]), "startprob has dtype int64"),
        ("reference", "reference_transmat", np.eye(4, dtype=np.int16), "transmat has dtype int16"),
    ],
)  # fmt: skip
def test_arrays_of_another_dtype_are_refused(files, kind, name, array, fragment) -> None:
    set_array(files[kind], name, array)
    if fragment is None:
        LOADERS[kind](files[kind])
    else:
        refused(files[kind], kind, fragment)


# --- 5. anything else malformed is one short InputError line -------------------------------------


@pytest.mark.parametrize(
    ("kind", "keys", "value", "fragment"),
    [
        ("cyber", ("parameters",), [1, 2], "parameters must be a JSON object, not [1, 2]"),
        ("cyber", ("parameters",), None, "parameters must be a JSON object, not None"),
        ("generator", ("parameters",), "fast", "parameters must be a JSON object, not 'fast'"),
        ("reference", ("reference", "parameters"), 3, "parameters must be a JSON object, not 3"),
        ("cyber", ("training",), "x", "training must be a JSON object, not 'x'"),
        ("generator", ("training",), None, "training must be a JSON object, not None"),
        ("generator", ("training", "groups"), "fast", "training groups 'fast' are not a list"),
        ("reference", ("reference", "training", "groups"), [1], "training groups [1] are not a"),
        ("cyber", ("training", "role"), ["leader"], "training role ['leader'] is none of"),
        ("cyber", ("training", "role"), "coach", "training role 'coach' is none of follower, "
                                                  "leader, group"),
        ("cyber", ("training", "n_sessions"), "many", "n_sessions must be an integer, not 'many'"),
        ("cyber", ("training", "n_sessions"), -1, "n_sessions -1 is outside 0..1000000000"),
        ("cyber", ("discretisation",), None, "discretisation must be a JSON object, not None"),
        ("cyber", ("discretisation", "features"), "sideways", "features 'sideways' are not one "
                                                              "of absolute, relative, reference"),
        ("cyber", ("discretisation", "features"), ["relative"], "features ['relative'] are not"),
        ("reference", ("reference",), "gen", "reference features but no reference generator"),
        ("generator", ("format",), "x" * 10_000, "not a mirror-avatar/ims-generator file (format "
                                                 "'xxxxxxxxx"),
        ("cyber", ("version",), [1] * 10_000, "unsupported mirror-avatar/cyber-player version"),
    ],
)  # fmt: skip
def test_malformed_metadata_is_refused(files, kind, keys, value, fragment) -> None:
    set_value(files[kind], keys, value)
    message = refused(files[kind], kind, fragment)
    assert len(message) < len(str(files[kind])) + 120


@pytest.mark.parametrize(
    ("keys", "value", "fragment"),
    [
        (("network",), None, "network must be a JSON object, not None"),
        (("network", "hidden"), [], "network hidden must list 1 to 8 layer widths"),
        (("network", "hidden"), "100", "network hidden must list 1 to 8 layer widths"),
        (("network", "hidden"), [10**9], "hidden layer width 1000000000 is outside 1..1024"),
        (("network", "hidden"), [8, 2.5], "hidden layer width must be an integer, not 2.5"),
        (("network", "hidden"), [8, 5], "layer widths [10, 8, 4, 9] do not match [10, 8, 5, 9]"),
        (("network", "n_slots"), 10**6, "n_slots 1000000 is outside 0..32"),
        (("network", "n_slots"), 1, "layer widths [10, 8, 4, 9] do not match [7, 8, 4, 9]"),
        (("network", "use_reference"), "yes", "use_reference must be true or false"),
        (("network", "use_reference"), True, "do not match"),
        (("parameters", "n_substeps"), 1e9, "n_substeps 1000000000 is outside 1..64"),
        (("parameters", "omega"), float("nan"), "omega"),
        (("training", "n_sessions"), -1, "n_sessions -1 is outside 0..1000000000"),
    ],
)
def test_malformed_deep_metadata_is_refused(files, keys, value, fragment) -> None:
    set_value(files["deep"], keys, value)
    refused(files["deep"], "deep", fragment)


@pytest.mark.parametrize(
    ("name", "array", "fragment"),
    [
        ("weights", np.zeros(3), "weights has shape (3,), expected (169,)"),
        ("weights", np.full(169, np.nan), "weights holds nan; its values must be finite"),
        ("weights", np.zeros(169, dtype=np.int64), "weights has dtype int64, expected floats"),
        ("sizes", np.array([7, 8, 4, 9]), "layer widths [7, 8, 4, 9] do not match [10, 8, 4, 9]"),
        ("sizes", np.array([10, 8, 4, -9]), "sizes holds -9"),
        ("actions", np.array([1e9]), "actions holds 1000000000.0"),
        ("actions", np.array([1.0, 2.0]), "layer widths [10, 8, 4, 9] do not match [10, 8, 4, 2]"),
        ("target_counts", np.ones(3), "target_counts has shape (3,)"),
    ],
)
def test_deep_arrays_out_of_their_range_are_refused(files, name, array, fragment) -> None:
    set_array(files["deep"], name, array)
    refused(files["deep"], "deep", fragment)


def test_a_truncated_deep_file_is_refused(files) -> None:
    data = files["deep"].read_bytes()
    files["deep"].write_bytes(data[: len(data) // 2])
    refused(files["deep"], "deep", "")


@pytest.mark.parametrize("kind", ["generator", "cyber"])
@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("[1, 2]", "metadata is not a JSON object"),
        ('{"format": ' + "9" * 5000 + "}", "metadata is not valid JSON"),
        ("{not json", "metadata is not valid JSON"),
    ],
)
def test_metadata_that_is_no_json_object_is_refused(files, kind, text, fragment) -> None:
    arrays, _ = contents(files[kind])
    write(files[kind], arrays, text)
    refused(files[kind], kind, fragment)


# --- through the command line --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "keys", "value", "problem"),
    [
        ("cyber", ("parameters", "n_substeps"), 1e9, "n_substeps 1000000000 is outside 1..64"),
        ("generator", ("parameters", "rate"), 1e308, "rate: 1e+308 is not allowed; give a number"),
        ("reference", ("reference", "parameters", "rate"), 1e308, "rate: 1e+308 is not allowed"),
        ("deep", ("network", "hidden"), [10**9], "hidden layer width 1000000000 is outside"),
    ],
)
def test_the_cli_refuses_a_crafted_model_in_one_line(
    files, tmp_path, monkeypatch, capsys, kind, keys, value, problem
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    crafted = files[kind]
    set_value(crafted, keys, value)
    arguments = ["simulate", "--leader", str(crafted), "--follower", "bundled:slow",
                 "--duration", "2", "--out", str(tmp_path / "out")]  # fmt: skip
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.startswith(f"mirror-avatar: error: {crafted}: {problem}")
    assert error.count("\n") == 1 and error.endswith("\n")


@pytest.mark.parametrize("leader", ["cyber", "reference"])
def test_valid_models_still_load_and_play(files, tmp_path, leader) -> None:
    arguments = ["simulate", "--leader", str(files[leader]), "--follower", str(files["generator"]),
                 "--duration", "2", "--out", str(tmp_path / "out")]  # fmt: skip
    assert main(arguments) == 0
    assert (tmp_path / "out" / "metrics.json").is_file()
