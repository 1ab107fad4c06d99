"""``hrc run``: start the five services of one trial as separate processes and watch them.

The trial ends when physics publishes ``run/end``. A service that dies before that ends the trial:
the others are stopped, the dead one is named, and the exit status is non-zero. Every service's
own log goes to ``<trial>/services/<name>.log``.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path

from hrc import metrics as metrics_schema
from hrc import service_table
from hrc.bus import Bus, BusConfig
from hrc.bus.access import TrialAccess, count_refusals
from hrc.diskspace import NO_SPACE, SpaceGuard, low_space
from hrc.paths import build_dir
from hrc.ports import free_port, release_port
from hrc.service_table import EXPERIMENTER
from hrc.trial.console import LiveConsole
from hrc.trial.options import (
    TrialOptions,
    TrialResult,
    awaits_watcher,
    fits_lowlatency,
    service_argv,
)
from hrc.trial.processes import (
    INTERRUPT_LEAVE_S,
    SERVICES_ABANDONED_S,
    SERVICES_LEAVE_S,
    START_LEAVE_S,
    Phases,
    ServiceGroup,
    Terminated,
    await_leaving,
    describe_exit,
    not_responding,
    process_age_s,
)
from hrc.wire import pb

log = logging.getLogger(__name__)


class _EndWatcher:
    """Listens for ``run/end`` so the CLI can name the reason even if a service log is terse."""

    def __init__(
        self,
        session: str,
        port: int,
        access: TrialAccess | None,
        on_end: Callable[[], None] = lambda: None,
    ) -> None:
        self.end: pb.RunEnd | None = None
        self._on_end_hook = on_end
        self.end_at: float | None = None  # time.monotonic() when run/end came
        self._event = threading.Event()
        cfg = BusConfig(
            session=session,
            connect=[f"tcp/127.0.0.1:{port}"],
            listen=[],
            config_file=str(access.config(EXPERIMENTER)) if access is not None else None,
        )
        # the experimenter's side of the trial: what stops it is named so ("stopped by
        # experimenter: ...")
        self.bus = Bus(cfg, EXPERIMENTER)
        self.bus.subscribe(self.bus.keys.run_end(), pb.RunEnd, self._on_end)
        self._up: set[str] = set()  # the services whose tokens came (the run follows them all)
        self.bus.watch_liveliness(self._on_token)
        # physics's first tick waits for this token (--watchers): the run's end cannot come
        # before the subscription above is in place
        self.bus.declare_token()

    def _on_token(self, name: str, alive: bool) -> None:
        if alive:
            self._up.add(name)

    def all_up(self) -> bool:
        """Every service of the trial declared its token (so the run is on, or about to be)."""
        return set(service_table.names()) <= self._up

    def _on_end(self, _key: str, end: pb.RunEnd) -> None:
        self.end_at = time.monotonic()
        self.end = end
        self._event.set()
        try:
            self._on_end_hook()
        except Exception as exc:  # a nicety: never the watcher's end
            log.debug("after run/end: %s", exc)

    def stop_run(self, reason: str, failed_service: str = "", abort: bool = False) -> None:
        """Asks the clock master to end the run, with ``reason``: as a normal stop, or (with
        ``failed_service``) as a failure of that service, which hrc run saw end or stop, or
        (``abort``) as a failure of no service (the disk). Every service then writes its files
        as at any end (metrics.json among them)."""
        ctl = pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason=reason)
        if failed_service or abort:
            ctl.command = pb.RunControl.COMMAND_ABORT
            ctl.failed_service = failed_service
        keys = self.bus.keys
        self.bus.publisher(keys.run_control(self.bus.sender), express=True).put(ctl)

    def failed_end(self, wait_s: float) -> bool:
        """A run/end with ok = false came (waiting up to ``wait_s`` for one)."""
        return self._event.wait(wait_s) and self.end is not None and not self.end.ok

    def close(self) -> None:
        self.bus.close()


def _phases(phases: Phases, t0: float, group: ServiceGroup, watcher: _EndWatcher | None) -> Phases:
    end_at = watcher.end_at if watcher is not None else None
    if watcher is None or watcher.end is None or end_at is None:
        return phases
    phases.run = watcher.end.wall_s
    phases.start = max(0.0, end_at - watcher.end.wall_s - t0)
    phases.exit_by_service = {n: group.exited_at[n] - end_at for n in group.exited_at}
    if group.exited_at:
        phases.end = max(group.exited_at.values()) - end_at
    return phases


def _watch(group: ServiceGroup, console: LiveConsole | None, guard: SpaceGuard) -> str | None:
    """Until a service exits (the loop below judges the exit), or the trial's disk is all but
    full (returns why): refreshes the live console, watches the disk."""
    while all(rc is None for rc in group.poll().values()):
        if console is not None:
            console.update()
        if guard.full is not None:
            return guard.full
        time.sleep(0.05)
    return None


def _when(watcher: _EndWatcher | None) -> str:
    """When a service's end came: before every service was up, or later."""
    up = watcher is None or watcher.all_up()
    return "during the run" if up else "at start-up, before the first tick"


def _interrupted(group: ServiceGroup, watcher: _EndWatcher | None, exc: BaseException) -> None:
    """Ctrl-C or SIGTERM during the run: the run is ended as a stop by the experimenter, so every
    service writes its files (metrics.json with that end reason); then the caller stops them."""
    how = "Ctrl-C" if isinstance(exc, KeyboardInterrupt) else str(exc)
    _end_run(group, watcher, f"interrupted ({how})")


def _end_run(
    group: ServiceGroup,
    watcher: _EndWatcher | None,
    reason: str,
    failed_service: str = "",
    abort: bool = False,
) -> None:
    """Ends the run over the bus (see :meth:`_EndWatcher.stop_run`) and gives the services
    INTERRUPT_LEAVE_S to write their files and leave (START_LEAVE_S before all of them came up;
    a stopped one is not waited for); the caller then stops what is left."""
    if watcher is None or watcher.end is not None:
        return
    try:
        watcher.stop_run(reason, failed_service, abort)
    except Exception as err:  # the bus is gone: the services are stopped as before
        log.debug("could not ask for the run's end: %s", err)
        return
    await_leaving(group, INTERRUPT_LEAVE_S if watcher.all_up() else START_LEAVE_S)


def run_trial(opts: TrialOptions, trial_dir: Path) -> TrialResult:
    # the port stays reserved (hrc.ports) until the trial's physics has gone
    port = opts.port or free_port()
    try:
        return _run_trial(opts, trial_dir, port)
    finally:
        if not opts.port:
            release_port(port)


def _run_trial(opts: TrialOptions, trial_dir: Path, port: int) -> TrialResult:
    session = opts.session or f"t{uuid.uuid4().hex[:10]}"
    lowlatency = opts.lowlatency and fits_lowlatency(opts.scenario)
    master = service_table.CLOCK_MASTER
    for svc in service_table.SERVICES:
        if svc.binary is not None and not (build_dir() / svc.binary).exists():
            return TrialResult(
                False,
                2,
                trial_dir,
                f"the {svc.name} service binary "
                f"{build_dir() / svc.binary} is missing: run scripts/setup.sh",
            )
    if (warning := low_space(trial_dir)) is not None:
        log.warning("%s", warning)
    guard = SpaceGuard(trial_dir)
    try:
        trial_dir.mkdir(parents=True, exist_ok=True)
        if (no_room := guard.start()) is not None:
            return TrialResult(False, 2, trial_dir, no_room)
        group = ServiceGroup(trial_dir)
    except OSError as exc:
        guard.release()
        return TrialResult(False, 2, trial_dir, f"cannot write to {trial_dir}: {exc.strerror}")
    watcher: _EndWatcher | None = None
    console: LiveConsole | None = None
    t0 = time.monotonic()
    phases = Phases(prepare=process_age_s())
    # (routers of other hosts know none of the trial's credentials)
    access = TrialAccess.create(session, service_table.names(), authenticate=not opts.connect)
    sock = access.socket if access is not None and opts.unix_socket else None
    try:
        # the table lists the clock master first: it listens where everybody else connects.
        for name in service_table.names():
            argv = service_argv(name, opts, session, port, trial_dir, sock, lowlatency, access)
            group.start(name, argv, service_table.service(name).module)
        guard.watch()  # (a thread: after the forks)
        try:  # (its client keeps trying until physics listens)
            watcher = _EndWatcher(session, port, access, on_end=group.lift_observers)
            if opts.vr is not None:
                console = LiveConsole(watcher.bus, opts.participant, opts.parts_total)
        except Exception as exc:
            if awaits_watcher(opts):  # physics waits for its token: no run without it
                group.stop_all(grace_s=service_table.STOP_GRACE_S + 0.5)
                why = f"hrc run could not join the trial's bus to watch it: {exc}"
                return TrialResult(False, 3, trial_dir, why, EXPERIMENTER)
            log.debug("no run/end watcher: %s", exc)  # process status still works
        failed = ""
        failure = ""
        try:
            disk = _watch(group, console, guard)
        except (KeyboardInterrupt, Terminated) as exc:
            _interrupted(group, watcher, exc)
            raise
        if disk is not None:
            # the room kept aside is given back; every service writes its last files
            log.error("%s", disk)
            _end_run(group, watcher, disk, abort=True)
        while True:
            status = group.poll()
            dead = [n for n, rc in status.items() if rc is not None and rc != 0 and n != master]
            if status[master] is not None:
                break
            # After a failed run/end the services exit 1 on their own: the end names the cause.
            # a stopped clock master is the cause (the others left when its link died): no
            # run/end can come then
            stopped = group.stopped() if dead else []
            if dead and (
                master in stopped
                or not (
                    watcher is not None
                    and all((status[n] or 0) > 0 for n in dead)
                    and watcher.failed_end(1.0)
                )
            ):
                # A clean exit (0) is not a failure by itself: the clock master notices the lost
                # liveliness and ends the run naming the service, if the run was still going.
                failed = dead[0]
                how = describe_exit(status[failed] or 0)
                failure = f"service '{failed}' {how} {_when(watcher)}"
                if stopped:
                    failed = stopped[0]
                    failure = not_responding(failed, how=group.halt_of(failed))
                # the run's end names the cause, and every service writes its files with it
                _end_run(group, watcher, failure, failed)
                break
            time.sleep(0.05)
        if not failed:
            # the clock master is done; the others leave on run/end.
            # (the logger may still be catching up: it writes every file before it leaves)
            ended = watcher is not None and watcher.end is not None
            master_rc = status[master]
            leave_s = SERVICES_LEAVE_S if ended or master_rc == 0 else SERVICES_ABANDONED_S
            if not ended and watcher is not None and not watcher.all_up():
                leave_s = START_LEAVE_S  # the clock master gone before the run began
            await_leaving(group, leave_s)  # hrc run returns as soon as the last one has left
        # judge by how each ended on its own, before we stop the stragglers
        status = group.poll()
        stopped = group.stopped()
        # SIGTERM: a service still writes its files (metrics.json) within its grace
        group.stop_all(grace_s=service_table.STOP_GRACE_S + 0.5)
        end = watcher.end if watcher else None
        wall = time.monotonic() - t0
        killed = [n for n in service_table.names() if (status.get(n) or 0) < 0]
        if killed and (not failed or (status.get(failed) or 0) >= 0):
            # a service killed by a signal is the root cause; the others' errors follow from it
            failed = killed[0]
            failure = f"service '{failed}' {describe_exit(status[failed] or 0)} {_when(watcher)}"
        phys = status.get(master)
        if not failed and phys is not None and (phys < 0 or (end is None and phys != 0)):
            # the clock master itself died: the others' errors ("clock master disappeared")
            # follow from it
            failed = master
            failure = f"service '{master}' {describe_exit(phys)} {_when(watcher)}"
        if (
            not failed
            and stopped
            and not (end is not None and not end.ok and end.failed_participant in stopped)
        ):
            # stopped at the end of a run that did not name it (it wrote none of its last files)
            failed = stopped[0]
            failure = not_responding(failed, " at the run's end", group.halt_of(failed))
        if not failed:
            bad = [n for n in service_table.names() if status.get(n) not in (0, None)]
            if end is not None and not end.ok:
                failed = end.failed_participant or (bad[0] if bad else master)
                failure = f"run failed: {end.reason}"
                rc = status.get(failed) or 0
                own = group.own_error(failed) if rc > 0 else ""
                if own and own not in end.reason:
                    # e.g. "never came up" while the service had given up joining the bus
                    failure += f" ('{failed}' {describe_exit(rc)}: {own})"
            elif bad:
                failed = bad[0]
                failure = f"service '{failed}' {describe_exit(status[failed] or 0)}"
        full = group.out_of_space() if failed or end is None or not end.ok else None
        if full is not None:
            failed = full
            failure = f"no space left on {trial_dir} (service '{full}' could not write its files)"
        if disk is not None:  # the cause of whatever the services said after it
            return TrialResult(False, 3, trial_dir, disk, "", end, wall)
        if failed:
            detail = group.tail(failed)
            if full is not None:  # the one line that says it, not a traceback
                said = [ln for ln in group.tail(failed, 40).splitlines() if NO_SPACE in ln]
                detail = said[0] if said else detail
            msg = failure + (
                f"\n--- last lines of {group.log_path(failed)}:\n{detail}" if detail else ""
            )
            return TrialResult(False, 3, trial_dir, msg, failed, end, wall)
        return TrialResult(True, 0, trial_dir, "trial completed", "", end, wall)
    finally:
        guard.stop()
        guard.release()
        if console is not None:
            end = watcher.end if watcher is not None else None
            console.close(end.reason if end is not None else "")
        if watcher is not None:
            watcher.close()
        group.stop_all(grace_s=1.0)
        metrics_schema.add_recording(trial_dir)
        if access is not None and not opts.connect:  # physics checked every link
            counts = count_refusals(group.log_path(master))
            if counts is not None:
                refused = metrics_schema.access_metrics(counts)
                metrics_schema.add_access(trial_dir, refused)
                if refused.refused_links:
                    log.warning("%s", metrics_schema.access_line(refused))
        group.write_cpu()
        group.write_timing(_phases(phases, t0, group, watcher))
        group.close()
        if access is not None:
            access.remove()
