"""Zenoh session configuration shared by every Python service."""

from __future__ import annotations

import argparse
import json
import os
from dataclasses import dataclass, field
from typing import Literal

import zenoh

from hrc.service_table import CLOCK_MASTER

Mode = Literal["peer", "client", "router"]

CONNECT_TIMEOUT_S = 60.0  # as long as the clock master waits for every service (--start-timeout)
# A client that starts before the router listens (they start together) tries again after 10,
# 20, 40, then every 50 ms: a failed local connect costs microseconds, a late retry costs the
# start-up up to the whole period (it was 100 ms doubling to 1 s). Same in ik_cpp's bus.cpp.
CONNECT_RETRY = "{ period_init_ms: 10, period_max_ms: 50, period_increase_factor: 2 }"


def without_shared_memory(cfg: zenoh.Config) -> zenoh.Config:
    """Zenoh's shared memory off: every message goes over the link itself. Zenoh puts a message
    of 3 KiB or more (the 32-tick state batches, replays) into shared memory when both ends allow
    it, and each process maps the other's segments. The segments stayed in /dev/shm after the
    processes ended (8 files, 49 MB of memory, per thesis trial: a study of a thousand trials
    would fill the machine's memory), and the messages the bus lost on loaded machines
    (docs/ARCHITECTURE.md, "Lost messages") were such batches, at Python receivers, and their
    replays were lost too. (ik_cpp is built without it.)"""
    cfg.insert_json5("transport/shared_memory/enabled", "false")
    return cfg


@dataclass
class BusConfig:
    """Where a service meets the others.

    Defaults: peer mode on loopback, multicast scouting off (so nothing leaks onto the LAN and two
    machines never join by accident), explicit endpoints, gossip on so peers that connected to the
    same endpoint find each other.
    """

    session: str = "default"
    mode: Mode = "peer"
    connect: list[str] = field(default_factory=list)
    listen: list[str] = field(default_factory=lambda: ["tcp/127.0.0.1:0"])
    multicast_scouting: bool = False
    # Zenoh's low-latency transport: a put writes to the socket on the caller's thread (no
    # hand-off to a tx thread), no QoS priorities, and no message above 64 KiB (no
    # fragmentation). A link falls back to the standard transport unless both ends ask for it.
    lowlatency: bool = False
    config_file: str | None = None
    # The service whose clock participants and observers follow (``hrc run`` passes it).
    clock_master: str = CLOCK_MASTER
    # How long a service with ``connect`` endpoints keeps trying to reach one before it gives up
    connect_timeout_s: float = CONNECT_TIMEOUT_S

    def to_zenoh(self) -> zenoh.Config:
        cfg = zenoh.Config.from_file(self.config_file) if self.config_file else zenoh.Config()
        cfg.insert_json5("mode", json.dumps(self.mode))
        cfg.insert_json5("scouting/multicast/enabled", json.dumps(self.multicast_scouting))
        if self.connect:
            cfg.insert_json5("connect/endpoints", json.dumps(self.connect))
            # Keep trying while the other end starts (a client otherwise fails at once).
            cfg.insert_json5("connect/timeout_ms", str(round(self.connect_timeout_s * 1000)))
            cfg.insert_json5("connect/retry", CONNECT_RETRY)
        if self.listen:
            cfg.insert_json5("listen/endpoints", json.dumps(self.listen))
        if (
            self.mode == "router"
            and not self.connect
            and not self.multicast_scouting
            and cfg.get_json("scouting/delay") == "null"
        ):
            # A router's open waits scouting/delay (Zenoh's default 500 ms) for the peers it
            # scouts or connects to: with neither, half a second of every trial's start-up
            # (physics is the trial's router) for nothing.
            cfg.insert_json5("scouting/delay", "0")
        if self.mode != "router":
            # Access control is the router's (hrc.bus.access.router_acl, default deny): in the
            # configuration file of a service that is the router in one deployment and a client
            # of another router in the next (physics), it would deny the client everything.
            cfg.insert_json5("access_control/enabled", "false")
        if self.lowlatency:
            cfg.insert_json5("transport/unicast/lowlatency", "true")
            cfg.insert_json5("transport/unicast/qos/enabled", "false")  # required by lowlatency
        return without_shared_memory(cfg)


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every service takes (environment variables give the defaults)."""
    g = parser.add_argument_group("bus")
    g.add_argument(
        "--session",
        default=os.environ.get("HRC_SESSION", "default"),
        help="session id; every key is under hrc/<session>/ (env HRC_SESSION)",
    )
    g.add_argument(
        "--connect",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable; "
        "env HRC_CONNECT, comma-separated)",
    )
    g.add_argument(
        "--connect-timeout",
        type=float,
        default=os.environ.get("HRC_CONNECT_TIMEOUT_S", str(CONNECT_TIMEOUT_S)),
        metavar="S",
        help="how long to keep trying to reach a --connect endpoint before giving up "
        f"(default {CONNECT_TIMEOUT_S:g}; env HRC_CONNECT_TIMEOUT_S)",
    )
    g.add_argument(
        "--listen",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on (repeatable; default tcp/127.0.0.1:0)",
    )
    g.add_argument(
        "--zenoh-mode",
        choices=["peer", "client", "router"],
        default=os.environ.get("HRC_ZENOH_MODE", "peer"),
        help="Zenoh mode (default peer)",
    )
    g.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="a Zenoh JSON5 config file applied before the options above",
    )
    g.add_argument(
        "--zenoh-lowlatency",
        action="store_true",
        default=os.environ.get("HRC_ZENOH_LOWLATENCY", "") not in ("", "0"),
        help="Zenoh's low-latency transport (no QoS, messages <= 64 KiB; both ends of "
        "a link must ask for it; env HRC_ZENOH_LOWLATENCY=1)",
    )
    g.add_argument(
        "--clock-master",
        default=CLOCK_MASTER,
        metavar="NAME",
        help="the service whose clock a participant or observer follows "
        f"(default {CLOCK_MASTER}, the service table's)",
    )


def bus_config_from_args(args: argparse.Namespace) -> BusConfig:
    connect = args.connect
    if connect is None:
        env = os.environ.get("HRC_CONNECT", "")
        connect = [e for e in env.split(",") if e]
    if args.listen is not None:
        listen = args.listen
    else:  # a client only connects; peers and routers accept links on a free loopback port
        listen = [] if args.zenoh_mode == "client" else ["tcp/127.0.0.1:0"]
    return BusConfig(
        session=args.session,
        mode=args.zenoh_mode,
        connect=connect,
        listen=listen,
        lowlatency=args.zenoh_lowlatency,
        config_file=args.zenoh_config,
        clock_master=args.clock_master,
        connect_timeout_s=args.connect_timeout,
    )
