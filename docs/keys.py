"""Write the documents' tables of declared keys from their declarations (``make docs-tables``).

Each table sits between ``<!-- keys: NAME -->`` and ``<!-- end keys -->``: in docs/lab.md the
protocol's tables, NAME one of `mirror_avatar.lab.design.protocol_keys.TABLES`; in
docs/METHODS.md the IMS generator's hyper-parameters, NAME ``generator``
(`mirror_avatar.motion.hyperparameters.GENERATOR_SETTINGS`). tests/unit/test_lab_protocol.py and
tests/unit/test_generator_hyperparameters.py check that the documents hold them as declared.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from mirror_avatar.common.constraints import settings_table
from mirror_avatar.lab.design.protocol_keys import key_tables
from mirror_avatar.motion.hyperparameters import GENERATOR_SETTINGS

DOCS = Path(__file__).parent
MARKED = re.compile(r"(<!-- keys: (\w+) -->\n).*?(<!-- end keys -->)", re.DOTALL)


def generator_tables() -> dict[str, str]:
    """Return the IMS generator's hyper-parameters as a Markdown table, by table name."""
    return {"generator": settings_table(GENERATOR_SETTINGS)}


PAGES: dict[str, Callable[[], dict[str, str]]] = {
    "lab.md": key_tables,
    "METHODS.md": generator_tables,
}
"""Each document with tables, and what writes them."""


def with_tables(text: str, tables: dict[str, str]) -> str:
    """Return a document's text with each marked table written from its declarations."""
    return MARKED.sub(lambda m: m.group(1) + tables[m.group(2)] + m.group(3), text)


if __name__ == "__main__":
    for name, tables in PAGES.items():
        page = DOCS / name
        page.write_text(with_tables(page.read_text(encoding="utf-8"), tables()), encoding="utf-8")
