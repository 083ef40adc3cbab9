"""The lab server's public address: what the join links, their QR codes and the console use.

A server behind a reverse proxy (Caddy, nginx: the lab guide, Serving a study on the internet)
is reached by its participants at the proxy's address, ``https://study.example.org``, not at the
one it listens on. Given that address (``lab --public-url``), the join links are built on it;
without one, on the address the researcher's console reached the server by.
"""

from __future__ import annotations

from urllib.parse import urlsplit

from starlette.requests import HTTPConnection

from mirror_avatar.common.errors import InputError

OPTION = "--public-url"
"""The option that sets the public address."""


def parse_public_url(text: str) -> str:
    """Check a public address and return it without a trailing ``/``.

    Parameters
    ----------
    text
        ``http(s)://NAME[:PORT]``, the root of a site (the server serves at its root).

    Raises
    ------
    InputError
        ``--public-url: ...`` when it is not an http or https address of a host, or has a
        path, query, fragment or user name.
    """
    try:
        parts = urlsplit(text.strip())
        port_ok = parts.port is None or parts.port > 0
    except ValueError:
        parts, port_ok = urlsplit(""), False
    example = "e.g. https://study.example.org"
    if parts.scheme not in ("http", "https") or not parts.hostname or not port_ok:
        raise InputError(OPTION, f"{text!r} is not an http or https address of a host ({example})")
    if parts.path not in ("", "/") or parts.query or parts.fragment or "@" in parts.netloc:
        raise InputError(
            OPTION,
            f"{text!r}: give the site's root, with no path, query, fragment or user name "
            f"({example}); the server serves at the root of its address",
        )
    return f"{parts.scheme}://{parts.netloc}"


def base_address(public_url: str | None, request: HTTPConnection) -> str:
    """Return the address links are built on: the public one, else the request's own."""
    return public_url or str(request.base_url).rstrip("/")


def is_secure(public_url: str | None, request: HTTPConnection) -> bool:
    """Whether the page is served over TLS: by the server itself or at an https public address.

    Behind a reverse proxy on the same machine uvicorn takes the request's scheme from the
    proxy's ``X-Forwarded-Proto`` header; the public address decides for a proxy elsewhere.
    """
    return request.url.scheme in ("https", "wss") or (public_url or "").startswith("https:")
