"""One shape for every Python service: options, logging, the bus session, the role, the exit code.

A service is a subclass of :class:`Service` (or :class:`ClockMasterService`) with a few hooks;
its ``main`` is ``return run_service(TheService, argv)``. :func:`run_service`:

1. parses the bus options, ``--input-timeout`` (participants and observers), the service's own
   options (:meth:`Service.add_arguments`) and ``--log-level``, and sets up logging;
2. constructs the service from its options: checks and local files, before joining the bus;
3. opens the bus session; :meth:`Service.open` fetches what the service needs from the bus,
   builds its state and declares its publishers;
4. creates the role (docs/ARCHITECTURE.md, "Roles"): a :class:`ClockMaster`, a
   :class:`LockstepParticipant` or an :class:`Observer`; :meth:`Service.register_inputs` adds
   the inputs; the role subscribes and declares the liveliness token (ready);
5. runs the role until the run ends (the step of each tick: :meth:`Service.step`, or the clock
   master's :meth:`ClockMasterService.publish_world` and :meth:`ClockMasterService.step_world`);
6. :meth:`Service.finish` writes what the service writes at the end; the exit code is 0 when the
   run ended ok, 1 when it failed, or a :class:`ServiceExit`'s code when the service refused to
   run (2: bad input or options, 1: something it needs never came).

A service's ``__main__`` ends with :func:`exit_now` (the process leaves without the
interpreter's teardown once everything is written).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType
from typing import ClassVar, NoReturn, Protocol

import zenoh

from hrc import privacy, service_table
from hrc.bus import (
    Bus,
    BusConfig,
    ClockFollower,
    ClockMaster,
    ClockSettings,
    LockstepParticipant,
    Observer,
    Outcome,
    add_bus_arguments,
    bus_config_from_args,
)
from hrc.bus.bus import M
from hrc.logsetup import setup_logging
from hrc.service_table import Role
from hrc.wire import pb

log = logging.getLogger(__name__)

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


class ServiceExit(Exception):
    """The service refuses to run: the message is logged (and, for bad input, printed on
    stderr), the process exits with ``code``."""

    def __init__(self, message: str, code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        self.code = code


class Inputs(Protocol):
    """What :meth:`Service.register_inputs` gets: the role's input registration."""

    def input(
        self,
        key: str,
        msg_type: type[M],
        handler: Callable[[str, M], None],
        validate: Callable[[M], str | None] | None = None,
    ) -> None: ...


class Service:
    """The hooks of a service; :func:`run_service` calls them in order. Override what you need."""

    # Its name in the service table (hrc.service_table), which gives its role and its command's
    # name; also its bus name: alive/<name>, clock/ack/<name>, the log prefix.
    name: ClassVar[str]
    description: ClassVar[str] = ""  # --help text; default: the docstring of the class's module
    # The observer role, for an observer's finish (its lag and sequence counters); set by
    # run_service.
    observer: Observer | None = None

    @classmethod
    def entry(cls) -> service_table.Service:
        """The service's line in the service table."""
        return service_table.service(cls.name)

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """The service's own command-line options."""

    def __init__(self, args: argparse.Namespace) -> None:
        """Checks the options and reads local files, before joining the bus (ServiceExit)."""
        self.args = args

    def open(self, bus: Bus, stack: contextlib.ExitStack) -> None:
        """The session is open: fetch what the service needs, build its state, declare its
        publishers. What must be released at the end goes on ``stack`` (closed before the bus)."""
        self.bus = bus

    def register_inputs(self, inputs: Inputs) -> None:
        """Registers the inputs (each is handed over before the step of its tick, in the order
        registered)."""

    def step(self, tick: pb.ClockTick) -> None:
        """The work of one tick (participants and observers): publish the tick's outputs."""

    def next_event_tick(self) -> int:
        """Participants, after the steps of an exchange: the earliest tick at which the
        service, holding its inputs, may make a discrete change the others react to (a timer
        runs out, an arm reaches its target); 0 if none is known. A lower bound, from simulated
        quantities only (docs/ARCHITECTURE.md, "Exchange step")."""
        return 0

    def next_sample_tick(self) -> tuple[int, int]:
        """Participants, after the steps of an exchange: the earliest tick at which the service
        reads its inputs to decide from what it perceives, and every how many ticks it goes on
        doing so (0: once); exchanges then start there, with no reaction chain. (0, 0): none
        (docs/ARCHITECTURE.md, "Exchange step")."""
        return 0, 0

    def finish(self, outcome: Outcome) -> int | None:
        """The run is over (the bus is still open): write what the service writes at the end.
        Returns the exit code, or None for the outcome's (0 ok, 1 failed)."""
        return None


class ClockMasterService(Service):
    """The clock master's hooks: its clock settings, and the two halves of its tick."""

    def clock_settings(self) -> ClockSettings:
        raise NotImplementedError

    def publish_world(self, tick: int, sim_time: float) -> None:
        """The world state of ``tick``, published before clock tick ``tick``."""

    def step_world(self, tick: int, sim_time: float) -> None:
        """After the barrier of ``tick``: its inputs are applied; advance to ``tick + 1``."""

    def max_exchange_ticks(self) -> int:
        """The longest exchange (lockstep). Default 1."""
        return 1

    def exchange_span(self, tick: int, limit: int) -> int:
        """How many ticks, at most ``limit`` (> 1: the longest exchange, shortened by the
        declared events), the exchange starting at ``tick`` covers (lockstep), chosen from the
        simulated state only (docs/ARCHITECTURE.md, "Exchange step"). Default ``limit``."""
        return limit

    def publish_substep(self, tick: int, sim_time: float) -> None:
        """Inside an exchange, ``tick`` is reached: publish what happened at it (stamped
        ``tick``); the rest of the world state goes with the next clock tick."""


def fetch_scenario(bus: Bus, timeout: float) -> pb.Scenario:
    """The scenario from the orchestrator's queryable (it may still be starting)."""
    try:
        return bus.get_one(bus.keys.scenario(), pb.Scenario, timeout=timeout)
    except TimeoutError as exc:
        raise ServiceExit(
            f"no scenario: {exc} (is the orchestrator running in session {bus.keys.session!r}?)"
        ) from exc


def parse_args(cls: type[Service], argv: list[str] | None = None) -> argparse.Namespace:
    description = cls.description or sys.modules[cls.__module__].__doc__ or ""
    p = argparse.ArgumentParser(
        prog=cls.entry().script,
        description=description,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bus_arguments(p)
    if cls.entry().role is not Role.CLOCK_MASTER:
        p.add_argument(
            "--input-timeout",
            type=float,
            default=10.0,
            metavar="S",
            help="lockstep: seconds to wait for the inputs a clock tick lists (default 10)",
        )
    cls.add_arguments(p)
    p.add_argument(
        "--log-level",
        default=None,
        help="DEBUG, INFO (default; env HRC_LOG_LEVEL), WARNING or ERROR",
    )
    return p.parse_args(argv)


def _stop_on_signals(role: ClockFollower) -> None:
    """SIGTERM / SIGINT end a service's run cleanly: it still writes its files, within
    service_table.STOP_GRACE_S (it may be far behind the clock); then it exits anyway, so that it
    never outlives the trial (hrc run sends SIGTERM when it stops, and when it dies)."""

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        # The handler runs on the main thread between two of its bytecodes, possibly while that
        # thread holds the role's lock (a plain Lock): stopping from here would wait for it
        # forever, before any timer (a logger SIGTERMed mid-trial hung so, 2026-12-01). So the
        # grace timer first, and the stop on a thread of its own, which gets the lock once the
        # main thread lets go of it.
        timer = threading.Timer(service_table.STOP_GRACE_S, _exit_now)
        timer.daemon = True
        timer.start()
        reason = f"terminated by {signal.Signals(signum).name}"
        threading.Thread(target=role.stop, args=(reason,), name="stop", daemon=True).start()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)


def _exit_now() -> None:
    log.error("still writing %.0f s after the stop signal: exiting", service_table.STOP_GRACE_S)
    os._exit(EXIT_FAILED)


def _run_role(service: Service, bus: Bus) -> Outcome:
    kind = service.entry().role
    if (kind is Role.CLOCK_MASTER) != isinstance(service, ClockMasterService):
        raise TypeError(
            f"{service.name}: the table says {kind.value}; a clock master "
            "is a ClockMasterService and nothing else is"
        )
    if isinstance(service, ClockMasterService):
        clock = ClockMaster(bus, service.clock_settings())
        service.register_inputs(clock)
        clock.start()
        end = clock.run(
            service.publish_world,
            service.step_world,
            service.exchange_span,
            service.publish_substep,
            max_span=service.max_exchange_ticks(),
        )
        return Outcome(end.ok, end.reason, end)
    timeout = service.args.input_timeout
    role: ClockFollower
    if kind is Role.OBSERVER:
        role = service.observer = Observer(bus, input_timeout_s=timeout)
    else:
        role = LockstepParticipant(bus, input_timeout_s=timeout)
        role.on_next_event(service.next_event_tick)
        role.on_next_sample(service.next_sample_tick)
    # a participant too: the orchestrator stopped right after the run's end (or by Ctrl-C)
    # still writes metrics.json with the end it saw
    _stop_on_signals(role)
    service.register_inputs(role)
    role.on_tick(service.step)
    role.start()
    return role.run()


def exit_now(code: int) -> NoReturn:
    """Ends a service's process with ``code`` once :func:`run_service` has returned: its files
    are written and closed, its session is closed. The interpreter's teardown (module clean-up,
    the zenoh / rerun / pybullet runtimes) is skipped: it took 0.3-1.7 s per service after
    the run on a busy machine, and ``hrc run`` waits for every service to leave."""
    logging.shutdown()
    flush_output()
    os._exit(code)


def flush_output() -> None:
    """Writes out what stdout and stderr hold (before ``os._exit``, or a fork that would write
    it twice)."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()


def bus_config(cls: type[Service], args: argparse.Namespace) -> BusConfig:
    """The bus options of service ``cls``. An observer stays on Zenoh's standard transport,
    whatever it is asked (HRC_ZENOH_LOWLATENCY reaches every service of a deployment): on a
    low-latency link the router could not drop what a stopped observer cannot take, and the
    observer would hold the clock (docs/ARCHITECTURE.md, "Observers never hold the clock")."""
    config = bus_config_from_args(args)
    if config.lowlatency and cls.entry().role is Role.OBSERVER:
        log.warning("an observer stays on Zenoh's standard transport: low latency ignored")
        config.lowlatency = False
    return config


def _join(cls: type[Service], args: argparse.Namespace) -> Bus:
    """The service's session on the trial's bus; ServiceExit naming where, if Zenoh gives up
    (a client retries until its connect timeout: the router never listened, or refused it)."""
    config = bus_config(cls, args)
    try:
        return Bus(config, cls.name)
    except zenoh.ZError as exc:
        where = ", ".join(config.connect or config.listen) or "the default endpoints"
        said = str(exc).split(" at /", 1)[0]  # (not where in Zenoh's source it gave up)
        raise ServiceExit(f"cannot join the trial's bus at {where}: {said}") from exc


def run_service(cls: type[Service], argv: list[str] | None = None) -> int:
    """Runs the service ``cls`` as a process would; returns its exit code."""
    args = parse_args(cls, argv)
    setup_logging(cls.name, args.log_level)
    try:
        privacy.apply()  # what it writes is private by default (hrc.privacy)
    except ValueError as exc:
        log.error("%s", exc)
        print(f"{cls.entry().script}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        service = cls(args)
        with _join(cls, args) as bus, contextlib.ExitStack() as stack:
            service.open(bus, stack)
            outcome = _run_role(service, bus)
            code = service.finish(outcome)
    except ServiceExit as exc:
        log.error("%s", exc)
        if exc.code == EXIT_BAD_INPUT:  # also when logging goes elsewhere: the user must act
            print(f"{cls.entry().script}: {exc}", file=sys.stderr)
        return exc.code
    if not outcome.ok:
        log.error("%s: %s", service_table.RUN_ENDED_WITH_ERROR, outcome.reason)
    return outcome.exit_code if code is None else code
