"""Control characters in text from users: found in names, shown escaped on a terminal.

A control character (Unicode's category Cc: C0, DEL and C1, among them the tab, the line breaks
and the escape that starts an ANSI sequence) has no place in a name, where it would split a
table's row or a line of output, and would act, not show, when printed to a terminal.
"""

from __future__ import annotations

import re

CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")
"""A control character (Unicode category Cc)."""


def escaped(character: str) -> str:
    r"""Return a character as Python writes it in a string literal (``\t``, ``\x1b``)."""
    return repr(character)[1:-1]


def first_control(text: str) -> str | None:
    """Return the first control character of ``text`` escaped (`escaped`), None if it has none."""
    found = CONTROL.search(text)
    return None if found is None else escaped(found.group())


def printable(text: str) -> str:
    """Return ``text`` with each control character escaped (`escaped`), to print it as it is."""
    return CONTROL.sub(lambda found: escaped(found.group()), text)
