"""The services of a session, declared once: name, program, options, barrier role, needs.

Everything that starts services reads this table:

- ``hrc run`` (``hrc.trial``) builds every process's command line with :func:`argv`;
- the clock master (physics, ``hrc.bus.ClockSettings``) takes the barrier's participants and
  observers from it, and the others learn the clock master's name from it (``--clock-master``,
  which every command line built here passes explicitly);
- ``hrc deploy-files`` writes ``deploy/process-compose.yaml`` and ``deploy/compose.yaml`` from it
  (``hrc.deploy_files``; a test keeps the committed files equal to the generated ones).

Why a typed Python table rather than a YAML file like dora-rs's ``dataflow.yml``: the command
lines are not fixed strings but depend on the deployment (a trial's socket, seed and options for
``hrc run``; ``{{.X}}`` variables for process-compose; ``${HRC_X}`` for compose), so a file would
need a template language of its own; the bus library reads the table at import time, where a file
would have to be found on disk; and mypy checks every use of it.

Readiness is the same for every service: it declares the liveliness token ``alive/<name>`` once
everything it subscribes to exists (``hrc alive NAME`` is the probe).
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass


class Role(enum.Enum):
    """A service's part in the tick protocol."""

    CLOCK_MASTER = "clock master"  # publishes the clock, waits for the participants' acks
    PARTICIPANT = "participant"  # computes each tick and acks it: closes the barrier
    OBSERVER = "observer"  # follows the clock, never acks; must be present at the start


@dataclass(frozen=True)
class Settings:
    """The values one deployment gives the services' options.

    Strings, because a deploy file gives placeholders (``{{.SESSION}}``, ``${HRC_TICKS:-0}``).
    An option whose setting is None, False, empty or () is left out of the command line.
    """

    session: str | None = None
    bus: str = ""  # the endpoint every other service connects to
    listen: tuple[str, ...] = ()  # where the clock master listens (``bus`` among them)
    connect: tuple[str, ...] = ()  # more endpoints for every service (a router)
    lowlatency: bool = False  # Zenoh's low-latency transport (all services, or none)
    # each service's Zenoh configuration file (its credentials); "{service}" stands for its name
    zenoh_config: str | None = None
    clock: str = ""  # lockstep | realtime
    ticks: str = ""  # 0: until the task ends
    barrier_timeout: str | None = None
    start_timeout: str | None = None
    scenario: str = ""
    out: str = ""  # the trial folder
    seed: str | None = None
    no_reach_check: bool = False  # the caller has just run the motion check
    keep_running: bool = False  # the orchestrator does not stop the run at the task's end
    stall_timeout: str | None = None  # the watchdog's timeout (None: the scenario's)
    record: str | None = None
    replay: str | None = None
    viewer: bool = False
    web: bool = False
    web_port: str | None = None  # the rerun web viewer's HTTP port (None: the logger's 9090)
    grpc_port: str | None = None  # the port the web viewer reads the data from
    no_view: bool = False  # the logger writes no 3D recording (a study that needs the metrics)
    # tools the clock master waits for before the first tick (their tokens), as it does for the
    # services, but which never hold the clock nor end the run by leaving: hrc run's own watch
    # of the run, which must not miss a short run's end
    watchers: str | None = None


Value = str | bool | tuple[str, ...] | None
SETTINGS = frozenset(f.name for f in dataclasses.fields(Settings))


@dataclass(frozen=True)
class Option:
    """``flag`` with the value of ``setting`` (a switch for a bool, repeated for a tuple), or the
    fixed ``value``."""

    flag: str
    setting: str | None = None
    value: str | None = None
    required: bool = False  # a deployment that leaves it out is an error

    def __post_init__(self) -> None:
        if (self.setting is None) == (self.value is None):
            raise ValueError(f"{self.flag}: give a setting or a fixed value")
        if self.setting is not None and self.setting not in SETTINGS:
            raise ValueError(f"{self.flag}: no setting {self.setting!r}")

    def argv(self, settings: Settings, service: str) -> list[str]:
        value: Value = self.value if self.setting is None else getattr(settings, self.setting)
        if value is None or value is False or value == "" or value == ():
            if self.required:
                raise ValueError(f"{service}: {self.flag} needs the setting {self.setting!r}")
            return []
        if value is True:
            return [self.flag]
        if isinstance(value, tuple):
            return [token for v in value for token in (self.flag, v)]
        if self.setting == "zenoh_config":
            value = value.replace("{service}", service)
        return [self.flag, value]


@dataclass(frozen=True)
class Service:
    name: str  # also its bus name: alive/<name>, clock/ack/<name>, stats/<name>
    role: Role
    description: str
    script: str  # the installed command (console script, or the C++ binary's name)
    module: str | None = None  # Python: started as ``python -m <module>``
    binary: str | None = None  # C++: the executable, relative to the build folder
    options: tuple[Option, ...] = ()  # its own options (the bus and role ones are added)
    needs: tuple[str, ...] = ()  # what must be there besides the .venv
    stop_timeout_s: int = 10  # how long it may take to finish its files after SIGTERM

    def __post_init__(self) -> None:
        if (self.module is None) == (self.binary is None):
            raise ValueError(f"{self.name}: give a Python module or a binary")

    @property
    def ready_token(self) -> str:
        """The liveliness key (under ``hrc/<session>/``) that says the service is ready."""
        return f"alive/{self.name}"


SERVICES: tuple[Service, ...] = (
    # The clock master comes first: the others connect to it, so it is started first.
    Service(
        "physics",
        Role.CLOCK_MASTER,
        "world + clock master (pybullet)",
        script="hrc-physics",
        module="hrc_physics",
        options=(
            Option("--clock", "clock", required=True),
            Option("--ticks", "ticks", required=True),
            Option("--barrier-timeout", "barrier_timeout"),
            Option("--start-timeout", "start_timeout"),
        ),
    ),
    Service(
        "ik_cpp",
        Role.PARTICIPANT,
        "both arms: Cartesian motion + IK (C++/KDL)",
        script="hrc-ik",
        binary="ik_cpp/hrc-ik",
        needs=("the C++ build (scripts/setup.sh)",),
    ),
    Service(
        "orchestrator",
        Role.PARTICIPANT,
        "scenario, task logic, metrics",
        script="hrc-orchestrator",
        module="hrc_orchestrator",
        options=(
            Option("--scenario", "scenario", required=True),
            Option("--out", "out", required=True),
            Option("--no-reach-check", "no_reach_check"),
            Option("--seed", "seed"),
            Option("--keep-running", "keep_running"),
            Option("--stall-timeout", "stall_timeout"),
        ),
    ),
    Service(
        "human_input",
        Role.PARTICIPANT,
        "participant: scripted, replay or live VR bridge",
        script="hrc-human-input",
        module="hrc_human_input",
        options=(Option("--record", "record"), Option("--replay", "replay")),
        needs=("a headset's browser that reaches the bridge, for the scenario's input = vr",),
    ),
    Service(
        "logger",
        Role.OBSERVER,
        "observer: rerun recording, log.txt, events.jsonl",
        script="hrc-logger",
        module="hrc_logger",
        options=(
            Option("--out", "out", required=True),
            Option("--viewer", "viewer"),
            Option("--web", "web"),
            Option("--web-port", "web_port"),
            Option("--grpc-port", "grpc_port"),
            Option("--no-view", "no_view"),
        ),
        needs=("a display, for --viewer",),
        stop_timeout_s=20,  # it closes the .rrd and flushes its files on SIGTERM
    ),
)


def names() -> tuple[str, ...]:
    """Every service, the clock master first (the start order)."""
    return tuple(s.name for s in SERVICES)


def service(name: str) -> Service:
    for s in SERVICES:
        if s.name == name:
            return s
    raise KeyError(f"no service {name!r} (the services are {', '.join(names())})")


def with_role(role: Role) -> tuple[str, ...]:
    return tuple(s.name for s in SERVICES if s.role is role)


def _one_clock_master() -> str:
    masters = with_role(Role.CLOCK_MASTER)
    if len(masters) != 1:
        raise ValueError(f"the table needs exactly one clock master, has {masters}")
    return masters[0]


CLOCK_MASTER = _one_clock_master()
PARTICIPANTS = with_role(Role.PARTICIPANT)  # their acks close the barrier
OBSERVERS = with_role(Role.OBSERVER)
# Not a service: hrc run's own bus session, and the tools and tests that join a trial with its
# credentials (hrc.bus.access). It may stop a run, and blame a service whose process ended.
EXPERIMENTER = "experimenter"
# After SIGTERM / SIGINT a service has this long to write its files (hrc run waits a little more)
STOP_GRACE_S = 2.0
# How a service's log says that the run it followed failed (hrc run tells that echo from the
# service's own errors)
RUN_ENDED_WITH_ERROR = "run ended with an error"


def _role_options(role: Role) -> tuple[Option, ...]:
    """What every service of a role is given, before its own options.

    Star topology: the clock master's session is a Zenoh router and every other service a client
    of it, so a route between any two services exists as soon as both have announced themselves
    (peer-to-peer links would form later, by gossip, and could miss the first messages).
    """
    common: tuple[Option, ...] = (
        Option("--session", "session"),
        Option("--zenoh-config", "zenoh_config"),
    )
    if role is not Role.OBSERVER:
        # An observer's link stays on the standard transport, where the router may drop what
        # it cannot take instead of blocking (hrc.bus.access.router_qos).
        common = (*common, Option("--zenoh-lowlatency", "lowlatency"))
    router = Option("--connect", "connect")
    if role is Role.CLOCK_MASTER:
        return (
            *common,
            Option("--zenoh-mode", value="router"),
            Option("--listen", "listen", required=True),
            router,
            Option("--participants", value=",".join(PARTICIPANTS)),
            Option("--observers", value=",".join(OBSERVERS)),
            Option("--watchers", "watchers"),
        )
    return (
        *common,
        Option("--zenoh-mode", value="client"),
        Option("--connect", "bus", required=True),
        router,
        Option("--clock-master", value=CLOCK_MASTER),
    )


def argv(svc: Service, settings: Settings) -> list[str]:
    """The arguments of ``svc`` (without the program) in a deployment with ``settings``."""
    return [
        token
        for opt in (*_role_options(svc.role), *svc.options)
        for token in opt.argv(settings, svc.name)
    ]


# human_input's VR bridge (input vr): where it listens by default, and how long a live trial waits
# for its first client; the service's options and hrc run's take these defaults.
VR_DEFAULT_HOST = "127.0.0.1"
VR_DEFAULT_PORT = 8765
VR_DEFAULT_WAIT_S = 300.0


def vr_client_url(host: str, port: int, token: str | None = None, driver: str | None = None) -> str:
    """The participant client's page served by human_input's VR bridge on ``host:port`` (with
    the token, and the participant's driver key, in the query when given): what ``hrc run
    --input vr`` prints."""
    from urllib.parse import urlencode

    shown = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    if ":" in shown and not shown.startswith("["):
        shown = f"[{shown}]"
    query = {k: v for k, v in (("token", token), ("driver", driver)) if v}
    return f"http://{shown}:{port}/" + (f"?{urlencode(query)}" if query else "")
