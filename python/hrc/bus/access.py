"""Who may reach a trial's bus on this machine: the trial's private folder.

``hrc run`` keeps, for each trial, a folder only this user may enter,
``<tmp>/hrc-<uid>/<session>/``, holding

- ``bus.sock``: the Unix socket the services meet on (no other local user can open it);
- ``users``: the Zenoh user/password dictionary physics (the router) checks every link
  against, one random password per service and one for the experimenter's tools;
- ``<name>.json5``: the Zenoh configuration each service (and ``experimenter``: ``hrc run``'s
  own watcher, tools, tests) opens its session with, holding its user and password;
- ``pid``: the ``hrc run`` that owns it.

A client without these credentials, on the socket or on the TCP port, is refused by Zenoh's
authentication when its link opens. Among those who have them, physics's access control denies
by default and lets only a key's own publisher put on it (:func:`publishers`), whatever key
expression the put uses: only the participants (a stop, an abort) and the experimenter end a run,
each on its own ``run/control/<name>``, only physics publishes the clock and ``run/end``, only the
orchestrator commands the robots and writes task events; a put from anyone else is dropped by the
router (:func:`router_acl`).

``hrc run`` removes the folder when it ends; a run killed with SIGKILL cannot, so every ``hrc run``
first removes the folders of runs that are gone. A session started from ``deploy/`` gets the same
files from ``hrc deploy-access`` (:func:`write_credentials`), in a folder it names.
"""

from __future__ import annotations

import json
import logging
import os
import re
import secrets
import shutil
import stat
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import zenoh

from hrc.bus.config import BusConfig
from hrc.bus.keys import Keys
from hrc.service_table import CLOCK_MASTER, EXPERIMENTER, OBSERVERS, PARTICIPANTS
from hrc.service_table import names as service_names

log = logging.getLogger(__name__)

SOCKET = "bus.sock"
USERS = "users"
OWNER = "pid"
ROUTER = "router"  # router.json5: a separate router's configuration (several hosts)
# The router's queue towards each link, in 64 KiB batches (Zenoh's maximum): what an observer
# has not taken yet waits there (hrc.bus.clock's window keeps lockstep well inside it).
ROUTER_QUEUE_BATCHES = 16
# How long a client's attempt to (re)open its link may take (Zenoh's default: 10 s). A stopped
# router still accepts connections in the kernel but never answers: a client that lost it must
# not spend 10 s in a reconnect attempt before it can close its session and leave.
OPEN_TIMEOUT_MS = 1000
MAX_SOCKET_PATH = 100  # bytes: a Unix socket path must fit sun_path (108 on Linux)
NEW_FOLDER_S = 60.0  # a folder without its pid file this young may be a run starting now


# Zenoh says a link it refused at authentication only in a debug line of its accept step. A router
# (physics, `hrc router`) turns on just that target, on its standard output (the service's log),
# beside Zenoh's errors (or what RUST_LOG asks for). hrc run counts the lines after
# the run (count_refusals).
REFUSAL_LOG_TARGET = "zenoh_transport::unicast::establishment::accept=debug"
# The reasons of Zenoh 1.10's user-password check (zenoh-transport, ext/auth/usrpwd.rs), by the
# field of pb.AccessMetrics each is counted in.
REFUSALS = {
    "no_credentials": "UsrPwd extension - Recv InitSyn. Expected extension.",
    "unknown_user": "UsrPwd extension - Recv OpenSyn. Invalid user.",
    "wrong_password": "UsrPwd extension - Recv OpenSyn. Invalid password.",
}
_ANSI = re.compile(rb"\x1b\[[0-9;]*m")  # Zenoh colours its log lines even into a file


# What every process writes of Zenoh's own log when RUST_LOG says nothing: its errors only (a
# transport it closed because a message could not be queued for 5 s, and with it the messages
# still queued, is said only there); quiet in a trial that goes well.
ZENOH_LOG_DEFAULT = "error"


def init_zenoh_log(router: bool = False) -> None:
    """Has Zenoh write what RUST_LOG asks for (default: its errors) to standard output (the
    service's log), and a router each link it refuses (once a process: later calls change
    nothing)."""
    directives = os.environ.get("RUST_LOG") or ZENOH_LOG_DEFAULT
    if router:
        # the later directive wins for its target: the refusals are counted whatever RUST_LOG says
        directives = f"{directives},{REFUSAL_LOG_TARGET}"
    os.environ["RUST_LOG"] = directives
    zenoh.init_log_from_env_or(directives)


def log_refusals() -> None:
    """Has Zenoh write each link this process refuses to its standard output, beside what
    RUST_LOG asks for (default: Zenoh's errors)."""
    init_zenoh_log(router=True)


def count_refusals(router_log: Path) -> dict[str, int] | None:
    """The links refused for want of credentials, by reason (the fields of pb.AccessMetrics),
    as the router's log ``router_log`` says them; None if it cannot be read."""
    counts = dict.fromkeys(REFUSALS, 0)
    try:
        with router_log.open("rb") as f:
            for raw in f:
                if b"UsrPwd" not in raw:
                    continue
                line = _ANSI.sub(b"", raw).decode("utf-8", "replace")
                for field, said in REFUSALS.items():
                    if said in line:
                        counts[field] += 1
    except OSError as exc:
        log.debug("refused links not counted: %s", exc)
        return None
    return counts


def _root() -> Path:
    return Path(tempfile.gettempdir()) / f"hrc-{os.getuid()}"


def make_private(path: Path, parents: bool = False) -> None:
    """``path`` made, or checked, as a folder of this user's that nobody else may enter (mode
    0700); ValueError if it is something else or another user's, OSError if it cannot be made."""
    path.mkdir(mode=0o700, parents=parents, exist_ok=True)
    st = path.lstat()
    if not stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{path} is not a folder")
    if st.st_uid != os.getuid():
        raise ValueError(f"{path} belongs to another user (uid {st.st_uid})")
    if stat.S_IMODE(st.st_mode) != 0o700:
        path.chmod(0o700)


def private_root() -> Path | None:
    """This user's folder of trial folders (mode 0700), or None if it cannot be made so."""
    path = _root()
    try:
        make_private(path)
    except ValueError:
        log.warning("%s is not this user's folder: the trial's bus is not protected", path)
        return None
    except OSError as exc:
        log.warning("no private folder for the trial (%s): its bus is not protected", exc)
        return None
    return path


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def sweep(root: Path) -> list[Path]:
    """Removes the folders of trials whose ``hrc run`` is gone; returns them."""
    gone: list[Path] = []
    for folder in root.iterdir():
        if not folder.is_dir() or folder.is_symlink():
            continue
        try:
            pid = int((folder / OWNER).read_text())
        except (OSError, ValueError):
            try:
                if time.time() - folder.lstat().st_mtime < NEW_FOLDER_S:
                    continue  # being made by a run starting now
            except OSError:
                continue
            pid = 0
        if pid and _alive(pid):
            continue
        shutil.rmtree(folder, ignore_errors=True)
        gone.append(folder)
    return gone


def _write_private(path: Path, text: str) -> None:
    """``text`` in a file only this user may read, renamed into place whole: a tool or a test
    that waits for the file (:func:`join`) opened the experimenter's configuration once while
    ``hrc run`` was still writing it, and Zenoh refused it as empty."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise


def publishers(keys: Keys) -> dict[str, frozenset[str]]:
    """Who may put on each key of a trial (docs/ARCHITECTURE.md, "Key expressions"): a put on
    any other key, or by anyone else, is dropped by the router (:func:`router_acl`)."""
    orchestrator = frozenset({"orchestrator"})
    physics = frozenset({CLOCK_MASTER})
    table = {
        keys.clock(): physics,
        keys.run_end(): physics,
        keys.world_objects(): physics,
        keys.world_contacts(): physics,
        keys.world_separation(): physics,
        keys.robot_commands(): orchestrator,
        keys.world_commands(): orchestrator,
        keys.task_events(): orchestrator,
        keys.task_indicators(): orchestrator,
        keys.task_metrics(): orchestrator,
        keys.robot_states(): frozenset({"ik_cpp"}),
        keys.human_state(): frozenset({"human_input"}),
        keys.human_clients(): frozenset({"human_input"}),
    }
    for name in (*PARTICIPANTS, *OBSERVERS):
        table[keys.clock_ack(name)] = frozenset({name})
    # A stop: the orchestrator (task finished, stalled) or the experimenter; an abort: any
    # participant whose tick failed (docs/ARCHITECTURE.md, "Roles"). Each on a key of its own:
    # the key proves the sender (hrc.bus.clock.control_problem).
    for name in (*PARTICIPANTS, EXPERIMENTER):
        table[keys.run_control(name)] = frozenset({name})
    return table


def answerers(keys: Keys) -> dict[str, frozenset[str]]:
    """Who may answer queries on each queryable key of a trial (a forged scenario or reach
    answer would steer it as surely as a put)."""
    table = {
        keys.scenario(): frozenset({"orchestrator"}),
        keys.robot_reach(): frozenset({"ik_cpp"}),
    }
    for name in service_names():
        table[keys.stats(name)] = frozenset({name})
        table[keys.replay(name)] = frozenset({name})
    return table


# What a holder of a trial's credentials may always send the router: asking (subscriptions,
# queries, liveliness queries) never changes a trial. Everything else is denied unless a rule
# below grants it, whatever key expression (wildcards included) it uses.
_READ = ["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"]
_ALL = [*_READ, "put", "delete", "declare_queryable", "reply", "liveliness_token"]


def observer_ids(names: Iterable[str]) -> dict[str, str]:
    """A fresh Zenoh id for each observer: the router recognises their links by it. (Zenoh
    refuses an id written with a leading 0: the top bit is set.)"""
    return {n: format(secrets.randbits(64) | 1 << 63, "x") for n in names if n in OBSERVERS}


def router_qos(observer_zids: Iterable[str]) -> dict[str, object]:
    """The router's side of "observers never hold the clock": every message it forwards to an
    observer may be dropped when that observer's queue is full (a frozen or starved logger),
    instead of blocking the router, and with it everyone. The observer sees the loss as gaps in
    the sequence numbers and records it. (Only on Zenoh's standard transport: observers never
    ask for the low-latency one, which writes to the socket on the sender's thread.)"""
    zids = sorted(observer_zids)
    qos: dict[str, object] = {}
    if zids:
        qos["network"] = [
            {
                "id": "observers_never_block",
                "zids": zids,
                "messages": ["put", "delete"],
                "flows": ["egress"],
                # batched: the queue holds 16 batches, and an express message takes one of
                # its own, so a logger a few messages behind would already lose some
                "overwrite": {"congestion_control": "drop", "express": False},
            }
        ]
    return qos


def router_acl(session: str, users: Iterable[str], separate: bool = False) -> dict[str, object]:
    """Zenoh access control for the router (the clock master, or a ``separate`` router that
    every service is a client of). Default deny: what comes in from a user is dropped unless it
    only asks (subscriptions, queries, on the session's keys), or is a put on a key of
    :func:`publishers` that the user owns, an answer on a key of :func:`answerers` it owns, or
    its own liveliness token ``alive/<user>``. Zenoh applies an allow rule only when the rule's
    key includes the message's whole key expression, so a put with a wildcard
    (``run/contr$*``) is denied unless the user owns every key it could mean. What the router
    sends out is not restricted. The clock master's own messages are not incoming when it is
    the router: a client that logs in with its name (stolen credentials) may only ask."""
    everyone = sorted(set(users))
    keys = Keys(session)
    own = frozenset() if separate else frozenset({CLOCK_MASTER})
    rules: list[dict[str, object]] = [
        _rule("read", ["ingress"], _READ, [keys.all()]),
        _rule("out", ["egress"], _ALL, ["**"]),
    ]
    policies: list[dict[str, list[str]]] = [{"rules": ["read", "out"], "subjects": ["all"]}]
    subjects: list[dict[str, object]] = [{"id": "all", "usernames": everyone}]
    puts = publishers(keys)
    answers = answerers(keys)
    for n, user in enumerate(everyone):
        if user in own:
            continue
        mine: list[str] = []
        put_keys = sorted(k for k, who in puts.items() if user in who)
        if put_keys:
            rules.append(_rule(f"put{n}", ["ingress"], ["put", "delete"], put_keys))
            mine.append(f"put{n}")
        answer_keys = sorted(k for k, who in answers.items() if user in who)
        if answer_keys:
            rules.append(_rule(f"ans{n}", ["ingress"], ["declare_queryable", "reply"], answer_keys))
            mine.append(f"ans{n}")
        if user in service_names():
            rules.append(_rule(f"tok{n}", ["ingress"], ["liveliness_token"], [keys.alive(user)]))
            mine.append(f"tok{n}")
        elif user == EXPERIMENTER:
            # A tool may join as an extra observer (a token, acks in the clock's window). The
            # experimenter is the user who ran the trial and holds every service's credentials
            # anyway: its rights are for tools, the boundary is around the services'.
            rules.append(_rule(f"tok{n}", ["ingress"], ["liveliness_token"], [keys.alive_all()]))
            rules.append(_rule(f"ack{n}", ["ingress"], ["put"], [keys.clock_acks()]))
            mine += [f"tok{n}", f"ack{n}"]
        if mine:
            subjects.append({"id": f"u{n}", "usernames": [user]})
            policies.append({"rules": mine, "subjects": [f"u{n}"]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def _rule(
    rid: str, flows: list[str], messages: list[str], key_exprs: list[str]
) -> dict[str, object]:
    return {
        "id": rid,
        "messages": messages,
        "flows": flows,
        "permission": "allow",
        "key_exprs": key_exprs,
    }


def write_credentials(
    folder: Path,
    session: str,
    users: Iterable[str],
    authenticate: bool = True,
    router: bool = False,
    lease_s: float | None = None,
) -> None:
    """Writes into ``folder`` (which only this user may enter) the credentials of ``users`` and
    the experimenter: one random password each, their dictionary (``users``), and one Zenoh
    configuration file per name (see the module's doc); with ``router`` also ``router.json5``,
    the configuration of a separate router that every service is a client of (several hosts:
    docs/multi-host.md). Paths inside the files are ``folder``'s as given: every process must see
    the folder at that path (a relative one: from the same working directory). Without
    ``authenticate`` the files hold no credentials. ``lease_s``: how long a link may be silent
    before the other end closes it (Zenoh's lease; its default, 10 s, if None), for every file
    but the observers': a host cut off is then gone for the others, and the run ends naming a
    participant on it, after about that long plus physics's 1 s grace."""
    names = [*dict.fromkeys([*users, EXPERIMENTER])]
    passwords = {n: secrets.token_hex(16) for n in names}
    zids = observer_ids(names)
    _write_private(folder / USERS, "".join(f"{n}:{p}\n" for n, p in passwords.items()))
    if router:
        _write_private(
            config_path(folder, ROUTER),
            json.dumps(
                _with_lease(_router_config(folder, session, names, zids, authenticate), lease_s),
                indent=1,
            )
            + "\n",
        )
    for n, p in passwords.items():
        usrpwd: dict[str, str] = {"user": n, "password": p}
        if n != EXPERIMENTER:
            # whoever listens (the clock master; any service could) checks its peers
            usrpwd["dictionary_file"] = str(folder / USERS)
        cfg: dict[str, object] = {}
        transport: dict[str, object] = {}
        if n in zids:
            cfg["id"] = zids[n]
        if n == CLOCK_MASTER:
            _as_router(cfg, transport, session, names, zids, authenticate)
        else:
            transport["unicast"] = {"open_timeout": OPEN_TIMEOUT_MS}
        if authenticate:
            transport["auth"] = {"usrpwd": usrpwd}
        if transport:
            cfg["transport"] = transport
        # not an observer's: at idle priority on a busy host it may not send its keep-alives
        # for a while, and nothing waits for it (the participants' leases end the run)
        cfg = _with_lease(cfg, None if n in OBSERVERS else lease_s)
        _write_private(config_path(folder, n), json.dumps(cfg, indent=1) + "\n")


LEASE_KEEPALIVES = 4  # Zenoh's: a silent link sends this many keep-alives per lease


def _with_lease(cfg: dict[str, object], lease_s: float | None) -> dict[str, object]:
    """``cfg`` with Zenoh's link lease set to ``lease_s`` (unchanged if None)."""
    if lease_s is None:
        return cfg
    if not lease_s > 0:
        raise ValueError(f"the lease must be > 0 s, got {lease_s}")
    transport = cfg.setdefault("transport", {})
    assert isinstance(transport, dict)
    tx = transport.setdefault("link", {}).setdefault("tx", {})
    tx["lease"] = max(1, round(lease_s * 1000))
    tx["keep_alive"] = LEASE_KEEPALIVES
    return cfg


def _as_router(
    cfg: dict[str, object],
    transport: dict[str, object],
    session: str,
    names: list[str],
    zids: dict[str, str],
    authenticate: bool,
    separate: bool = False,
) -> None:
    """What the router of a session's bus (physics, or a ``separate`` one) adds to its
    configuration ``cfg`` and its ``transport`` section: the observers' QoS, its queue and, with
    credentials, access control."""
    if qos := router_qos(zids.values()):
        cfg["qos"] = qos
    transport["link"] = {"tx": {"queue": {"size": {"data": ROUTER_QUEUE_BATCHES}}}}
    if authenticate:
        cfg["access_control"] = router_acl(session, names, separate)


def _router_config(
    folder: Path, session: str, names: list[str], zids: dict[str, str], authenticate: bool
) -> dict[str, object]:
    """A separate router's configuration: what physics's holds when it is the router (the
    dictionary, access control, the observers' QoS, its queue), and the listening and scouting
    of deploy/zenoh-router.json5 (every interface, port 7447; no multicast)."""
    transport: dict[str, object] = {}
    cfg: dict[str, object] = {
        "mode": "router",
        "listen": {"endpoints": ["tcp/0.0.0.0:7447"]},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True}},
        "transport": transport,
    }
    _as_router(cfg, transport, session, names, zids, authenticate, separate=True)
    if authenticate:
        transport["auth"] = {"usrpwd": {"dictionary_file": str(folder / USERS)}}
    return cfg


def config_path(folder: Path, name: str) -> Path:
    """The Zenoh configuration file of service (or tool) ``name`` in a credentials folder."""
    return folder / f"{name}.json5"


@dataclass(frozen=True)
class TrialAccess:
    """One trial's private folder (see the module's doc)."""

    folder: Path

    @classmethod
    def create(
        cls, session: str, users: Iterable[str], authenticate: bool = True
    ) -> TrialAccess | None:
        """Makes the folder of ``session`` with credentials for ``users`` and the
        experimenter; None where no private folder can be had (the bus is then open to every
        local user, as said in the log). Without ``authenticate`` (a trial that joins routers
        of other hosts, which know none of these) the configuration files hold no
        credentials."""
        root = private_root()
        if root is None:
            return None
        sweep(root)
        folder = root / session
        try:
            folder.mkdir(mode=0o700)
        except FileExistsError:
            log.warning("%s exists: another run with session %r?", folder, session)
            return None
        except OSError as exc:
            log.warning("no private folder for the trial (%s): its bus is not protected", exc)
            return None
        access = cls(folder)
        _write_private(folder / OWNER, str(os.getpid()))
        write_credentials(folder, session, users, authenticate)
        return access

    @property
    def socket(self) -> Path | None:
        """The Unix socket's path; None if it would be too long for one."""
        path = self.folder / SOCKET
        return path if len(str(path)) <= MAX_SOCKET_PATH else None

    def config(self, name: str) -> Path:
        """The Zenoh configuration file of service (or tool) ``name``."""
        return config_path(self.folder, name)

    def remove(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def join(session: str, port: int, timeout_s: float = 60.0) -> BusConfig:
    """How a tool on this machine joins the running trial ``session`` (``hrc run`` listening on
    TCP ``port``): as the experimenter, with the credentials ``hrc run`` wrote before it
    started the services (waited for up to ``timeout_s``)."""
    deadline = time.monotonic() + timeout_s
    while (config := tool_config(session)) is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if config is None:
        raise TimeoutError(f"no trial {session!r} on this machine (no credentials for it)")
    return BusConfig(
        session=session,
        mode="client",
        connect=[f"tcp/127.0.0.1:{port}"],
        listen=[],
        config_file=str(config),
    )


def as_tool(cfg: BusConfig) -> BusConfig:
    """``cfg`` of a tool (``hrc alive``, ``hrc echo``) given no Zenoh configuration file: for a
    trial ``hrc run`` runs on this machine, the experimenter's, with its credentials."""
    if cfg.config_file is None:
        found = tool_config(cfg.session)
        cfg.config_file = str(found) if found is not None else None
    return cfg


def tool_config(session: str) -> Path | None:
    """The experimenter's Zenoh configuration of the running trial ``session`` on this machine
    (for tools and tests that join its bus); None if there is none."""
    path = _root() / session / f"{EXPERIMENTER}.json5"
    return path if path.is_file() else None
