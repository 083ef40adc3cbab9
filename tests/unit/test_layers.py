"""The import-cycle counter of `benchmarks/import_cycles.py`, on a made-up package and on ours."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parents[2] / "benchmarks" / "import_cycles.py"
spec = importlib.util.spec_from_file_location("import_cycles", SCRIPT)
assert spec is not None and spec.loader is not None
import_cycles = importlib.util.module_from_spec(spec)
spec.loader.exec_module(import_cycles)


def write_package(root: Path, files: dict[str, str]) -> Path:
    package = root / "mirror_avatar"
    for name, text in {"__init__.py": "__version__ = '0'\n", **files}.items():
        path = package / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return package


def test_function_level_and_type_checking_imports_close_cycles(tmp_path):
    package = write_package(
        tmp_path,
        {
            "low.py": "def f():\n    from mirror_avatar.high import g\n",
            "high/__init__.py": "",
            "high/core.py": (
                "from typing import TYPE_CHECKING\n"
                "from .. import low\n"
                "if TYPE_CHECKING:\n    from mirror_avatar.other import h\n"
            ),
            "other.py": "from mirror_avatar import __version__, low\n",
            "alone.py": "import mirror_avatar.low\n",
        },
    )
    edges = import_cycles.part_edges(package)
    assert set(edges) == {
        ("low", "high"), ("high", "low"), ("high", "other"), ("other", "low"), ("alone", "low")
    }  # fmt: skip
    assert edges[("low", "high")] == ["low.py"]
    assert import_cycles.cycles(edges) == [["high", "low", "other"]]


def test_relative_imports_resolve_inside_subpackages(tmp_path):
    package = write_package(
        tmp_path,
        {"a/__init__.py": "from .b import x\n", "a/b.py": "from ..c import y\n", "c.py": ""},
    )
    assert set(import_cycles.part_edges(package)) == {("a", "c")}


def test_the_package_has_no_import_cycle():
    """The script in a fresh interpreter, as `make lint` would run it.

    In a test worker, an earlier failed AST construction (an interrupted or too deep parse by
    another test) can leave CPython 3.11.7's AST recursion counter off, and ``ast.parse`` then
    raises ``SystemError: AST constructor recursion depth mismatch`` (CPython gh-106905, fixed
    in 3.11.8): the package's imports are read where no other test has parsed anything.
    """
    done = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "0 cycle(s)" in done.stdout
