"""The VR bridge's options and their checks, without the bridge: a scripted or replayed
participant checks them too, but never imports the bridge's server (websockets, asyncio). What
the bridge shares with a session's page (files, loopback, the address options) is the
library's: hrc.webpage."""

from __future__ import annotations

from hrc.service_table import VR_DEFAULT_HOST, VR_DEFAULT_PORT
from hrc.webpage import bind_problem, client_dist, is_loopback

DEFAULT_HOST = VR_DEFAULT_HOST
DEFAULT_PORT = VR_DEFAULT_PORT
CLIENT_DIST = client_dist()
DRIVER, SPECTATOR = "driver", "spectator"  # a client's role (docs/client-protocol.md)
# the bridge's options, with is_loopback re-exported from the library for the bridge's users
__all__ = [
    "CLIENT_DIST",
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "DRIVER",
    "SPECTATOR",
    "BridgeConfigError",
    "check_bind",
    "is_loopback",
]


class BridgeConfigError(ValueError):
    """The bridge would be unsafe or cannot start as configured."""


def check_bind(host: str, token: str | None) -> None:
    """A bridge reachable from other machines must require a token."""
    problem = bind_problem(
        host,
        token,
        "the VR bridge",
        "drive the participant's hands",
        "--vr-token (or HRC_VR_TOKEN)",
    )
    if problem:
        raise BridgeConfigError(problem)
