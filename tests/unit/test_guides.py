"""The guides show what a new reader needs first, and the files they quote as they are."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).parents[2]


def test_the_lab_guide_shows_the_example_protocol_as_it_is():
    protocol = (ROOT / "examples" / "protocol.toml").read_text(encoding="utf-8")
    guide = (ROOT / "docs" / "lab.md").read_text(encoding="utf-8")
    assert f"```toml\n{protocol.rstrip()}\n```" in guide


def test_the_user_guide_defines_units_and_specs_before_the_first_command():
    guide = (ROOT / "docs" / "guide.md").read_text(encoding="utf-8")
    first_command = guide.index("## Command line")
    assert guide.index("60 cm of hand travel") < first_command
    assert guide.index("### SPECs") < first_command


def sections(lines: list[str]) -> list[tuple[str, int]]:
    """Return each Markdown heading with the number of prose lines under it (neither fenced
    code nor table rows)."""
    found: list[tuple[str, int]] = []
    fenced = False
    for line in lines:
        fence = line.startswith("```")
        fenced ^= fence
        if not fenced and line.startswith("#"):
            found.append((line, 0))
        elif found and not (fenced or fence or line.startswith("|")):
            found[-1] = (found[-1][0], found[-1][1] + 1)
    return found


def test_the_lab_guide_comes_in_short_sections():
    lines = (ROOT / "docs" / "lab.md").read_text(encoding="utf-8").splitlines()
    found = sections(lines)
    assert found[0][1] < 20, "the guide's introduction is short"
    assert max(length for _, length in found) <= 50, found
