"""The several-hosts recipe of docs/multi-host.md, on one machine: `hrc deploy-access` writes the
session's credentials and a router's configuration, `hrc router` runs with it, and the five
services join as clients with their own files. The router refuses a client without credentials
(and says so in its log), keeps every key to its own publisher (an insider cannot end the run or
publish the clock), and the run finishes as if nobody had tried."""

from __future__ import annotations

import datetime as dt
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from hrc.bus import Bus, BusConfig, Keys, access
from hrc.wire import pb

from .conftest import HRC, ROOT, free_port, wait_until
from .goldens import MINIMAL, normalised
from .netns import Hosts
from .test_intruders import FORGED, forge, intruder

pytestmark = [pytest.mark.e2e]
BIN = Path(sys.executable).parent


def delivered(router: str, cfg: Path, session: str, key: str, sender: Path, msg: pb.RunEnd) -> bool:
    """Whether ``msg``, put on ``key`` by a client with the credentials ``sender``, reaches a
    subscriber with ``cfg``'s through the router."""
    got: list[bytes] = []

    def config(path: Path) -> BusConfig:
        return BusConfig(
            session=session, mode="client", connect=[router], listen=[], config_file=str(path)
        )

    with Bus(config(cfg), "experimenter") as watcher:
        sub = watcher.session.declare_subscriber(key, lambda s: got.append(bytes(s.payload)))
        with Bus(config(sender), "insider") as insider:
            pub = insider.session.declare_publisher(key)
            # a few puts, until the first arrives or for 5 s: routes form within a moment
            wait_until(lambda: pub.put(msg.SerializeToString()) or bool(got), 5, 0.25)
        sub.undeclare()
    return bool(got)


def deploy_access(tmp_path: Path, session: str) -> Path:
    """docs/multi-host.md, step 0: the session's credentials and router.json5 (hrc
    deploy-access); returns their folder."""
    folder = tmp_path / "access" / session
    made = subprocess.run(
        [HRC, "deploy-access", "--session", session, "--out", str(folder)],
        capture_output=True,
        text=True,
    )
    assert made.returncode == 0, made.stderr
    return folder


def service_commands(ik_bin: Path, scenario: Path, out: Path) -> dict[str, list[str]]:
    """docs/multi-host.md, step 2: each service's command line, before the bus options."""
    return {
        "physics": [str(BIN / "hrc-physics"), "--clock", "lockstep", "--ticks", "0"],
        "ik_cpp": [str(ik_bin)],
        "orchestrator": [
            str(BIN / "hrc-orchestrator"),
            "--scenario",
            str(scenario),
            "--out",
            str(out),
        ],
        "human_input": [str(BIN / "hrc-human-input")],
        "logger": [str(BIN / "hrc-logger"), "--out", str(out)],
    }


@pytest.mark.timeout(420)
def test_a_session_over_a_router_admits_only_its_own_services(tmp_path: Path, ik_bin: Path) -> None:
    session = f"mh{os.getpid()}"
    folder = deploy_access(tmp_path, session)
    router_ep = f"tcp/127.0.0.1:{free_port()}"
    procs: dict[str, subprocess.Popen[bytes]] = {}
    logs = tmp_path / "logs"
    logs.mkdir()

    def start(name: str, argv: list[str]) -> None:
        with (logs / f"{name}.log").open("wb") as out:
            procs[name] = subprocess.Popen(
                argv,
                stdout=out,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )

    start(
        "router",
        [HRC, "router", "--config", str(folder / "router.json5"), "--listen", router_ep],
    )
    try:
        experimenter = folder / "experimenter.json5"
        keys = Keys(session)
        # Insiders, through the router before the run: a service's credentials put only on its
        # own keys (a forged end of the run goes nowhere, the human's state does)
        human = folder / "human_input.json5"
        end = pb.RunEnd(ok=True, reason=FORGED)
        assert wait_until(
            lambda: delivered(router_ep, experimenter, session, keys.human_state(), human, end),
            30,
            0.5,
        ), (logs / "router.log").read_text()[-2000:]
        assert intruder(router_ep, None) is None, "a client without credentials got in"
        assert not delivered(router_ep, experimenter, session, keys.run_end(), human, end)
        assert not delivered(router_ep, experimenter, session, keys.clock(), human, end)
        physics = folder / "physics.json5"
        assert delivered(router_ep, experimenter, session, keys.run_end(), physics, end)
        # docs/multi-host.md, step 2: every service a client of the router, with its own file
        common = ["--session", session, "--zenoh-mode", "client", "--connect", router_ep]
        out = tmp_path / "trial"
        # the two-part board: the run starts only once the logger joins, after the intruders
        commands = service_commands(ik_bin, MINIMAL, out)
        logger = commands.pop("logger")
        for name, argv in commands.items():
            start(name, [*argv, *common, "--zenoh-config", str(folder / f"{name}.json5")])
        # Intruders while the session gathers (physics waits for the logger's token before the
        # first tick): none gets in, so what they would forge never reaches the run
        admitted = []
        for user in (None, ("orchestrator", "a guess"), ("intruder", "x")):
            s = intruder(router_ep, user)
            if s is not None:
                admitted.append(user)
                forge(s, keys)
                s.close()
        assert not admitted, admitted
        start("logger", [*logger, *common, "--zenoh-config", str(folder / "logger.json5")])
        for name in ("physics", "ik_cpp", "orchestrator", "human_input", "logger"):
            try:
                rc = procs[name].wait(300)
            except subprocess.TimeoutExpired:
                pytest.fail(f"{name} still running after 300 s")
            assert rc == 0, f"{name} exited {rc}:\n{(logs / f'{name}.log').read_text()[-2000:]}"
    finally:
        for p in procs.values():
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
                p.wait(30)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["run"]["ok"] is True, metrics["run"]
    assert metrics["task"]["finished"] is True, metrics["task"]
    assert FORGED not in (out / "log.txt").read_text()
    assert FORGED not in (out / "events.jsonl").read_text()
    # the router says each link it refused, by reason
    refused = access.count_refusals(logs / "router.log")
    assert refused is not None and all(refused[k] >= 1 for k in access.REFUSALS), refused


# --- two hosts: network namespaces joined by a cable (tests/netns.py) -----------------------
COMPUTE = ("physics", "ik_cpp")  # on the router's host; the others on the second host
WORKSTATION = ("orchestrator", "human_input", "logger")
LOG_TIME = "%Y-%m-%d %H:%M:%S,%f"  # hrc.logsetup's asctime
RUNNER_SECTIONS = {"access", "recording"}


def _split_trial(
    hosts: Hosts, tmp_path: Path, ik_bin: Path, scenario: Path, out: Path
) -> dict[str, subprocess.Popen[bytes]]:
    """docs/multi-host.md over a cable: the router, physics and ik_cpp on host a; the
    orchestrator, human_input and the logger on host b, all clients of the router."""
    session = f"nh{os.getpid()}"
    folder = deploy_access(tmp_path, session)
    addr_a, _addr_b = hosts.cable("a", "b")
    router = f"tcp/{addr_a}:7447"
    hosts.start("a", "router", [HRC, "router", "--config", str(folder / "router.json5")])
    common = ["--session", session, "--zenoh-mode", "client", "--connect", router]
    commands = service_commands(ik_bin, scenario, out)
    return {
        name: hosts.start(
            "a" if name in COMPUTE else "b",
            name,
            [*argv, *common, "--zenoh-config", str(folder / f"{name}.json5")],
        )
        for name, argv in commands.items()
    }


def _only_the_router_is_left(hosts: Hosts, procs: dict[str, subprocess.Popen[bytes]]) -> None:
    router = {p.pid for p in hosts.procs} - {p.pid for p in procs.values()}
    assert wait_until(lambda: set(hosts.pids("a")) <= router and not hosts.pids("b"), 15, 0.1), (
        f"left on host a: {hosts.pids('a')} (router {router}), on host b: {hosts.pids('b')}"
    )


@pytest.mark.timeout(600)
def test_a_trial_over_two_hosts_gives_the_events_and_metrics_of_one_host(
    tmp_path: Path, ik_bin: Path
) -> None:
    one = tmp_path / "one-host"
    run = subprocess.run(
        [HRC, "run", str(MINIMAL), "--out", str(one)], capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stderr[-2000:]
    two = tmp_path / "two-hosts"
    with Hosts(f"hrc{os.getpid() % 100000}", ["a", "b"], tmp_path / "logs") as hosts:
        procs = _split_trial(hosts, tmp_path, ik_bin, MINIMAL, two)
        for name, proc in procs.items():
            try:
                rc = proc.wait(300)
            except subprocess.TimeoutExpired:
                pytest.fail(f"{name} still running after 300 s:\n{hosts.log(name)[-2000:]}")
            assert rc == 0, f"{name} exited {rc}:\n{hosts.log(name)[-2000:]}"
        _only_the_router_is_left(hosts, procs)
    a, b = normalised(one), normalised(two)
    assert b["metrics.json"]["task"]["finished"] is True
    assert len(a["events.jsonl"]) == len(b["events.jsonl"])
    for i, (x, y) in enumerate(zip(a["events.jsonl"], b["events.jsonl"], strict=True)):
        assert x == y, f"event {i} differs"
    assert a["log.txt"] == b["log.txt"]
    # hrc run fills two sections from its services' logs (refused links, the recording's
    # losses); services started by hand leave them empty
    assert b["metrics.json"]["access"] is None and b["metrics.json"]["recording"] is None
    ours = {k: v for k, v in a["metrics.json"].items() if k not in RUNNER_SECTIONS}
    assert ours == {k: v for k, v in b["metrics.json"].items() if k not in RUNNER_SECTIONS}


@pytest.mark.timeout(600)
def test_a_cable_pulled_mid_run_ends_the_trial_within_2_s_naming_who_is_gone(
    tmp_path: Path, ik_bin: Path
) -> None:
    out = tmp_path / "trial"
    with Hosts(f"hrc{os.getpid() % 100000}", ["a", "b"], tmp_path / "logs") as hosts:
        procs = _split_trial(hosts, tmp_path, ik_bin, ROOT / "scenarios" / "thesis.toml", out)
        events = out / "events.jsonl"

        def running() -> bool:  # a few task events recorded: the run is under way
            return events.exists() and len(events.read_text().splitlines()) >= 3

        assert wait_until(running, 180, 0.05), hosts.log("physics")[-2000:]
        cut_at = dt.datetime.now()
        hosts.cut("a", "b")
        for name, proc in procs.items():
            try:
                rc = proc.wait(30)
            except subprocess.TimeoutExpired:
                pytest.fail(f"{name} still running 30 s after the cut:\n{hosts.log(name)[-2000:]}")
            assert rc != 0, f"{name} exited 0 after the cut:\n{hosts.log(name)[-2000:]}"
        _only_the_router_is_left(hosts, procs)
        physics = hosts.log("physics")
    failed = [line for line in physics.splitlines() if "run failed:" in line]
    assert failed, physics[-2000:]
    ended_at = dt.datetime.strptime(" ".join(failed[0].split()[:2]), LOG_TIME)
    took = (ended_at - cut_at).total_seconds()
    print(f"the run ended {took:.2f} s after the cut: {failed[0]}")
    assert any(f"service '{name}' left the bus" in failed[0] for name in WORKSTATION), failed[0]
    assert took <= 2.0, failed[0]
