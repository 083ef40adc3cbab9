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
    lines = [
        f"# Benchmark results\n\n{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
        f"{machine()}\n"
    ]
    for path in sorted(HERE.glob("bench_*.py")):
        if args.only and path.stem.removeprefix("bench_") not in args.only:
            continue
        print(f"running {path.stem} ...", file=sys.stderr, flush=True)
        rows = load(path).run(quick=args.quick)
        lines.append(f"\n## {path.stem.removeprefix('bench_')}\n")
        lines.append("| " + " | ".join(COLUMNS) + " |")
        lines.append("|" + "---|" * len(COLUMNS))
        for row in rows:
            lines.append("| " + " | ".join(_cell(row.get(c, "")) for c in COLUMNS) + " |")
    text = "\n".join(lines) + "\n"
    args.out.write_text(text)
    print(text)
    return 0


def _cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


if __name__ == "__main__":
    sys.exit(main())
