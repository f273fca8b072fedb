"""The DDS configuration of wristmark's ROS 2 participants: loopback only unless the user says
otherwise. When ``CYCLONEDDS_URI`` is unset (or empty), :func:`ensure_loopback` sets it, before
the first participant, to :data:`LOOPBACK_CONFIG`: the loopback interface, no multicast, the
only peer 127.0.0.1 (ports by participant index), so that nothing leaves the host. A user's own
``CYCLONEDDS_URI`` (a lab network's configuration) is used as given. The DDS domain is
``ROS_DOMAIN_ID`` (default 0), as in ROS 2.

This module imports no cyclonedds; :func:`require_cyclonedds` checks that it is installed.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from typing import Any

from wristmark.models.errors import InputError

LOOPBACK_CONFIG = (
    '<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    '<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
)
INSTALL_HINT = "pip install 'wristmark[ros2]' (or pip install cyclonedds)"


def ensure_loopback(environ: MutableMapping[str, str] | None = None) -> str:
    """The Cyclone DDS configuration in force: ``CYCLONEDDS_URI`` as the user gave it, or (unset
    or empty) :data:`LOOPBACK_CONFIG`, written into the environment for the participants to come."""
    env = os.environ if environ is None else environ
    given = env.get("CYCLONEDDS_URI", "")
    if given.strip():
        return given
    env["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
    return LOOPBACK_CONFIG


def domain_id(environ: MutableMapping[str, str] | None = None) -> int:
    """The DDS domain: ``ROS_DOMAIN_ID`` (0..232, default 0); InputError when it is not one."""
    env = os.environ if environ is None else environ
    text = env.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 232:
        raise InputError(f"ROS_DOMAIN_ID must be an integer 0..232, got {text!r}")
    return value


def require_cyclonedds(what: str = "--ros2") -> None:
    """InputError (one line) when the optional ``cyclonedds`` is not installed."""
    try:
        import cyclonedds  # noqa: F401 - the check itself (a broken install fails here too)
    except ImportError as e:
        raise InputError(f"{what} needs the Python package cyclonedds, which cannot be imported ({e}): "
                         f"{INSTALL_HINT}") from None


def open_participant() -> Any:
    """A Cyclone DDS participant on ``ROS_DOMAIN_ID``, loopback only unless ``CYCLONEDDS_URI``
    says otherwise (:func:`ensure_loopback` first). It reads this process's environment only:
    Cyclone DDS reads its configuration from ``os.environ``, so a participant opened after
    writing the loopback configuration anywhere else would not be loopback only."""
    require_cyclonedds()
    ensure_loopback()
    from cyclonedds.domain import DomainParticipant

    return DomainParticipant(domain_id())
