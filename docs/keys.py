"""Write the lab guide's tables of protocol keys from their declarations (``make docs-tables``).

Each table sits in docs/lab.md between ``<!-- keys: NAME -->`` and ``<!-- end keys -->``, NAME
one of `mirror_avatar.lab.design.protocol_keys.TABLES`; tests/unit/test_lab_protocol.py checks that
the guide holds them as declared.
"""

from __future__ import annotations

import re
from pathlib import Path

from mirror_avatar.lab.design.protocol_keys import key_tables

GUIDE = Path(__file__).with_name("lab.md")
MARKED = re.compile(r"(<!-- keys: (\w+) -->\n).*?(<!-- end keys -->)", re.DOTALL)


def with_tables(text: str) -> str:
    """Return the guide's text with each marked table written from its declarations."""
    tables = key_tables()
    return MARKED.sub(lambda m: m.group(1) + tables[m.group(2)] + m.group(3), text)


if __name__ == "__main__":
    GUIDE.write_text(with_tables(GUIDE.read_text(encoding="utf-8")), encoding="utf-8")
