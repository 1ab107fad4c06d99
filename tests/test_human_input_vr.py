"""human_input as a real process on a real Zenoh bus, driven by a real WebSocket client and by
headless Chromium running the served page. The test process plays the orchestrator (serves the
scenario) and the clock master (as physics does), so these tests need no other service."""

from __future__ import annotations

import itertools
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from websockets.sync.client import connect

from hrc import scenario as sc
from hrc.bus import Bus, BusConfig, ClockMaster, ClockSettings
from hrc.paths import project_root
from hrc.ports import free_port
from hrc.wire import pb

ROOT = project_root()
pytestmark = pytest.mark.slow


@dataclass
class Rig:
    session: str
    port: int
    vr_port: int
    states: list[pb.HumanState] = field(default_factory=list)
    proc: subprocess.Popen | None = None
    lock: threading.Lock = field(default_factory=threading.Lock)

    def right(self) -> list[tuple[float, float, float, float]]:
        with self.lock:
            return [
                (
                    s.right_hand.position.x,
                    s.right_hand.position.y,
                    s.right_hand.position.z,
                    s.right_grip,
                )
                for s in self.states
            ]

    def wait(self, pred, timeout: float = 30.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if pred():
                return True
            time.sleep(0.02)
        return False


def service_cmd(session: str, port: int, *extra: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "hrc_human_input",
        "--session",
        session,
        "--connect",
        f"tcp/127.0.0.1:{port}",
        *extra,
    ]


@contextmanager
def rig(*extra: str, tick_hz: float = 60.0) -> Iterator[Rig]:
    session = f"hi{uuid.uuid4().hex[:8]}"
    r = Rig(session, free_port(), free_port())
    scen = sc.to_proto(sc.load(ROOT / "scenarios" / "minimal.toml"))
    scen.participant.input = pb.INPUT_SOURCE_VR
    scen.info.tick_hz = tick_hz
    with Bus(BusConfig(session=session, listen=[f"tcp/127.0.0.1:{r.port}"]), "physics") as bus:
        scen.header.session = session
        bus.queryable(bus.keys.scenario(), None, lambda _req: scen)
        clock = ClockMaster(
            bus,
            ClockSettings(
                mode="realtime",
                tick_hz=tick_hz,
                ticks=0,
                participants=["human_input"],
                observers=[],
                start_timeout_s=60.0,
            ),
        )

        def on_state(_k: str, msg: pb.HumanState) -> None:
            with r.lock:
                r.states.append(msg)

        clock.input(bus.keys.human_state(), pb.HumanState, on_state)
        clock.start()
        log = open(Path(tempfile.gettempdir()) / f"{session}.log", "wb")
        r.proc = subprocess.Popen(
            service_cmd(session, r.port, "--vr-port", str(r.vr_port), *extra),
            stdout=log,
            stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
        )
        ended: list[pb.RunEnd] = []
        th = threading.Thread(
            target=lambda: ended.append(clock.run(lambda k, t: None, lambda k, t: None)),
            daemon=True,
        )
        th.start()
        try:
            yield r
        finally:
            bus.publisher(bus.keys.run_control(bus.sender)).put(
                pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason="test done")
            )
            th.join(timeout=20)
            try:
                rc = r.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                r.proc.kill()
                rc = r.proc.wait()
            log.close()
            text = Path(log.name).read_text(errors="replace")
            assert rc == 0, f"human_input exited {rc}:\n{text[-3000:]}"


def wait_bridge(port: int, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1):
                return
        except OSError:
            time.sleep(0.1)
    raise AssertionError(f"VR bridge never listened on {port}")


def next_of(ws, kind: str, timeout: float = 10.0) -> dict:
    """The next message of type ``kind`` (the bridge also streams scene, frames and events)."""
    end = time.monotonic() + timeout
    while True:
        msg = json.loads(ws.recv(timeout=max(0.01, end - time.monotonic())))
        if msg["type"] == kind:
            return msg


def pose(p: list[float]) -> dict:
    return {"position": p, "orientation": [0, 0, 0, 1]}


def test_websocket_client_streams_a_reach_onto_the_bus() -> None:
    with rig() as r:
        wait_bridge(r.vr_port)
        start, goal = (0.22, -0.56, 0.10), (-0.10, -0.05, 0.08)
        with connect(f"ws://127.0.0.1:{r.vr_port}/ws") as ws:
            assert json.loads(ws.recv(timeout=10))["type"] == "hello"
            n = 40
            for i in range(n + 1):
                tau = i / n
                s = tau**3 * (10 - 15 * tau + 6 * tau**2)
                p = [a + (b - a) * s for a, b in zip(start, goal, strict=True)]
                ws.send(
                    json.dumps(
                        {
                            "head": pose([0, -0.7, 0.6]),
                            "left": pose([-0.22, -0.56, 0.1]),
                            "right": pose(p),
                            "left_grip": 0.0,
                            "right_grip": 1.0 if i == n else 0.0,
                        }
                    )
                )
                if i == n // 2:  # a malformed frame mid-reach gets an error and changes nothing
                    ws.send(json.dumps({"head": pose([0, 0, 0]), "right_grip": "full"}))
                    reply = next_of(ws, "error")
                    assert "right_grip" in reply["error"]
                time.sleep(0.05)
            assert r.wait(lambda: any(g == 1.0 for *_p, g in r.right()))
        got = r.right()
        # the bus followed the reach: from the rest pose towards the goal, never backwards
        xs = [x for x, *_ in got]
        moving = [x for x in xs if start[0] - 1e-9 >= x >= goal[0] - 1e-9]
        assert len(set(moving)) >= 5, "too few intermediate samples relayed"
        assert all(b <= a + 1e-9 for a, b in itertools.pairwise(moving))
        last = got[-1]
        assert last[:3] == pytest.approx(goal) and last[3] == 1.0
        with r.lock:
            assert all(s.source == pb.INPUT_SOURCE_VR for s in r.states)
        # the malformed frame never reached the bus
        assert all(abs(y) < 1.0 for _x, y, _z, _g in got)


def test_non_loopback_bind_without_token_is_refused() -> None:
    proc = subprocess.run(
        service_cmd("refused", free_port(), "--input", "vr", "--vr-host", "0.0.0.0"),
        capture_output=True,
        text=True,
        timeout=60,
        env={k: v for k, v in os.environ.items() if k != "HRC_VR_TOKEN"},
    )
    assert proc.returncode == 2
    assert "without a token" in proc.stderr


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def test_headless_chromium_page_streams_onto_the_bus() -> None:
    if chromium() is None:
        pytest.fail("Debian's chromium is missing: scripts/setup.sh installs it")
    target = (0.05, -0.10, 0.12)
    # the minimal fallback page (its demo mode); the participant client has its own tests
    with (
        rig("--vr-client-dir", "/nonexistent") as r,
        tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as profile,
    ):
        wait_bridge(r.vr_port)
        url = f"http://127.0.0.1:{r.vr_port}/?demo=1&tx={target[0]}&ty={target[1]}&tz={target[2]}"
        browser = subprocess.Popen(
            [
                chromium(),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--no-first-run",
                f"--user-data-dir={profile}",
                "--remote-debugging-port=0",
                url,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:

            def arrived() -> bool:
                got = r.right()
                return (
                    bool(got)
                    and got[-1][3] == 1.0
                    and got[-1][:3] == pytest.approx(target, abs=0.012)
                )

            assert r.wait(arrived, timeout=90), f"last right hand: {r.right()[-1:]}"
        finally:
            browser.terminate()
            try:
                browser.wait(timeout=10)
            except subprocess.TimeoutExpired:
                browser.kill()
                browser.wait()
        xs = {round(x, 4) for x, *_ in r.right()}
        assert len(xs) >= 5, "the page's mouse reach did not arrive as a motion"
