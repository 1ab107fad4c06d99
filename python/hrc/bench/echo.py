"""A Python echo peer for the bus benchmark: republishes every payload of one key on another."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

import zenoh

from hrc.bus import Bus, access, add_bus_arguments, bus_config_from_args


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m hrc.bench.echo")
    add_bus_arguments(p)
    p.add_argument("--in", dest="inp", required=True, help="bench key name to listen on")
    p.add_argument("--out", required=True, help="bench key name to answer on")
    args = p.parse_args(argv)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with Bus(access.as_tool(bus_config_from_args(args)), "echo") as bus:
        pub = bus.session.declare_publisher(
            bus.keys.bench(args.out), express=True, congestion_control=zenoh.CongestionControl.BLOCK
        )

        def on_sample(sample: zenoh.Sample) -> None:
            pub.put(sample.payload)

        sub = bus.session.declare_subscriber(bus.keys.bench(args.inp), on_sample)
        print("ready", flush=True)
        try:
            while not done.wait(0.5):
                pass
        except KeyboardInterrupt:
            pass
        sub.undeclare()
        pub.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
