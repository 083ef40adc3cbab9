"""A pilot's emulated internets: one before every person's page, or one per person.

``lab pilot --network SPEC`` puts every stand-in's page behind one emulated internet
(`mirror_avatar.remote.proxy.ProxyThread`, the spec read by
`mirror_avatar.remote.network.parse_network`), its truth in `NETWORK_LOG`;
``--network LABEL=SPEC`` puts person LABEL's page behind one of its own, its truth in
``pilot-network-LABEL.csv`` (`network_log`), so that people at home on different links are
piloted as they will join. Both may be given: the persons no ``LABEL=`` names are behind the
``SPEC`` one; without it, they join the server directly. Each log has its JSON companion
(`mirror_avatar.remote.truth.companion`): the network, its seed, the clock's anchor.

The internet before everyone is seeded with the pilot's seed; person ``j``'s own (``j`` their
index among the protocol's people) with ``spawn_seeds(seed, len(people))[j]``, so that no two
draw the same delays and none depends on which others have one.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from urllib.parse import urlsplit

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.remote.network import DIRECTIONS, Network, parse_network
from mirror_avatar.remote.proxy import ProxyThread
from mirror_avatar.remote.truth import companion

EVERYONE = ""
"""The key of the network before every person that no ``LABEL=SPEC`` names."""

NETWORK_LOG = "pilot-network.csv"
"""The truth log of the network before everyone in a pilot's output folder (its JSON companion
beside it: the network, the seed, the clock's anchor)."""

SPEC_KEYS = (*DIRECTIONS, "stall")
"""The words before a ``=`` that belong to a network spec, never a person's label."""


def parse_networks(
    values: Sequence[str], people: Sequence[str], option: str = "--network"
) -> dict[str, Network]:
    """Read ``--network`` options: ``SPEC`` (every person) or ``LABEL=SPEC`` (that person).

    A value is a person's when the text before its first ``=`` has no comma and is none of
    `SPEC_KEYS` (``up=40,down=120`` is one spec for everyone).

    Returns
    -------
    dict of str to Network
        The network per person's label, `EVERYONE`'s for the others.

    Raises
    ------
    InputError
        One line naming ``option``: a spec that cannot be read, a label that is no person of
        ``people``, a person or everyone given twice.
    """
    networks: dict[str, Network] = {}
    for value in values:
        key, sep, rest = value.partition("=")
        label = key.strip() if sep and "," not in key and key.strip() not in SPEC_KEYS else ""
        if label and label not in people:
            raise InputError(
                option, f"{value!r}: {label} is no person of the protocol (its people: "
                f"{', '.join(people)}); give SPEC or LABEL=SPEC",
            )  # fmt: skip
        if label in networks:
            whom = f"person {label}" if label else "every person (SPEC without LABEL=)"
            raise InputError(option, f"{value!r}: a second network for {whom}; give one")
        networks[label] = parse_network(rest if label else value, option)
    return networks


def network_log(label: str) -> str:
    """Return the truth log's name for the network of ``label`` (`EVERYONE`: `NETWORK_LOG`)."""
    return NETWORK_LOG if label == EVERYONE else f"pilot-network-{label}.csv"


def network_files(networks: Mapping[str, Network]) -> list[str]:
    """Return the files the networks write in the output folder: each log and its companion."""
    logs = [network_log(label) for label in networks]
    return [name for log in logs for name in (log, companion(Path(log)).name)]


def describe(networks: Mapping[str, Network]) -> str:
    """Return the networks in a few words, with where their truth is written."""
    if set(networks) == {EVERYONE}:
        return f"network {networks[EVERYONE]}, its truth in {NETWORK_LOG}"
    return "networks " + ", ".join(
        f"{label or 'everyone else'} {network} (truth in {network_log(label)})"
        for label, network in networks.items()
    )


@contextlib.contextmanager
def emulated_internets(
    networks: Mapping[str, Network],
    base: str,
    out_dir: Path,
    seed: int,
    people: Sequence[str],
) -> Iterator[dict[str, str]]:
    """Yield the base URL each person's page joins at, for as long as the block runs.

    That is the address of the person's own emulated internet to the server at ``base``, or
    else of the one before everyone, or else ``base`` itself; each proxy writes its truth in
    ``out_dir`` (`network_log`) and is seeded as the module's docstring says.
    """
    server = urlsplit(base)
    assert server.hostname is not None and server.port is not None
    target = (server.hostname, server.port)
    seeds = spawn_seeds(seed, len(people))
    with contextlib.ExitStack() as stack:
        urls = {
            label: stack.enter_context(
                ProxyThread(
                    network,
                    target,
                    out_dir / network_log(label),
                    seed if label == EVERYONE else int(seeds[people.index(label)]),
                )
            ).url
            for label, network in networks.items()
        }
        yield {label: urls.get(label, urls.get(EVERYONE, base)) for label in people}
