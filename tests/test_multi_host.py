"""The several-hosts recipe of docs/multi-host.md, on one machine: `hrc deploy-access` writes the
session's credentials and a router's configuration, `hrc router` runs with it, and the five
services join as clients with their own files. The router refuses a client without credentials
(and says so in its log), keeps every key to its own publisher (an insider cannot end the run or
publish the clock), and the run finishes as if nobody had tried."""

from __future__ import annotations

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


@pytest.mark.timeout(420)
def test_a_session_over_a_router_admits_only_its_own_services(tmp_path: Path, ik_bin: Path) -> None:
    session = f"mh{os.getpid()}"
    folder = tmp_path / "access" / session
    made = subprocess.run(
        [HRC, "deploy-access", "--session", session, "--out", str(folder)],
        capture_output=True,
        text=True,
    )
    assert made.returncode == 0, made.stderr
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
        commands = {
            "physics": [str(BIN / "hrc-physics"), "--clock", "lockstep", "--ticks", "0"],
            "ik_cpp": [str(ik_bin)],
            "orchestrator": [
                str(BIN / "hrc-orchestrator"),
                "--scenario",
                str(ROOT / "scenarios" / "thesis.toml"),
                "--out",
                str(out),
            ],
            "human_input": [str(BIN / "hrc-human-input")],
        }
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
        logger = [str(BIN / "hrc-logger"), "--out", str(out), *common]
        start("logger", [*logger, "--zenoh-config", str(folder / "logger.json5")])
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
