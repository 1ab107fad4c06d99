"""Entry point of the orchestrator service (``hrc-orchestrator``)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from hrc import scenario as scenario_mod
from hrc.bus import Bus, LockstepParticipant, add_bus_arguments, bus_config_from_args
from hrc.logsetup import setup_logging
from hrc.wire import pb
from hrc_orchestrator.metrics_file import run_section, write_json

log = logging.getLogger("hrc_orchestrator")

NAME = "orchestrator"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hrc-orchestrator", description=__doc__)
    add_bus_arguments(p)
    p.add_argument("--scenario", required=True, help="scenario TOML file")
    p.add_argument("--out", default=None, help="trial folder for metrics.json (default: none)")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument("--log-level", default=None)
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    setup_logging(NAME, args.log_level)
    try:
        scenario = scenario_mod.load(args.scenario)
    except scenario_mod.ScenarioError as exc:
        log.error("scenario rejected:\n%s", exc)
        return 2
    except OSError as exc:
        log.error("cannot read scenario %s: %s", args.scenario, exc)
        return 2
    spb = scenario_mod.to_proto(scenario)
    if args.seed is not None:
        spb.info.seed = args.seed
    with Bus(bus_config_from_args(args), NAME) as bus:
        spb.header.session = bus.keys.session
        spb.header.sender = NAME
        bus.queryable(bus.keys.scenario(), None, lambda _req: spb)
        participant = LockstepParticipant(bus)
        participant.start()
        log.info("serving scenario %r (seed %d)", spb.info.name, spb.info.seed)
        outcome = participant.run()
        if args.out and outcome.run_end is not None:
            metrics = {
                "scenario": spb.info.name,
                "participant": spb.participant.name,
                "conditions": {"anticipation": spb.conditions.anticipation,
                               "safety_policy": spb.conditions.safety_policy},
                "seed": int(spb.info.seed),
                "run": run_section(outcome.run_end),
            }
            write_json(Path(args.out) / "metrics.json", metrics)
        if not outcome.ok:
            log.error("run ended with an error: %s", outcome.reason)
        return outcome.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
