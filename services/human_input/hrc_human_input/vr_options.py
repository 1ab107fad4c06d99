"""The VR bridge's options and their checks, without the bridge: a scripted or replayed
participant checks them too, but never imports the bridge's server (websockets, asyncio)."""

from __future__ import annotations

import ipaddress
import os
from pathlib import Path

from hrc.services import VR_DEFAULT_HOST, VR_DEFAULT_PORT

DEFAULT_HOST = VR_DEFAULT_HOST
DEFAULT_PORT = VR_DEFAULT_PORT
# The participant client's bundle (built by scripts/setup.sh, services/human_input/client/);
# HRC_CLIENT_DIST serves another build (a developer's, built with build.mjs --out DIR).
CLIENT_DIST = Path(
    os.environ.get("HRC_CLIENT_DIST") or Path(__file__).resolve().parents[1] / "client" / "dist"
)
DRIVER, SPECTATOR = "driver", "spectator"  # a client's role (docs/client-protocol.md)


class BridgeConfigError(ValueError):
    """The bridge would be unsafe or cannot start as configured."""


def is_loopback(host: str) -> bool:
    if host in ("localhost", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False  # a host name other than localhost may resolve to anything


def check_bind(host: str, token: str | None) -> None:
    """A bridge reachable from other machines must require a token."""
    if not is_loopback(host) and not token:
        raise BridgeConfigError(
            f"refusing to bind the VR bridge to {host!r} without a token: anyone on the network "
            "could drive the participant's hands. Give --vr-token (or HRC_VR_TOKEN), or bind "
            "127.0.0.1"
        )
