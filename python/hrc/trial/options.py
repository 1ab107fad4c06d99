"""What one trial is asked to do (TrialOptions, VrOptions), what it gave (TrialResult), where
its files go, and the command line of each of its services (built from the service table,
hrc.service_table)."""

from __future__ import annotations

import datetime as dt
import logging
import sys
from dataclasses import dataclass, field
from pathlib import Path

from hrc import service_table
from hrc.bus.access import TrialAccess
from hrc.paths import build_dir
from hrc.scenario.resolved import Resolved, slug
from hrc.wire import pb

log = logging.getLogger(__name__)


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
    view: bool = True  # False: no 3D recording (recording.rrd); the logs and metrics as always
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

    host: str = service_table.VR_DEFAULT_HOST
    port: int = service_table.VR_DEFAULT_PORT
    wait_s: float = service_table.VR_DEFAULT_WAIT_S  # for the first client; then the trial fails
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
        return service_table.vr_client_url(
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


def awaits_watcher(opts: TrialOptions) -> bool:
    """Whether physics's first tick waits for hrc run's own session (``--watchers``), so that
    a run of a few ticks cannot end before hrc run listens: on one host. On a bus of several
    hosts physics keeps Zenoh's start-up delay (it connects to a router), which covers it."""
    return not opts.connect


def trial_settings(
    opts: TrialOptions,
    session: str,
    port: int,
    trial_dir: Path,
    sock: Path | None = None,
    lowlatency: bool = False,
    access: TrialAccess | None = None,
) -> service_table.Settings:
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
    return service_table.Settings(
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
        no_view=not opts.view,
        watchers=service_table.EXPERIMENTER if awaits_watcher(opts) else None,
    )


def program(svc: service_table.Service) -> list[str]:
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
    svc = service_table.service(name)
    settings = trial_settings(opts, session, port, trial_dir, sock, lowlatency, access)
    own: list[str] = []
    if name == "human_input":
        own += ["--input", opts.input] if opts.input else []
        own += opts.vr.argv() if opts.vr is not None else []
    return program(svc) + service_table.argv(svc, settings) + own + opts.extra.get(name, [])
