"""Count import cycles between the package's first-level parts.

A first-level part is a subpackage or a top module of ``src/mirror_avatar``. Every import
statement counts, wherever it stands: module level, inside a function, or under
``if TYPE_CHECKING``. The parts that import each other, directly or through others, form
strongly connected components; a component of more than one part is a cycle.

Run ``python benchmarks/import_cycles.py`` (``--edges`` also prints every arrow between parts
with the file that draws it; ``--root`` names another copy of the package, e.g. an older commit's
``git archive``). The exit code is the number of parts caught in cycles, so the
script fails when any cycle exists.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from pathlib import Path

PACKAGE = "mirror_avatar"
ROOT = Path(__file__).resolve().parents[1] / "src" / PACKAGE


def part_of(module: str) -> str | None:
    """Return the first-level part a dotted module name belongs to, or None if outside."""
    pieces = module.split(".")
    if pieces[0] != PACKAGE or len(pieces) < 2:
        return None
    return pieces[1]


def is_part(root: Path, name: str) -> bool:
    """Tell whether ``name`` is a first-level part of the package at ``root``."""
    return (root / name / "__init__.py").is_file() or (root / f"{name}.py").is_file()


def module_name(root: Path, path: Path) -> str:
    """Return the dotted name of a source file of the package at ``root``."""
    relative = path.relative_to(root.parent).with_suffix("")
    pieces = list(relative.parts)
    if pieces[-1] == "__init__":
        pieces.pop()
    return ".".join(pieces)


def imported_modules(root: Path, path: Path) -> list[str]:
    """Return every module a file imports (absolute names), at any depth of its syntax tree."""
    name = module_name(root, path)
    is_package = path.name == "__init__.py"
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                drop = node.level - 1 if is_package else node.level
                base = base[: len(base) - drop] if drop else base
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append(target)
            # ``from mirror_avatar import deep`` names a part in the alias, not the module
            # (``from mirror_avatar import __version__`` names no part).
            if target == PACKAGE:
                found.extend(
                    f"{PACKAGE}.{alias.name}" for alias in node.names if is_part(root, alias.name)
                )
    return found


def part_edges(root: Path = ROOT) -> dict[tuple[str, str], list[str]]:
    """Return the arrows between first-level parts, each with the files that draw it."""
    edges: dict[tuple[str, str], list[str]] = defaultdict(list)
    for path in sorted(root.rglob("*.py")):
        source = part_of(module_name(root, path))
        if source is None:
            continue
        for target_module in imported_modules(root, path):
            target = part_of(target_module)
            if target is None or target == source:
                continue
            where = str(path.relative_to(root))
            if where not in edges[(source, target)]:
                edges[(source, target)].append(where)
    return dict(edges)


def cycles(edges: dict[tuple[str, str], list[str]]) -> list[list[str]]:
    """Return the strongly connected components of more than one part (Tarjan's algorithm)."""
    graph: dict[str, set[str]] = defaultdict(set)
    for source, target in edges:
        graph[source].add(target)
        graph.setdefault(target, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return components


def main() -> int:
    """Print the cycles (and optionally every arrow) and return the number of parts in cycles."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--edges", action="store_true", help="print every arrow between parts")
    parser.add_argument(
        "--root", type=Path, default=ROOT, help="the package's folder (default: this tree's)"
    )
    arguments = parser.parse_args()
    edges = part_edges(arguments.root.resolve())
    if arguments.edges:
        for (source, target), files in sorted(edges.items()):
            print(f"{source} -> {target}: {', '.join(files)}")
    found = cycles(edges)
    for component in found:
        print(f"cycle of {len(component)} parts: {', '.join(component)}")
    in_cycles = sum(len(component) for component in found)
    print(f"{len(found)} cycle(s), {in_cycles} part(s) in cycles")
    return in_cycles


if __name__ == "__main__":
    sys.exit(min(main(), 125))
