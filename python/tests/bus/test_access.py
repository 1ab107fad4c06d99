"""A trial's bus admits only its credentials: a real Zenoh router (another process, as physics
is) refuses the links without them, says each in its log, and `count_refusals` counts them by
reason; a separate router's configuration (several hosts) checks the same credentials."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import zenoh

from hrc import service_table
from hrc.bus import access
from hrc.ports import free_port

from .conftest import wait_until

ROUTER = """
import sys, zenoh
from hrc.bus import access
access.log_refusals()
with zenoh.open(zenoh.Config.from_file(sys.argv[1])):
    sys.stdin.read()  # until the test closes it
"""


def client(endpoint: str, user: tuple[str, str] | None) -> zenoh.Session | None:
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("scouting/multicast/enabled", "false")
    cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
    cfg.insert_json5("connect/timeout_ms", "1500")
    if user is not None:
        usrpwd = {"user": user[0], "password": user[1]}
        cfg.insert_json5("transport/auth/usrpwd", json.dumps(usrpwd))
    try:
        return zenoh.open(cfg)
    except zenoh.ZError:
        return None


def start_router(
    tmp_path: Path, out: Any = subprocess.DEVNULL, env: dict[str, str] | None = None
) -> tuple[subprocess.Popen[bytes], str, dict[str, str]]:
    """A real Zenoh router (another process) with the router.json5 `hrc deploy-access` writes
    for session s1, on a free loopback port: the process, its endpoint and the users'
    passwords."""
    folder = tmp_path / "s1"
    access.make_private(folder)
    access.write_credentials(folder, "s1", service_table.names(), router=True)
    users = dict(ln.split(":") for ln in (folder / access.USERS).read_text().splitlines())
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cfg = json.loads(access.config_path(folder, access.ROUTER).read_text())
    cfg["listen"]["endpoints"] = [endpoint]
    (tmp_path / "router.json5").write_text(json.dumps(cfg))
    router = subprocess.Popen(
        [sys.executable, "-c", ROUTER, str(tmp_path / "router.json5")],
        stdin=subprocess.PIPE,
        stdout=out,
        stderr=subprocess.STDOUT,
        env=env,
    )
    return router, endpoint, users


def test_a_credentials_file_appears_only_whole(tmp_path: Path, monkeypatch: Any) -> None:
    """A tool or a test waits for the experimenter's configuration, then opens it: once it read
    it while `hrc run` was still writing it (Zenoh: "Empty config file"). Every file of the
    folder appears under its name only whole (written aside, renamed), readable by this user
    alone, and nothing is left aside."""
    folder = tmp_path / "s1"
    access.make_private(folder)
    visible: list[tuple[str, int]] = []  # what a reader could open while a file is written
    real_fdopen = os.fdopen

    def spying_fdopen(fd: int, *args: Any, **kwargs: Any) -> Any:
        f = real_fdopen(fd, *args, **kwargs)
        write = f.write

        def spying_write(text: str) -> int:
            visible.extend(
                (p.name, p.stat().st_size) for p in folder.iterdir() if not p.name.startswith(".")
            )
            return write(text)

        f.write = spying_write
        return f

    monkeypatch.setattr(os, "fdopen", spying_fdopen)
    access.write_credentials(folder, "s1", service_table.names(), router=True)
    monkeypatch.undo()
    assert visible, "no file was written through the spy"
    assert not [v for v in visible if v[1] == 0], f"seen empty while being written: {visible}"
    names = sorted(p.name for p in folder.iterdir())
    assert f"{access.EXPERIMENTER}.json5" in names and access.USERS in names, names
    assert not [n for n in names if n.startswith(".")], f"left aside: {names}"
    for n in names:
        assert (folder / n).stat().st_mode & 0o777 == 0o600, n


@pytest.mark.parametrize("rust_log", [None, "error", "zenoh_transport=warn"])
def test_a_router_refuses_and_counts_each_link_without_the_credentials(
    tmp_path: Path, rust_log: str | None
) -> None:
    """Whatever RUST_LOG the researcher has set, the refusals are in the log."""
    log = tmp_path / "router.log"
    with log.open("wb") as out:
        env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
        if rust_log is not None:
            env["RUST_LOG"] = rust_log
        router, endpoint, users = start_router(tmp_path, out, env)
    try:
        admitted: list[zenoh.Session] = []

        def one_of_the_trial_gets_in() -> bool:
            s = client(endpoint, ("ik_cpp", users["ik_cpp"]))
            if s is not None:
                admitted.append(s)
            return s is not None

        assert wait_until(one_of_the_trial_gets_in, 30, 0.2), log.read_text()[-2000:]
        admitted.pop().close()
        for user in (None, ("orchestrator", "a guess"), ("intruder", users["ik_cpp"])):
            assert client(endpoint, user) is None, user
    finally:
        assert router.stdin is not None
        router.stdin.close()
        router.wait(20)
    counts = access.count_refusals(log)
    assert counts is not None
    # one attempt at least per client, each under its reason; none for the one let in
    assert all(counts[k] >= 1 for k in access.REFUSALS), counts
    assert sum(counts.values()) == log.read_bytes().count(b"UsrPwd"), log.read_text()


def test_a_log_that_is_not_there_is_not_counted(tmp_path: Path) -> None:
    assert access.count_refusals(tmp_path / "physics.log") is None


def may(acl: dict[str, Any], user: str, message: str, key: str) -> bool:
    """Would access control ``acl`` let ``user``'s ``message`` on ``key`` into the router? As
    Zenoh 1.10 decides (authorization.rs): default deny; an allow rule of one of the user's
    policies applies when one of its keys includes the message's whole key expression."""
    subjects = {s["id"] for s in acl["subjects"] if user in s["usernames"]}
    rules = {r["id"]: r for r in acl["rules"]}
    ke = zenoh.KeyExpr(key)
    for p in acl["policies"]:
        if not subjects & set(p["subjects"]):
            continue
        for rid in p["rules"]:
            r = rules[rid]
            applies = "ingress" in r["flows"] and message in r["messages"]
            if (
                applies
                and r["permission"] == "allow"
                and any(zenoh.KeyExpr(k).includes(ke) for k in r["key_exprs"])
            ):
                return True
    assert acl["default_permission"] == "deny"
    return False


def denied(acl: dict[str, Any], key: str) -> set[str]:
    """The users whose puts on ``key`` access control ``acl`` denies."""
    users = {u for s in acl["subjects"] for u in s["usernames"]}
    return {u for u in users if not may(acl, u, "put", key)}


def test_a_separate_router_lets_physics_publish_the_clock_and_nobody_else() -> None:
    names = [*service_table.names(), service_table.EXPERIMENTER]
    others = set(names) - {service_table.CLOCK_MASTER}
    # physics as the router: its own puts never come in, so a client in its name is denied
    assert denied(access.router_acl("s1", names), "hrc/s1/clock") == set(names)
    assert denied(access.router_acl("s1", names, separate=True), "hrc/s1/clock") == others
    assert denied(access.router_acl("s1", names, separate=True), "hrc/s1/run/end") == others


def test_every_key_is_put_on_by_its_owner_alone_whatever_expression_the_put_uses() -> None:
    names = [*service_table.names(), service_table.EXPERIMENTER]
    acl = access.router_acl("s1", names, separate=True)
    owners = access.publishers(access.Keys("s1"))
    for key, who in owners.items():
        concrete = key.replace("*", "r1")
        if "/clock/ack/" in key:  # a tool may join as an extra observer (docs/access.md)
            who = who | {service_table.EXPERIMENTER}
        assert denied(acl, concrete) == set(names) - who, key
        # a wildcard that means this key (and maybe others) is nobody's but an owner of all
        head, _, last = concrete.rpartition("/")
        for wild in (f"{head}/{last[:3]}$*", f"{head}/*", "hrc/s1/**", f"{head}/**"):
            assert denied(acl, wild) >= set(names) - who, wild
    # the stop of each sender on its own key: the key proves who sent it
    for name in (*service_table.PARTICIPANTS, service_table.EXPERIMENTER):
        assert denied(acl, f"hrc/s1/run/control/{name}") == set(names) - {name}
    assert denied(acl, "hrc/s1/run/control/*") == set(names)
    # a key outside the table (made up) is nobody's
    assert denied(acl, "hrc/s1/robot/r1/brake") == set(names)
    # answers: only the orchestrator serves the scenario, only a service its own stats
    for user in names:
        assert may(acl, user, "declare_queryable", "hrc/s1/scenario") == (user == "orchestrator")
        assert may(acl, user, "reply", "hrc/s1/stats/logger") == (user == "logger")
        token = may(acl, user, "liveliness_token", "hrc/s1/alive/ik_cpp")
        assert token == (user in ("ik_cpp", service_table.EXPERIMENTER)), user
        # asking is open to every holder of the credentials, on the session's keys only
        assert may(acl, user, "declare_subscriber", "hrc/s1/**")
        assert may(acl, user, "query", "hrc/s1/stats/physics")
        assert not may(acl, user, "declare_subscriber", "hrc/s2/**")


def test_a_real_router_drops_every_put_by_a_non_owner_wildcards_included(tmp_path: Path) -> None:
    """Each user of a trial puts on every protected key, exactly and with wildcards that mean
    it; a subscriber on the whole session receives only the owners' puts."""
    names = service_table.names()
    router, endpoint, users = start_router(tmp_path)
    sessions: dict[str, zenoh.Session] = {}
    try:
        for user in [*names, service_table.EXPERIMENTER]:

            def joined(user: str = user) -> bool:
                s = client(endpoint, (user, users[user]))
                if s is not None:
                    sessions[user] = s
                return s is not None

            assert wait_until(joined, 30, 0.2), user
        got: list[tuple[str, bytes]] = []
        # a session of its own: a session's own puts reach its subscribers without the router
        reader = client(endpoint, (service_table.EXPERIMENTER, users[service_table.EXPERIMENTER]))
        assert reader is not None
        sessions["reader"] = reader
        sub = reader.declare_subscriber(
            "hrc/s1/**", lambda s: got.append((str(s.key_expr), s.payload.to_bytes()))
        )
        # the router learns of the subscription a moment later (seconds on a loaded machine):
        # an owner's probe arrives once it has, and only then do the forgers begin
        clock_owner = sessions[service_table.CLOCK_MASTER]

        def probed() -> bool:
            clock_owner.put("hrc/s1/clock", b"probe")
            return any(g[1] == b"probe" for g in got)

        assert wait_until(probed, 30, 0.2), "the reader's subscription never reached the router"
        owners = access.publishers(access.Keys("s1"))
        sent_ok: set[tuple[str, bytes]] = set()
        for key, who in sorted(owners.items()):
            concrete = key.replace("*", "r1")
            head, _, last = concrete.rpartition("/")
            for user, s in sessions.items():
                ack = user == service_table.EXPERIMENTER and "/clock/ack/" in key
                if user == "reader" or user in who or ack:  # ack: a tool's right (access.md)
                    continue
                for expr in (concrete, f"{head}/{last[:3]}$*", f"{head}/*", f"{head}/**"):
                    s.put(expr, b"forged by " + user.encode())
            owner = sorted(who)[0]
            sessions[owner].put(concrete, b"owner " + owner.encode())
            sent_ok.add((concrete, b"owner " + owner.encode()))
        # the owners' puts arrive (each after every forgery on its key: the order of one
        # session's puts is kept, the forgers' came first)
        assert wait_until(lambda: {g for g in got if g[1].startswith(b"owner")} >= sent_ok, 20), (
            sorted(sent_ok - set(got))
        )
        forged = [g for g in got if g[1].startswith(b"forged")]
        assert not forged, forged[:10]
        sub.undeclare()
    finally:
        for s in sessions.values():
            s.close()
        assert router.stdin is not None
        router.stdin.close()
        router.wait(20)
