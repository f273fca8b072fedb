"""Which addresses the 3D view's web server listens on: loopback only unless asked for more.

By default the page, its status endpoint and the scene websocket answer on 127.0.0.1 and, where
the machine has IPv6, ::1: nobody else on the network can watch a run. ``--host ADDRESS``
(``wristmark view``, ``experiment --view``, ``servo --view``) adds one address, e.g. 0.0.0.0 for
every IPv4 interface; the loopback addresses stay served so that the printed
``http://127.0.0.1:PORT/...`` URL keeps working. ZMQ (the scene commands) is always on 127.0.0.1.
"""

from __future__ import annotations

import argparse
import ipaddress

LOOPBACK_V4 = "127.0.0.1"
LOOPBACK_V6 = "::1"
WILDCARDS = {"0.0.0.0": "every IPv4 interface", "::": "every IPv6 interface"}


def listen_addresses(host: str | None = None) -> tuple[list[str], list[str]]:
    """Addresses to bind for ``host`` (None: loopback only): (required, optional). Optional
    ones (IPv6 loopback) are skipped where the machine cannot bind them."""
    if host is None or host in (LOOPBACK_V4, "localhost"):
        return [LOOPBACK_V4], [LOOPBACK_V6]
    if host == LOOPBACK_V6:
        return [LOOPBACK_V4, LOOPBACK_V6], []
    if host == "0.0.0.0":  # covers 127.0.0.1 (binding both would collide)
        return [host], [LOOPBACK_V6]
    if host == "::":  # tornado binds IPv6 sockets v6-only
        return [host, LOOPBACK_V4], []
    return [host, LOOPBACK_V4], [LOOPBACK_V6]


def exposure_notice(host: str | None, port: int) -> str | None:
    """The stderr line saying who else can reach the view (None for loopback only)."""
    required, _ = listen_addresses(host)
    extra = [h for h in required if h not in (LOOPBACK_V4, LOOPBACK_V6)]
    if not extra:
        return None
    h = extra[0]
    where = WILDCARDS.get(h, "that address")
    shown = f"[{h}]" if ":" in h else h
    return (f"wristmark: the 3D view also listens on {shown}:{port} ({where}, --host): anyone who can reach "
            "this machine there can watch the run")


def host_address(text: str) -> str:
    """argparse type of ``--host``: an IP address (or ``localhost``)."""
    if text == "localhost":
        return text
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"'{text}' is not an IP address (e.g. 127.0.0.1, the default, or 0.0.0.0 for every interface)"
        ) from None

