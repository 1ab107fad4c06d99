"""``hrc run``: start the five services of one trial as separate processes and watch them.

The trial ends when physics publishes ``run/end``. A service that dies before that ends the trial:
the others are stopped, the dead one is named, and the exit status is non-zero. Every service's
own log goes to ``<trial>/services/<name>.log``.
"""

from __future__ import annotations

import datetime as dt
import functools
import json
import logging
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from hrc import metrics as metrics_schema
from hrc import priority, services
from hrc.bus import Bus, BusConfig
from hrc.bus.access import EXPERIMENTER, TrialAccess, count_refusals
from hrc.cli.console import LiveConsole
from hrc.cli.prefork import ForkedProcess, can_fork, fork_service
from hrc.diskspace import NO_SPACE, low_space
from hrc.paths import build_dir
from hrc.ports import free_port, release_port
from hrc.scenario.resolved import Resolved, slug
from hrc.wire import pb

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


@dataclass
class TrialOptions:
    scenario: Path
    out: Path | None = None
    mode: str = "lockstep"
    seed: int | None = None
    ticks: int = 0  # > 0: run exactly this many ticks, even past the task's end
    max_ticks: int = 0  # > 0: stop here at the latest (the task's end stops it earlier)
    session: str | None = None
    port: int = 0  # tcp/127.0.0.1:<port> physics listens on (0: a free one)
    unix_socket: bool = True  # the services meet on a Unix socket (else on the TCP port)
    lowlatency: bool = False  # Zenoh's low-latency transport (if the scenario fits)
    barrier_timeout_s: float = 10.0
    stall_timeout_s: float | None = None  # None: the scenario's stall_timeout_s
    start_timeout_s: float = 60.0
    viewer: bool = False
    web: bool = False
    web_port: int = 0  # > 0: the rerun web viewer's port (its data port then a free one)
    grpc_port: int = 0
    record: Path | None = None
    replay: Path | None = None
    connect: list[str] = field(default_factory=list)  # extra endpoints for every service (router)
    validated: bool = False  # the scenario file was fully checked (reach included) just before
    input: str | None = None  # the participant's input, overriding the scenario's
    vr: VrOptions | None = None  # the input is vr: the bridge's options
    participant: str = ""  # a live trial's participant id (its console shows it)
    parts_total: int = 0  # a live trial's number of parts (its console counts placements)
    extra: dict[str, list[str]] = field(default_factory=dict)  # per-service extra arguments


VR_START_MARGIN_S = 30.0  # physics waits this much longer than human_input waits for a client


@dataclass
class VrOptions:
    """A live trial's bridge (human_input's --vr-* options; the token comes from HRC_VR_TOKEN)."""

    host: str = services.VR_DEFAULT_HOST
    port: int = services.VR_DEFAULT_PORT
    wait_s: float = services.VR_DEFAULT_WAIT_S  # for the first client; then the trial fails
    driver: str | None = None  # the participant's key (HRC_VR_DRIVER, which the services read)

    def argv(self) -> list[str]:
        return [
            "--vr-host",
            self.host,
            "--vr-port",
            str(self.port),
            "--vr-wait",
            f"{self.wait_s:g}",
        ]

    def url(self, token: str | None, participant: bool = True) -> str:
        """The participant's link (with the driver key) or a spectator's."""
        return services.vr_client_url(
            self.host, self.port, token, self.driver if participant else None
        )


@dataclass
class TrialResult:
    ok: bool
    exit_code: int
    trial_dir: Path
    message: str
    failed_service: str = ""
    run_end: pb.RunEnd | None = None
    wall_s: float = 0.0


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


def default_trial_dir(base: Path, participant: str, name: str) -> Path:
    """``<base>/<date>/<participant>/<name>/``, never reused (``_2``, ``_3``, ... appended);
    ``name`` is `Resolved.folder_name()`: ``<scenario>_<Anticipation|Normal>[...]_<hash>``."""
    d = base / dt.date.today().isoformat() / slug(participant) / name
    n = 2
    candidate = d
    while candidate.exists():
        candidate = d.with_name(f"{d.name}_{n}")
        n += 1
    return candidate


SCENARIO_COPY = "scenario.toml"


def write_scenario_copy(trial_dir: Path, run: Resolved) -> Path:
    """The resolved scenario into the trial folder: the file every service of the trial loads."""
    trial_dir.mkdir(parents=True, exist_ok=True)
    path = trial_dir / SCENARIO_COPY
    path.write_text(run.toml(), encoding="utf-8")
    return path


DEFAULT_WEB_PORT = 9090  # the logger's defaults (services/logger/README.md)
DEFAULT_GRPC_PORT = 9877


def web_viewer_url(opts: TrialOptions) -> str:
    """What to open for ``--web``: the viewer page, told where the trial's data is."""
    web = opts.web_port or DEFAULT_WEB_PORT
    grpc = opts.grpc_port or DEFAULT_GRPC_PORT
    return f"http://127.0.0.1:{web}/?url=rerun%2Bhttp://127.0.0.1:{grpc}/proxy"


def _stat(pid: int | str) -> list[str]:
    """The fields of Linux ``/proc/<pid>/stat`` after the command name (field 3, the state,
    first); OSError where there is none."""
    with open(f"/proc/{pid}/stat") as f:
        return f.read().rsplit(")", 1)[1].split()


def process_stopped(pid: int) -> bool:
    """The process is stopped (SIGSTOP, SIGTSTP, a debugger): Linux /proc state T or t. A
    stopped service answers nothing and acts on no signal but SIGKILL."""
    try:
        return _stat(pid)[0] in ("T", "t")
    except (OSError, IndexError):
        return False


def cpu_ticks(pid: int) -> int | None:
    """CPU time the process has used so far (user + system, in clock ticks; Linux /proc)."""
    try:
        fields = _stat(pid)
        return int(fields[11]) + int(fields[12])
    except (OSError, IndexError, ValueError):
        return None


def not_responding(name: str, when: str = "") -> str:
    """hrc run's words for a stopped service (one wording wherever it is judged)."""
    return (
        f"service '{name}' not responding{when}: its process is stopped (SIGSTOP or a "
        "debugger); hrc run ended it"
    )


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
        is forked from this process where that is safe (``hrc.cli.prefork``)."""
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
        """The services whose process is stopped (not running, not gone), in table order."""
        return [n for n, p in self.procs.items() if p.returncode is None and process_stopped(p.pid)]

    def lift_observers(self) -> None:
        """The observers (the logger) back from SCHED_IDLE: at the run's end, when nobody waits
        on their account any more. A logger starved on a busy machine would otherwise read the
        end only after its backlog, and physics may be gone by then (hrc.bus.clock._linger)."""
        for name in services.OBSERVERS:
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
        while any(r is None for r in self.poll().values()) and time.monotonic() < deadline:
            time.sleep(0.01)
        for p in self.procs.values():
            if p.poll() is None:
                p.kill()
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

    def tail(self, name: str, lines: int = 15) -> str:
        try:
            text = self.log_path(name).read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(text[-lines:])


LOWLATENCY_MAX_SCENARIO_BYTES = 48 * 1024


def fits_lowlatency(scenario: Path) -> bool:
    """Zenoh's low-latency transport does not fragment: a message must fit one 64 KiB batch.
    The scenario (served on the bus) is the largest message of a trial, about 0.4 KiB a part;
    keep a margin for the rest (the full world state at tick 0, the final metrics)."""
    from hrc import scenario as sc

    try:
        size = len(sc.to_proto(sc.load(scenario, motion_check=False)).SerializeToString())
    except (sc.ScenarioError, OSError):
        return False  # the orchestrator reports what is wrong with it
    if size > LOWLATENCY_MAX_SCENARIO_BYTES:
        log.info("scenario is %d bytes on the wire: using Zenoh's standard transport", size)
        return False
    return True


def trial_settings(
    opts: TrialOptions,
    session: str,
    port: int,
    trial_dir: Path,
    sock: Path | None = None,
    lowlatency: bool = False,
    access: TrialAccess | None = None,
) -> services.Settings:
    """The values of the services' options in one trial.

    Physics listens on tcp/127.0.0.1:``port`` (for tools and other hosts) and on the Unix socket
    ``sock`` if given; the other services connect to the socket, else to the port. With
    ``access`` each service joins with its credentials (hrc.bus.access)."""
    tcp = f"tcp/127.0.0.1:{port}"
    bus = f"unixsock-stream/{sock}" if sock is not None else tcp
    start_timeout = opts.start_timeout_s
    if opts.vr is not None and opts.vr.wait_s > 0:
        # physics waits for human_input, which waits for the participant's client
        start_timeout = max(start_timeout, opts.vr.wait_s + VR_START_MARGIN_S)
    return services.Settings(
        session=session,
        bus=bus,
        listen=(tcp, bus) if sock is not None else (tcp,),
        connect=tuple(opts.connect),
        lowlatency=lowlatency,
        zenoh_config=str(access.config("{service}")) if access is not None else None,
        clock=opts.mode,
        ticks=str(opts.ticks or opts.max_ticks),
        barrier_timeout=str(opts.barrier_timeout_s),
        start_timeout=f"{start_timeout:g}",
        scenario=str(opts.scenario),
        out=str(trial_dir),
        seed=None if opts.seed is None else str(opts.seed),
        no_reach_check=opts.validated,
        keep_running=bool(opts.ticks),
        stall_timeout=None if opts.stall_timeout_s is None else str(opts.stall_timeout_s),
        record=str(opts.record) if opts.record else None,
        replay=str(opts.replay) if opts.replay else None,
        viewer=opts.viewer,
        web=opts.web,
        web_port=str(opts.web_port) if opts.web and opts.web_port else None,
        grpc_port=str(opts.grpc_port) if opts.web and opts.grpc_port else None,
    )


def program(svc: services.Service) -> list[str]:
    """How ``hrc run`` starts ``svc``: its module with this interpreter, or its built binary."""
    if svc.module is not None:
        return [sys.executable, "-m", svc.module]
    assert svc.binary is not None  # the table guarantees one of the two
    return [str(build_dir() / svc.binary)]


def service_argv(
    name: str,
    opts: TrialOptions,
    session: str,
    port: int,
    trial_dir: Path,
    sock: Path | None = None,
    lowlatency: bool = False,
    access: TrialAccess | None = None,
) -> list[str]:
    """The command line of service ``name`` in one trial (``opts.extra`` appended)."""
    svc = services.service(name)
    settings = trial_settings(opts, session, port, trial_dir, sock, lowlatency, access)
    own: list[str] = []
    if name == "human_input":
        own += ["--input", opts.input] if opts.input else []
        own += opts.vr.argv() if opts.vr is not None else []
    return program(svc) + services.argv(svc, settings) + own + opts.extra.get(name, [])


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

    def _on_end(self, _key: str, end: pb.RunEnd) -> None:
        self.end_at = time.monotonic()
        self.end = end
        self._event.set()
        try:
            self._on_end_hook()
        except Exception as exc:  # a nicety: never the watcher's end
            log.debug("after run/end: %s", exc)

    def stop_run(self, reason: str, failed_service: str = "") -> None:
        """Asks the clock master to end the run, with ``reason``: as a normal stop, or (with
        ``failed_service``) as a failure of that service, which hrc run saw end or stop. Every
        service then writes its files as at any end (metrics.json among them)."""
        ctl = pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason=reason)
        if failed_service:
            ctl.command = pb.RunControl.COMMAND_ABORT
            ctl.failed_service = failed_service
        self.bus.publisher(self.bus.keys.run_control()).put(ctl)

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


def _watch(group: ServiceGroup, console: LiveConsole | None) -> None:
    """Until a service exits: refreshes the live console (the loop below judges the exit)."""
    while all(rc is None for rc in group.poll().values()):
        if console is not None:
            console.update()
        time.sleep(0.05)


def _interrupted(group: ServiceGroup, watcher: _EndWatcher | None, exc: BaseException) -> None:
    """Ctrl-C or SIGTERM during the run: the run is ended as a stop by the experimenter, so every
    service writes its files (metrics.json with that end reason); then the caller stops them."""
    how = "Ctrl-C" if isinstance(exc, KeyboardInterrupt) else str(exc)
    _end_run(group, watcher, f"interrupted ({how})")


def _end_run(
    group: ServiceGroup, watcher: _EndWatcher | None, reason: str, failed_service: str = ""
) -> None:
    """Ends the run over the bus (see :meth:`_EndWatcher.stop_run`) and gives the services
    INTERRUPT_LEAVE_S to write their files and leave (a stopped one is not waited for); the
    caller then stops what is left."""
    if watcher is None or watcher.end is not None:
        return
    try:
        watcher.stop_run(reason, failed_service)
    except Exception as err:  # the bus is gone: the services are stopped as before
        log.debug("could not ask for the run's end: %s", err)
        return
    _await_leaving(group, INTERRUPT_LEAVE_S)


def _await_leaving(group: ServiceGroup, limit_s: float) -> None:
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
    master = services.CLOCK_MASTER
    for svc in services.SERVICES:
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
    try:
        trial_dir.mkdir(parents=True, exist_ok=True)
        group = ServiceGroup(trial_dir)
    except OSError as exc:
        return TrialResult(False, 2, trial_dir, f"cannot write to {trial_dir}: {exc.strerror}")
    watcher: _EndWatcher | None = None
    console: LiveConsole | None = None
    t0 = time.monotonic()
    phases = Phases(prepare=process_age_s())
    # (routers of other hosts know none of the trial's credentials)
    access = TrialAccess.create(session, services.names(), authenticate=not opts.connect)
    sock = access.socket if access is not None and opts.unix_socket else None
    try:
        # the table lists the clock master first: it listens where everybody else connects.
        for name in services.names():
            argv = service_argv(name, opts, session, port, trial_dir, sock, lowlatency, access)
            group.start(name, argv, services.service(name).module)
        time.sleep(0.2)
        try:
            watcher = _EndWatcher(session, port, access, on_end=group.lift_observers)
            if opts.vr is not None:
                console = LiveConsole(watcher.bus, opts.participant, opts.parts_total)
        except Exception as exc:  # the bus is optional for the CLI; process status still works
            log.debug("no run/end watcher: %s", exc)
        failed = ""
        failure = ""
        try:
            _watch(group, console)
        except (KeyboardInterrupt, Terminated) as exc:
            _interrupted(group, watcher, exc)
            raise
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
                failure = f"service '{failed}' {describe_exit(status[failed] or 0)} during the run"
                if stopped:
                    failed, failure = stopped[0], not_responding(stopped[0])
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
            _await_leaving(group, leave_s)  # hrc run returns as soon as the last one has left
        # judge by how each ended on its own, before we stop the stragglers
        status = group.poll()
        stopped = group.stopped()
        # SIGTERM: a service still writes its files (metrics.json) within its grace
        group.stop_all(grace_s=services.STOP_GRACE_S + 0.5)
        end = watcher.end if watcher else None
        wall = time.monotonic() - t0
        killed = [n for n in services.names() if (status.get(n) or 0) < 0]
        if killed and (not failed or (status.get(failed) or 0) >= 0):
            # a service killed by a signal is the root cause; the others' errors follow from it
            failed = killed[0]
            failure = f"service '{failed}' {describe_exit(status[failed] or 0)} during the run"
        phys = status.get(master)
        if not failed and phys is not None and (phys < 0 or (end is None and phys != 0)):
            # the clock master itself died: the others' errors ("clock master disappeared")
            # follow from it
            failed = master
            failure = f"service '{master}' {describe_exit(phys)} during the run"
        if (
            not failed
            and stopped
            and not (end is not None and not end.ok and end.failed_participant in stopped)
        ):
            # stopped at the end of a run that did not name it (it wrote none of its last files)
            failed = stopped[0]
            failure = not_responding(failed, " at the run's end")
        if not failed:
            bad = [n for n in services.names() if status.get(n) not in (0, None)]
            if end is not None and not end.ok:
                failed = end.failed_participant or (bad[0] if bad else master)
                failure = f"run failed: {end.reason}"
            elif bad:
                failed = bad[0]
                failure = f"service '{failed}' {describe_exit(status[failed] or 0)}"
        full = group.out_of_space() if failed or end is None or not end.ok else None
        if full is not None:
            failed = full
            failure = f"no space left on {trial_dir} (service '{full}' could not write its files)"
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
