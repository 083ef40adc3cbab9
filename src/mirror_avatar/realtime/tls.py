"""A server's own TLS certificate: its files checked before the server starts.

A server given a certificate and its private key (PEM files, as a certificate authority such as
Let's Encrypt issues them) serves HTTPS and secure WebSockets itself (uvicorn's ``ssl_certfile``
and ``ssl_keyfile``). `TlsFiles.check` reads both files and loads them as the server will, so
that a missing or unreadable file, a file that is not PEM, a key of another certificate or an
encrypted key is refused in one line naming the file and its option, before anything listens.
"""

from __future__ import annotations

import ssl
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.user_files import read_text

MAX_PEM_BYTES = 1 << 20
"""Largest certificate (chain) or key file read (bytes)."""

CERTIFICATE_MARK = "-----BEGIN CERTIFICATE-----"
"""The line a PEM certificate begins with."""

KEY_MARK = "PRIVATE KEY-----"
"""How a PEM private key's first line ends (``-----BEGIN [EC |RSA ]PRIVATE KEY-----``)."""


@dataclass(frozen=True)
class TlsFiles:
    """A server's certificate (chain) and its private key, PEM files.

    Parameters
    ----------
    certfile
        The certificate, followed by the intermediate certificates of its chain if any.
    keyfile
        Its private key, unencrypted (the server asks for no password).
    """

    certfile: Path
    keyfile: Path

    def check(self) -> None:
        """Read both files and load them as the server will.

        Raises
        ------
        InputError
            One line naming the file, the problem and the option (``--certfile``,
            ``--keyfile``): a missing, unreadable or oversized file, one that is not PEM, a key
            that is not the certificate's, or an encrypted key.
        """
        _pem(self.certfile, CERTIFICATE_MARK, "--certfile", "a PEM certificate")
        _pem(self.keyfile, KEY_MARK, "--keyfile", "a PEM private key")
        context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        try:
            context.load_cert_chain(self.certfile, self.keyfile, password=_no_password)
        except _Encrypted:
            raise InputError(
                self.keyfile,
                "the key is encrypted: give --keyfile an unencrypted copy (openssl pkey -in "
                "KEY -out PLAIN), readable by the server's user only",
            ) from None
        except ssl.SSLError as error:
            problem = (
                "is not the private key of the certificate in --certfile"
                if error.reason == "KEY_VALUES_MISMATCH"
                else f"cannot be loaded with the certificate in --certfile ({error.reason})"
            )
            raise InputError(self.keyfile, f"{problem}: give --keyfile that key") from None

    def uvicorn_options(self) -> dict[str, Any]:
        """Return uvicorn's settings serving with this certificate and key."""
        return {"ssl_certfile": str(self.certfile), "ssl_keyfile": str(self.keyfile)}


class _Encrypted(Exception):
    """The key file asked for a password."""


def _no_password() -> str:
    """Refuse to decrypt a key (the server runs unattended: it prompts for nothing)."""
    raise _Encrypted


def _pem(path: Path, mark: str, option: str, kind: str) -> None:
    """Check that ``path`` is a readable text file holding ``mark`` (one line on error)."""
    try:
        text = read_text(path, MAX_PEM_BYTES)
    except InputError as error:
        raise InputError(None, f"{error} (check {option})") from None
    if mark not in text:
        raise InputError(path, f"not {kind} (no '{mark}' line): check {option}")
