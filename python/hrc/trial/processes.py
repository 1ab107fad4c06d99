"""The processes of one trial: started, watched and stopped as a group (ServiceGroup); how a
stop is asked for (signals) and how a process that hangs or dies is named."""

from __future__ import annotations

import functools
import json
import logging
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from hrc import priority, service_table
from hrc.diskspace import NO_SPACE
from hrc.trial.prefork import ForkedProcess, can_fork, fork_service

log = logging.getLogger(__name__)


# After the clock master's end: how long the others may take to finish their files and leave.
SERVICES_LEAVE_S = 60.0
# ... when it died without publishing run/end: the others have no end to finish on (they leave
# when they notice it gone, or are stopped), so a stop must not wait a minute for them.
SERVICES_ABANDONED_S = 5.0
# A service that has used no CPU for this long while it should be leaving is hung: hrc run
# stops waiting for it (SIGTERM, then SIGKILL).
LEAVE_IDLE_S = 5.0
# Ctrl-C or SIGTERM: how long the services may take to end the run and write their files.
INTERRUPT_LEAVE_S = 10.0
# ... the same before every service came up: only those already following the clock act on the
# end (physics in its wait for the others, the orchestrator with metrics.json); the others wait
# for a scenario or a router that will never come, so waiting longer only delays the report.
START_LEAVE_S = 2.0


class Terminated(BaseException):
    """``hrc run`` got SIGTERM or SIGHUP (or its parent died): stop the trial like Ctrl-C.
    A BaseException, as KeyboardInterrupt: no ``except Exception`` on the way may swallow it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise_terminated(signum: int, _frame: object) -> None:
    for sig in (signal.SIGTERM, signal.SIGHUP):  # a second signal must not cut the cleanup short
        signal.signal(sig, signal.SIG_IGN)
    raise Terminated(signum)


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def die_with_parent(signum: int = signal.SIGTERM) -> None:
    """Asks Linux to send ``signum`` to this process when its parent dies (no-op elsewhere)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl: the services still leave on lost liveliness
        pass


STOP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM, signal.SIGHUP})


def _service_preexec(mask: Iterable[int]) -> None:
    """In a service's process before exec: it never outlives hrc run (even one killed with
    SIGKILL), it gets the signal mask hrc run had before it held the stop signals, and it has a
    process group of its own: a Ctrl-C in the terminal reaches hrc run alone, which ends the run
    over the bus so that every service writes its files (``_interrupted``)."""
    os.setpgid(0, 0)
    die_with_parent()
    signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def stop_on_signals() -> None:
    """SIGTERM and SIGHUP (a process manager, a CI timeout, a closed terminal) and the death of
    our own parent end ``hrc run`` as Ctrl-C does: run_trial's cleanup stops every service.

    Ctrl-C (SIGINT) is taken whatever this process inherited: a script's background job, nohup or
    a CI runner starts a program with SIGINT ignored, and Python then leaves it ignored, so a
    Ctrl-C (or ``kill -INT``) was lost and the trial went on."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _raise_terminated)
    parent = os.getppid()
    die_with_parent(signal.SIGTERM)
    if os.getppid() != parent:  # it died before prctl took effect
        raise Terminated(signal.SIGTERM)


def _stat(pid: int | str) -> list[str]:
    """The fields of Linux ``/proc/<pid>/stat`` after the command name (field 3, the state,
    first); OSError where there is none."""
    with open(f"/proc/{pid}/stat") as f:
        return f.read().rsplit(")", 1)[1].split()


STOPPED = "stopped (SIGSTOP or a debugger)"
FROZEN = "frozen (cgroup freezer)"


def halt(pid: int) -> str | None:
    """How the process is halted, if it is: stopped (SIGSTOP, SIGTSTP, a debugger: Linux /proc
    state T or t) or frozen by the cgroup freezer (its state then says D or S, like a process
    that waits). Either way it answers nothing; a stopped one acts on no signal but SIGKILL,
    and a frozen one (cgroup v1) not even on that until it is thawed."""
    try:
        if _stat(pid)[0] in ("T", "t"):
            return STOPPED
    except (OSError, IndexError):
        return None
    return FROZEN if frozen(pid) else None


def process_stopped(pid: int) -> bool:
    """The process is halted (:func:`halt`): stopped or frozen."""
    return halt(pid) is not None


def frozen(pid: int) -> bool:
    """The process's cgroup is frozen or freezing: cgroup v1's ``freezer.state``, or v2's
    ``cgroup.events`` (``frozen 1``), found through ``/proc/<pid>/cgroup``."""
    try:
        with open(f"/proc/{pid}/cgroup") as f:
            lines = f.read().splitlines()
    except OSError:
        return False
    for line in lines:
        _hier, controllers, path = [*line.split(":", 2), "", ""][:3]
        if "freezer" in controllers.split(","):
            state = _read(f"/sys/fs/cgroup/freezer{path}/freezer.state")
            if state.strip() in ("FROZEN", "FREEZING"):
                return True
        elif controllers == "" and path not in ("", "/"):
            for root in ("/sys/fs/cgroup", "/sys/fs/cgroup/unified"):
                if "frozen 1" in _read(f"{root}{path}/cgroup.events").splitlines():
                    return True
    return False


def _read(path: str) -> str:
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return ""


def cpu_ticks(pid: int) -> int | None:
    """CPU time the process has used so far (user + system, in clock ticks; Linux /proc)."""
    try:
        fields = _stat(pid)
        return int(fields[11]) + int(fields[12])
    except (OSError, IndexError, ValueError):
        return None


def not_responding(name: str, when: str = "", how: str = STOPPED) -> str:
    """hrc run's words for a halted service (one wording wherever it is judged); ``how``: as
    :func:`halt` says."""
    return f"service '{name}' not responding{when}: its process is {how}; hrc run ended it"


def describe_exit(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


def process_age_s() -> float | None:
    """Seconds since this process started (Linux /proc; None elsewhere): the start of the
    end-to-end wall of ``hrc run``, imports included."""
    try:
        start_ticks = int(_stat("self")[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


TIMING_FILE = "timing.json"


@dataclass
class Phases:
    """Where the wall time of one ``hrc run`` went (``services/timing.json``), all in seconds:
    ``prepare`` (process start -> services started: imports, the scenario's check, its copy),
    ``start`` (services started -> the first tick: their imports, sessions, scenario, tokens),
    ``run`` (the run phase, run/end's wall_s), ``end`` (run/end -> every service gone: the
    logger catching up, files), ``exit_by_service`` (run/end -> each service's exit)."""

    prepare: float | None = None
    start: float | None = None
    run: float | None = None
    end: float | None = None
    exit_by_service: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, object]:
        def r(v: float | None) -> float | None:
            return None if v is None else round(v, 3)

        return {
            "prepare_s": r(self.prepare),
            "start_s": r(self.start),
            "run_s": r(self.run),
            "end_s": r(self.end),
            "exit_by_service_s": {n: r(v) for n, v in self.exit_by_service.items()},
        }


class ServiceGroup:
    """The child processes of one trial."""

    def __init__(self, trial_dir: Path) -> None:
        self.logs_dir = trial_dir / "services"
        self.logs_dir.mkdir(parents=True, exist_ok=True)
        self.procs: dict[str, subprocess.Popen[bytes] | ForkedProcess] = {}
        self._files: list[IO[bytes]] = []
        self.cpu_s: dict[str, tuple[float, float]] = {}  # (user, system) of each ended service
        self.exited_at: dict[str, float] = {}  # time.monotonic() when each was seen gone

    def start(self, name: str, argv: list[str], module: str | None = None) -> None:
        """Starts service ``name`` with command line ``argv``; a Python service (``module``)
        is forked from this process where that is safe (``hrc.trial.prefork``)."""
        f = open(self.log_path(name), "wb")
        self._files.append(f)
        # a log is a file: no colour codes (Zenoh colours its lines unless told not to)
        env = dict(os.environ, PYTHONUNBUFFERED="1", NO_COLOR="1")
        log.debug("starting %s: %s", name, " ".join(argv))
        # A stop signal that arrived while Popen runs would leave a service nobody knows of
        # (the child forked, not yet on the list): held until it is on the list.
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            if module is not None and can_fork():
                in_child = functools.partial(_service_preexec, mask)
                self.procs[name] = fork_service(module, argv, f.fileno(), env, in_child)
            else:
                self.procs[name] = subprocess.Popen(
                    argv,
                    stdout=f,
                    stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL,
                    env=env,
                    preexec_fn=functools.partial(_service_preexec, mask),
                )
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)

    def _reap(self, name: str, p: subprocess.Popen[bytes] | ForkedProcess) -> int | None:
        """Like ``p.poll()``, but reaps with wait4 to keep the service's CPU time."""
        if p.returncode is None:
            try:
                pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            except ChildProcessError:
                return p.poll()
            if pid:
                p.returncode = os.waitstatus_to_exitcode(status)
                self.cpu_s[name] = (ru.ru_utime, ru.ru_stime)
        if p.returncode is not None:
            self.exited_at.setdefault(name, time.monotonic())
        return p.returncode

    def poll(self) -> dict[str, int | None]:
        return {n: self._reap(n, p) for n, p in self.procs.items()}

    def stopped(self) -> list[str]:
        """The services whose process is halted, stopped or frozen (not running, not gone), in
        table order."""
        return [n for n, p in self.procs.items() if p.returncode is None and process_stopped(p.pid)]

    def halt_of(self, name: str) -> str:
        """How service ``name`` is halted (:func:`halt`; stopped if it no longer is)."""
        return halt(self.procs[name].pid) or STOPPED

    def lift_observers(self) -> None:
        """The observers (the logger) back from SCHED_IDLE: at the run's end, when nobody waits
        on their account any more. A logger starved on a busy machine would otherwise read the
        end only after its backlog, and physics may be gone by then (hrc.bus.clock._linger)."""
        for name in service_table.OBSERVERS:
            p = self.procs.get(name)
            # (returncode, not poll(): the run thread reaps, with wait4 for the CPU figures;
            # an exited but unreaped process keeps its pid)
            if p is not None and p.returncode is None:
                priority.leave_idle(p.pid)

    def stop_all(self, grace_s: float = 2.0) -> None:
        """SIGTERM (a service writes its files within its grace), then SIGKILL; a stopped
        process gets SIGKILL at once (SIGTERM would wait for a SIGCONT that never comes)."""
        for p in self.procs.values():
            if p.poll() is None:
                if process_stopped(p.pid):
                    p.kill()
                    continue
                priority.leave_idle(p.pid)  # the logger: else it may get no CPU to stop
                p.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + grace_s
        # a frozen process (killed above) leaves only when thawed: not waited for
        held = {n for n, p in self.procs.items() if p.returncode is None and frozen(p.pid)}
        while time.monotonic() < deadline and any(
            r is None for n, r in self.poll().items() if n not in held
        ):
            time.sleep(0.01)
        for name, p in self.procs.items():
            if p.poll() is None:
                p.kill()
                if frozen(p.pid):
                    # a frozen process dies of SIGKILL only once thawed (cgroup v1): not waited
                    # for, it leaves then (and is reaped by init)
                    log.warning("service '%s' is frozen: killed, it leaves when thawed", name)
                    continue
                p.wait()

    def write_cpu(self) -> None:
        """``services/cpu.json``: each service's CPU seconds (user, system), for benches."""
        data = {
            n: {"user_s": round(u, 3), "system_s": round(s, 3)} for n, (u, s) in self.cpu_s.items()
        }
        self._write(self.logs_dir / "cpu.json", json.dumps(data, indent=1) + "\n")

    def write_timing(self, phases: Phases) -> None:
        self._write(self.logs_dir / TIMING_FILE, json.dumps(phases.to_dict(), indent=1) + "\n")

    @staticmethod
    def _write(path: Path, text: str) -> None:
        """hrc run's own small files: on a full disk said so, never a traceback (nothing half
        written is left)."""
        try:
            path.write_text(text)
        except OSError as exc:
            path.unlink(missing_ok=True)
            log.error("could not write %s: %s", path, exc.strerror or exc)

    def out_of_space(self) -> str | None:
        """The first service whose log says its disk was full."""
        for name in self.procs:
            if NO_SPACE in self.tail(name, 40):
                return name
        return None

    def close(self) -> None:
        for f in self._files:
            f.close()

    def log_path(self, name: str) -> Path:
        """Where service ``name``'s output goes."""
        return self.logs_dir / f"{name}.log"

    def own_error(self, name: str) -> str:
        """The last error service ``name`` logged of its own (not its echo of a failed run's
        end), without time stamp and logger; "" if none."""
        try:
            text = self.log_path(name).read_text(errors="replace").splitlines()
        except OSError:
            return ""
        for line in reversed(text):
            _, sep, said = line.partition(" ERROR ")
            said = said.split(": ", 1)[-1]
            if sep and not said.startswith(service_table.RUN_ENDED_WITH_ERROR):
                return said
        return ""

    def tail(self, name: str, lines: int = 15) -> str:
        try:
            text = self.log_path(name).read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(text[-lines:])


def await_leaving(group: ServiceGroup, limit_s: float) -> None:
    """Until every service has left, or ``limit_s``. Not waited for: a stopped service, and one
    that has used no CPU for LEAVE_IDLE_S (hung: a service writing its files works)."""
    deadline = time.monotonic() + limit_s
    checked = 0.0
    busy: dict[str, tuple[int | None, float]] = {}  # service -> (CPU ticks, since when)
    while time.monotonic() < deadline:
        left = [n for n, rc in group.poll().items() if rc is None]
        if not left:
            return
        now = time.monotonic()
        if now - checked >= 0.1:  # /proc reads: not every 10 ms
            checked = now
            stopped = set(group.stopped())
            idle = set()
            for n in left:
                cpu = cpu_ticks(group.procs[n].pid)
                last, since = busy.get(n, (None, now))
                if cpu != last:
                    busy[n] = (cpu, now)
                elif now - since >= LEAVE_IDLE_S:
                    idle.add(n)
            if set(left) <= stopped | idle:
                if idle - stopped:
                    hung = ", ".join(sorted(idle - stopped))
                    log.warning("%s used no CPU for %g s: not waited for", hung, LEAVE_IDLE_S)
                return
        time.sleep(0.01)
