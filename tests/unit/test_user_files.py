"""The one way user files are opened and user JSON and TOML parsed (`files.user_files`)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.user_files import (
    FLOAT_DIGITS,
    MAX_DEPTH,
    MAX_PART_BYTES,
    check_path,
    nesting_depth,
    open_regular,
    parse_json,
    parse_toml,
    read_bytes,
    read_json,
    read_text,
)


def test_a_regular_file_is_read_whole_within_its_limit(tmp_path: Path) -> None:
    path = tmp_path / "a.txt"
    path.write_bytes(b"\xef\xbb\xbfhello")
    assert read_bytes(path, 8) == b"\xef\xbb\xbfhello"
    assert read_text(path, 8) == "hello"
    with pytest.raises(InputError, match=r"a.txt: 8 bytes, over the limit of 7 bytes"):
        read_bytes(path, 7)


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"pipe.csv: is a named pipe \(FIFO\), not a regular"):
        open_regular(fifo, 100)


@pytest.mark.parametrize(
    ("path", "problem"),
    [
        ("/dev/null", "is a character device"),
        ("/", "is a folder"),
        ("/no/such/file.csv", "no such file"),
    ],
)
def test_what_is_not_a_readable_regular_file_is_one_line(path: str, problem: str) -> None:
    with pytest.raises(InputError, match=problem):
        read_bytes(path, 100)


def test_paths_no_system_can_open_are_named_without_their_nul(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"a\\0b.csv: the path holds a NUL byte"):
        check_path("a\0b.csv")
    part = "é" * (MAX_PART_BYTES // 2 + 1)  # two bytes each in UTF-8
    with pytest.raises(InputError, match=f"a part of the path is {2 * len(part)} bytes"):
        check_path(tmp_path / part / "x.csv")
    assert check_path(tmp_path / ("a" * MAX_PART_BYTES)) == tmp_path / ("a" * MAX_PART_BYTES)


def test_json_at_the_depth_limit_and_brackets_in_strings_are_read() -> None:
    deep = "[" * MAX_DEPTH + "]" * MAX_DEPTH
    text = json.dumps({"note": '[{"\\'})[:-1] + f', "deep": {deep[1:-1]}}}'
    assert parse_json(text, "f.json")["note"] == '[{"\\'
    with pytest.raises(InputError, match=f"f.json: is JSON nested deeper than the limit of "
                                         f"{MAX_DEPTH}"):  # fmt: skip
        parse_json("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), "f.json")


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ('{"a": NaN}', "NaN is not a JSON number"),
        ('{"a": -Infinity}', "-Infinity is not a JSON number"),
        ('{"a": 1e400}', "the number 1e400 is beyond the range of float64"),
        ('{"a": ' + "9" * (FLOAT_DIGITS + 1) + "}", "is beyond the range of float64"),
        ("{a}", "not valid JSON (Expecting property name"),
        (b"\xff{}", "not UTF-8"),
    ],
)
def test_json_numbers_outside_float64_and_non_json_are_refused(
    text: str | bytes, problem: str
) -> None:
    with pytest.raises(InputError, match=problem.replace("(", r"\(")):
        parse_json(text, "f.json", "the sidecar")


def test_numbers_left_to_a_checking_reader_are_kept_when_asked() -> None:
    value = parse_json('{"a": NaN, "b": 1e400, "c": ' + "9" * 400 + "}", "m.npz", finite=False)
    assert value["b"] == float("inf") and value["c"] == int("9" * 400)


def test_read_json_reads_a_file_within_its_limit(tmp_path: Path) -> None:
    path = tmp_path / "s.json"
    path.write_text('{"a": [1, 2.5]}')
    assert read_json(path, 100) == {"a": [1, 2.5]}
    with pytest.raises(InputError, match="over the limit"):
        read_json(path, 5)


@pytest.mark.parametrize(
    "text",
    [
        "label = {" + ".".join(["k"] * 3000) + " = 1}",
        "[" + ".".join(["t"] * (MAX_DEPTH + 1)) + "]",
        "x = " + "{a = " * 3000 + "1" + "}" * 3000,
        "x = " + "[" * 60_000 + "]" * 60_000,
    ],
    ids=["dotted keys in an inline table", "a table header", "inline tables", "arrays"],
)
def test_toml_nested_deeper_than_the_limit_is_refused_in_one_line(text: str) -> None:
    with pytest.raises(InputError, match=f"^p.toml: is TOML nested deeper than the limit of "
                                         f"{MAX_DEPTH} levels$"):  # fmt: skip
        parse_toml(text, "p.toml")


def test_toml_at_the_depth_limit_is_read() -> None:
    keys = ".".join(["k"] * (MAX_DEPTH - 1))
    assert nesting_depth(parse_toml(f"{keys} = [1]", "p.toml")) == MAX_DEPTH
    with pytest.raises(InputError, match="p.toml: not valid TOML: "):
        parse_toml("x = [", "p.toml")
