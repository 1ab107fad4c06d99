"""Entry point of the physics service (``hrc-physics``): the pybullet world and the clock."""

from __future__ import annotations

import argparse
import logging

from hrc.bus import Bus, ClockMaster, ClockSettings, RunFailed, add_bus_arguments, bus_config_from_args
from hrc.logsetup import setup_logging
from hrc.scenario import ScenarioError
from hrc.services import OBSERVERS, PARTICIPANTS
from hrc.wire import pb
from hrc_physics.robots import RobotModelError
from hrc_physics.service import PhysicsService
from hrc_physics.world import WorldSettings

log = logging.getLogger("hrc_physics")

NAME = "physics"


def _names(text: str) -> list[str]:
    return [n for n in text.split(",") if n]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hrc-physics", description=__doc__)
    add_bus_arguments(p)
    p.add_argument("--clock", choices=["lockstep", "realtime"], default="lockstep",
                   help="co-simulation mode (default lockstep)")
    p.add_argument("--ticks", type=int, default=0, help="stop after N ticks (0: when told to stop)")
    p.add_argument("--tick-hz", type=float, default=0.0,
                   help="override the scenario's tick_hz (0: use the scenario's)")
    p.add_argument("--participants", default=",".join(PARTICIPANTS),
                   help="comma-separated services whose acks close the barrier "
                        "(default: the service table's, %(default)s)")
    p.add_argument("--observers", default=",".join(OBSERVERS),
                   help="comma-separated services that must be present but never ack "
                        "(default: the service table's, %(default)s)")
    p.add_argument("--barrier-timeout", type=float, default=10.0,
                   help="lockstep: seconds a participant may take for one tick (default 10)")
    p.add_argument("--start-timeout", type=float, default=60.0,
                   help="seconds to wait for the scenario and every service (default 60)")
    p.add_argument("--solver-iterations", type=int, default=WorldSettings.solver_iterations,
                   help="pybullet solver iterations per step (default %(default)s)")
    p.add_argument("--log-level", default=None)
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    setup_logging(NAME, args.log_level)
    if args.ticks < 0:
        log.error("--ticks must be >= 0, got %d", args.ticks)
        return 2
    if args.solver_iterations < 1:
        log.error("--solver-iterations must be >= 1, got %d", args.solver_iterations)
        return 2
    with Bus(bus_config_from_args(args), NAME) as bus:
        try:
            scenario = bus.get_one(bus.keys.scenario(), pb.Scenario, timeout=args.start_timeout)
        except TimeoutError as exc:
            log.error("no scenario: %s (is the orchestrator running in session %r?)", exc,
                      bus.keys.session)
            return 1
        tick_hz = args.tick_hz or scenario.info.tick_hz or 240.0
        try:
            settings = ClockSettings(mode=args.clock, tick_hz=tick_hz, ticks=args.ticks,
                                     participants=_names(args.participants),
                                     observers=_names(args.observers),
                                     barrier_timeout_s=args.barrier_timeout,
                                     start_timeout_s=args.start_timeout)
        except ValueError as exc:
            log.error("%s", exc)
            return 2
        try:
            service = PhysicsService(bus, scenario, tick_hz, args.solver_iterations)
        except (ScenarioError, RobotModelError) as exc:
            log.error("cannot build the world: %s", exc)
            return 1
        with service:
            clock = ClockMaster(bus, settings)
            service.register_inputs(clock)
            clock.start()
            log.info("scenario %r, %s at %g Hz, %d objects, waiting for %s", scenario.info.name,
                     args.clock, tick_hz, len(service.world.objects),
                     ", ".join(settings.participants + settings.observers))
            try:
                end = clock.run(service.publish_world, service.step)
            except RunFailed as exc:  # pragma: no cover - run() reports failures in RunEnd
                log.error("%s", exc)
                return 1
        log.info("run ended after %d ticks (%.2f s wall, %.1fx realtime): %s", end.ticks,
                 end.wall_s, end.realtime_factor, end.reason)
        return 0 if end.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
