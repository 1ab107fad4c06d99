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


@pytest.mark.parametrize("rust_log", [None, "error", "zenoh_transport=warn"])
def test_a_router_refuses_and_counts_each_link_without_the_credentials(
    tmp_path: Path, rust_log: str | None
) -> None:
    """Whatever RUST_LOG the researcher has set, the refusals are in the log."""
    folder = tmp_path / "s1"
    access.make_private(folder)
    access.write_credentials(folder, "s1", service_table.names(), router=True)
    users = dict(ln.split(":") for ln in (folder / access.USERS).read_text().splitlines())
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cfg = json.loads(access.config_path(folder, access.ROUTER).read_text())
    cfg["listen"]["endpoints"] = [endpoint]
    (tmp_path / "router.json5").write_text(json.dumps(cfg))
    log = tmp_path / "router.log"
    with log.open("wb") as out:
        env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
        if rust_log is not None:
            env["RUST_LOG"] = rust_log
        router = subprocess.Popen(
            [sys.executable, "-c", ROUTER, str(tmp_path / "router.json5")],
            stdin=subprocess.PIPE,
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
        )
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


def denied(acl: dict[str, Any], key: str) -> set[str]:
    """The users whose puts on ``key`` access control ``acl`` denies."""
    rules = {r["id"] for r in acl["rules"] if key in r["key_exprs"]}
    subjects = {s["id"]: s["usernames"] for s in acl["subjects"]}
    return {
        u
        for p in acl["policies"]
        if rules & set(p["rules"])
        for s in p["subjects"]
        for u in subjects[s]
    }


def test_a_separate_router_lets_physics_publish_the_clock_and_nobody_else() -> None:
    names = [*service_table.names(), access.EXPERIMENTER]
    others = set(names) - {service_table.CLOCK_MASTER}
    # physics as the router: its own puts never come in, so a client in its name is denied
    assert denied(access.router_acl("s1", names), "hrc/s1/clock") == set(names)
    assert denied(access.router_acl("s1", names, separate=True), "hrc/s1/clock") == others
    assert denied(access.router_acl("s1", names, separate=True), "hrc/s1/run/end") == others
