"""Protocols loaded from the console: validated, kept under ``OUT/protocols/`` and run from there.

The console sends a protocol's TOML text with the name of the file the researcher chose
(`store_protocol`). It is validated as a ``--protocol`` file is
(`mirror_avatar.lab.design.protocol`), every mistake refused with one line naming the chosen file,
and a copy is kept as
``OUT/protocols/<name>.toml``, ``<name>`` being the chosen file's stem in Unicode's composed
form (NFC) with every run of characters other than letters, digits (of any script: ``études``,
``протокол``), ``-`` and ``_`` made one ``-`` - so no path separator, dot or control character
stays -, cut to `MAX_NAME_CHARS` characters and `MAX_NAME_BYTES` bytes of UTF-8. The copy is the
protocol's source: participants' folders are named after its stem
(`mirror_avatar.lab.running.study.study_folder`), so a server restarted with ``--protocol
OUT/protocols/<name>.toml`` resumes the same folders.

**Choice**: a protocol without a ``seed`` gets the seed drawn for it written as the copy's first
line (`SEED_LINE`), so that the copy replays the same order and partners after a restart.

**Choice**: a copy is never replaced. Loading a different protocol under a name already kept is
refused (rename the file); loading the same text again (also a text whose copy received a
drawn seed) uses the copy, its seed included.

Avatar specs inside the protocol are resolved as any spec (`mirror_avatar.specs`): a relative
path is relative to the server's working directory, as for a ``--protocol`` file, so the
copy resolves them the same way after a restart from the same directory.
"""

from __future__ import annotations

import re
import unicodedata
from dataclasses import replace
from pathlib import Path, PurePosixPath

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_text
from mirror_avatar.files.user_files import read_text
from mirror_avatar.lab.design.protocol import (
    MAX_PROTOCOL_BYTES,
    Protocol,
    protocol_from_text,
)

PROTOCOLS_FOLDER = "protocols"
"""The folder of OUT holding the protocols loaded from the console."""

SEED_LINE = "seed = {seed}  # drawn when the protocol was loaded from the console\n"
"""The first line of a kept copy whose protocol had no seed."""

DRAWN_SEED = re.compile(r"seed = \d+  # drawn when the protocol was loaded from the console\n")
"""`SEED_LINE` with any seed."""

MAX_NAME_CHARS = 64
"""Longest name of a kept protocol (characters)."""

MAX_NAME_BYTES = 200
"""Longest name of a kept protocol in UTF-8 (bytes): with ``.toml`` or a participant's
``-p003``, within the 255 bytes a file name may have."""

NOT_NAME = re.compile(r"[^\w-]+")
"""Runs of characters a kept protocol's name does not hold: all but letters and digits of any
script, ``_`` and ``-``."""


def file_part(file_name: str) -> str:
    """Return the last part of a file name given by a browser (no folder, at most 255 chars)."""
    return file_name.replace("\\", "/").rsplit("/", 1)[-1][:255]


def protocol_name(file_name: str) -> str:
    """Return the name a protocol chosen as ``file_name`` is kept under (see the module).

    Raises
    ------
    InputError
        A name with no letter or digit.
    """
    part = file_part(file_name)
    stem = unicodedata.normalize("NFC", PurePosixPath(part).stem)
    name = NOT_NAME.sub("-", stem).strip("-_")[:MAX_NAME_CHARS]
    while len(name.encode("utf-8")) > MAX_NAME_BYTES:
        name = name[:-1]
    name = name.rstrip("-_")
    if not name:
        problem = "the file name has no letters or digits (rename it, e.g. study.toml)"
        raise InputError(part or "protocol", problem)
    return name


def store_protocol(out_dir: Path, file_name: str, text: str) -> Protocol:
    """Validate a protocol's text, keep its copy in ``out_dir/protocols`` and return it.

    Parameters
    ----------
    out_dir
        The lab's output folder.
    file_name
        The name of the file the researcher chose (errors name it).
    text
        The file's TOML text (at most `MAX_PROTOCOL_BYTES` as UTF-8).

    Returns
    -------
    Protocol
        The protocol, its source the kept copy.

    Raises
    ------
    InputError
        One line naming the chosen file: too long, not TOML, the first mistake in the protocol,
        or another protocol kept under that name.
    """
    shown = file_part(file_name) or "protocol"
    if len(text.encode("utf-8")) > MAX_PROTOCOL_BYTES:
        raise InputError(shown, f"the protocol is over {MAX_PROTOCOL_BYTES} bytes (shorten it)")
    protocol = protocol_from_text(text, shown)
    copy = out_dir / PROTOCOLS_FOLDER / f"{protocol_name(file_name)}.toml"
    if copy.exists():
        kept = read_text(copy, MAX_PROTOCOL_BYTES + len(SEED_LINE) + 20)
        if not same_protocol(kept, text):
            raise InputError(
                shown,
                f"{copy} holds another protocol of that name (rename the file, or load that one)",
            )
        return protocol_from_text(kept, str(copy))
    kept = SEED_LINE.format(seed=protocol.seed) + text if protocol.seed_drawn else text
    copy.parent.mkdir(parents=True, exist_ok=True)
    write_atomic_text(copy, kept)
    return replace(protocol, source=str(copy))


def same_protocol(kept: str, text: str) -> bool:
    """Whether a kept copy holds ``text``, as given or after its drawn `SEED_LINE`."""
    if kept == text:
        return True
    head = kept[: len(kept) - len(text)]
    return kept.endswith(text) and DRAWN_SEED.fullmatch(head) is not None
