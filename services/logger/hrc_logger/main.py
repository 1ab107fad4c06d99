"""Entry point of the logger service (``hrc-logger``): observes the session, never acks."""

from __future__ import annotations

import argparse
import logging

from hrc.bus import Bus, LockstepParticipant, add_bus_arguments, bus_config_from_args
from hrc.logsetup import setup_logging

log = logging.getLogger("hrc_logger")

NAME = "logger"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hrc-logger", description=__doc__)
    add_bus_arguments(p)
    p.add_argument("--out", default=None, help="trial folder")
    p.add_argument("--log-level", default=None)
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    setup_logging(NAME, args.log_level)
    with Bus(bus_config_from_args(args), NAME) as bus:
        observer = LockstepParticipant(bus, ack=False)
        observer.start()
        outcome = observer.run()
        if not outcome.ok:
            log.error("run ended with an error: %s", outcome.reason)
        return outcome.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
