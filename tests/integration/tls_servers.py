"""What the TLS tests share: the certificates they make for themselves (``cryptography``: an
authority, a certificate it signs, or one that signs itself, for names and addresses of this
machine), and a free port for a server whose public address is known before it starts."""

from __future__ import annotations

import datetime
import ipaddress
import socket
from collections.abc import Sequence
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

Key = ec.EllipticCurvePrivateKey


def new_key() -> Key:
    """A new P-256 private key."""
    return ec.generate_private_key(ec.SECP256R1())


def certificate(
    subject: str,
    key: Key,
    issuer: x509.Certificate | None,
    signer: Key,
    names: Sequence[str] = (),
) -> bytes:
    """A PEM certificate of ``key`` for ``subject``, self-signed when ``issuer`` is None.

    ``names`` are its subject alternative names: host names, or IP addresses (a client checks
    the address it connected to against them).
    """
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)])
    now = datetime.datetime.now(datetime.UTC)
    builder = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name if issuer is None else issuer.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(hours=1))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(x509.BasicConstraints(ca=issuer is None, path_length=None), critical=True)
    )
    if names:
        builder = builder.add_extension(
            x509.SubjectAlternativeName([_general_name(n) for n in names]), critical=False
        )
    return builder.sign(signer, hashes.SHA256()).public_bytes(serialization.Encoding.PEM)


def _general_name(name: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(name))
    except ValueError:
        return x509.DNSName(name)


def write_key(key: Key, path: Path) -> None:
    """Write ``key`` unencrypted (PKCS #8 PEM), readable by its owner only."""
    path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    path.chmod(0o600)


def self_signed(
    folder: Path, names: Sequence[str] = ("localhost", "127.0.0.1")
) -> tuple[Path, Path]:
    """Write a self-signed certificate for ``names`` and its key into ``folder``; return both."""
    key = new_key()
    cert, key_file = folder / "server.crt", folder / "server.key"
    cert.write_bytes(certificate(names[0], key, None, key, names))
    write_key(key, key_file)
    return cert, key_file


def free_port() -> int:
    """A loopback port no one listens on now (the server binds it next)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])
