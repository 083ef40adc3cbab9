"""Run every benchmark module (``benchmarks/bench_*.py``) and write one Markdown results file.

Each module defines ``run(quick: bool) -> list[dict]``; each dict is one measured row with at
least ``name`` and ``value`` keys (plus ``unit``, ``baseline``, ``ratio``, ``peak_memory_mb``,
``note`` where they apply). Speeds are reported as ratios against a baseline measured in the same
run, next to the machine's conditions.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import re
import sys
import time
from pathlib import Path

HERE = Path(__file__).parent
COLUMNS = ("name", "value", "unit", "baseline", "ratio", "peak_memory_mb", "note")


def machine() -> str:
    """One line describing the machine and its load."""
    load = os.getloadavg()
    return (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"{platform.platform()}, load average {load[0]:.2f}/{load[1]:.2f}/{load[2]:.2f}"
    )


def load(path: Path):  # noqa: ANN201 - a module object
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while it loads
    spec.loader.exec_module(module)
    return module


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=HERE / "results.md")
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke test")
    parser.add_argument("only", nargs="*", help="benchmark module names (default: all)")
    args = parser.parse_args()
    measured: dict[str, str] = {}
    for path in sorted(HERE.glob("bench_*.py")):
        if args.only and path.stem.removeprefix("bench_") not in args.only:
            continue
        print(f"running {path.stem} ...", file=sys.stderr, flush=True)
        rows = load(path).run(quick=args.quick)
        name = path.stem.removeprefix("bench_")
        lines = [f"## {name}\n",
                 f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {machine()}\n",
                 "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]  # fmt: skip
        lines += ["| " + " | ".join(_cell(row.get(c, "")) for c in COLUMNS) + " |" for row in rows]
        measured[name] = "\n".join(lines) + "\n"
    old = args.out.read_text(encoding="utf-8") if args.out.is_file() else "# Benchmark results\n"
    text = merge_sections(old, measured)
    args.out.write_text(text, encoding="utf-8")
    print("".join(measured.values()))
    return 0


def merge_sections(text: str, measured: dict[str, str]) -> str:
    """Put each measured section in place of the table of its ``## name`` section of ``text``.

    A measured section replaces its section up to the section's first ``### `` subsection (the
    studies measured with their own scripts, written by hand, stay), or up to the next ``## ``
    heading; every section not measured this time stays as it is. Sections new to the file are
    appended.
    """
    blocks = re.split(r"(?m)^(?=## )", text)
    merged, seen = [], set()
    for block in blocks:
        name = block.split("\n", 1)[0].removeprefix("## ").strip()
        if not block.startswith("## ") or name not in measured:
            merged.append(block)
            continue
        seen.add(name)
        kept = re.split(r"(?m)^(?=### )", block, maxsplit=1)[1:]
        merged.append(measured[name] + "\n" + "".join(kept))
    merged += ["\n" + section for name, section in measured.items() if name not in seen]
    return "".join(merged)


def _cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


if __name__ == "__main__":
    sys.exit(main())
