"""Every section of the README or the documents that the code or the README names exists.

`make docs` checks the links between the documents' pages; this checks what it does not see:
the README's links into docs/, and the sections the package's docstrings and help name in
words (README "Title", the lab guide, Title; METHODS section N) or by address (docs/lab.md#anchor).
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import pytest
from markdown.extensions.toc import slugify

ROOT = Path(__file__).parents[2]
GUIDES = {"user": "docs/guide.md", "lab": "docs/lab.md"}


@cache
def headings(path: Path) -> list[str]:
    """The headings of a Markdown file (outside code blocks), as written."""
    text = re.sub(r"(?ms)^```.*?^```", "", path.read_text(encoding="utf-8"))
    return [found.strip() for found in re.findall(r"(?m)^#{1,6} (.+)$", text)]


@cache
def anchors(path: Path) -> set[str]:
    return {slugify(heading, "-") for heading in headings(path)}


def source_texts() -> list[tuple[str, str]]:
    """Each module of the package with its text, whitespace runs made single spaces."""
    return [
        (str(path.relative_to(ROOT)), " ".join(path.read_text(encoding="utf-8").split()))
        for path in sorted((ROOT / "src" / "mirror_avatar").rglob("*.py"))
    ]


def references() -> list[tuple[str, str, str]]:
    """(where, what kind, reference) for every named section in the package and the README."""
    found = []
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    for where, text in [*source_texts(), ("README.md", readme)]:
        for title in re.findall(r"README [\"']([^\"']+)[\"']", text):
            found.append((where, "README", title))
        for number in re.findall(r"METHODS(?:\.md)?,? (?:section )?(\d+)\b", text):
            found.append((where, "METHODS", number))
        for guide, title in re.findall(
            r"\b([Uu]ser|[Ll]ab) guide, ([A-Z][a-z]+(?: [a-z]+)*)", text
        ):
            found.append((where, GUIDES[guide.lower()], title))
        for address in re.findall(r"((?:docs/)?[A-Za-z_]+\.md#[a-z0-9-]+)", text):
            if where == "README.md" and not address.startswith("docs/"):
                continue
            found.append((where, "address", address))
    return found


def resolves(kind: str, reference: str) -> bool:
    if kind == "README":
        return reference in headings(ROOT / "README.md")
    if kind == "METHODS":
        return any(h.startswith(f"{reference}. ") for h in headings(ROOT / "docs/METHODS.md"))
    if kind == "address":
        name, anchor = reference.split("#")
        path = ROOT / "docs" / name.removeprefix("docs/")
        return path.is_file() and anchor in anchors(path)
    return reference in headings(ROOT / kind)


def test_references_are_found():
    kinds = {kind for _, kind, _ in references()}
    assert {"METHODS", "address", "docs/guide.md", "docs/lab.md"} <= kinds


@pytest.mark.parametrize(("where", "kind", "reference"), references())
def test_each_named_section_exists(where, kind, reference):
    assert resolves(kind, reference), f"{where}: {kind} {reference!r} names no section"
