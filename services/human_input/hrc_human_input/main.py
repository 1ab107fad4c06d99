"""Entry point of the human-input service (``hrc-human-input``)."""

from __future__ import annotations

import argparse
import logging

from hrc.bus import Bus, LockstepParticipant, add_bus_arguments, bus_config_from_args
from hrc.logsetup import setup_logging
from hrc.wire import pb

log = logging.getLogger("hrc_human_input")

NAME = "human_input"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hrc-human-input", description=__doc__)
    add_bus_arguments(p)
    p.add_argument("--start-timeout", type=float, default=60.0)
    p.add_argument("--log-level", default=None)
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    setup_logging(NAME, args.log_level)
    with Bus(bus_config_from_args(args), NAME) as bus:
        try:
            scenario = bus.get_one(bus.keys.scenario(), pb.Scenario, timeout=args.start_timeout)
        except TimeoutError as exc:
            log.error("no scenario: %s", exc)
            return 1
        participant = LockstepParticipant(bus)
        participant.start()
        log.info("participant %r ready (input %s)", scenario.participant.name,
                 scenario.participant.input)
        outcome = participant.run()
        if not outcome.ok:
            log.error("run ended with an error: %s", outcome.reason)
        return outcome.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
