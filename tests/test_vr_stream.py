"""The bridge streams the world to participant clients (issue 13; docs/client-protocol.md).

Full live trials (all five services, ``--input vr``, realtime) with Python WebSocket clients:
one drives the hands through the task, others watch, misbehave or never read.
"""

from __future__ import annotations

import base64
import os
import re
import socket
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from hrc.bench.client import REST_LEFT, REST_RIGHT, LiveClient, connect_when_up, grab, move
from hrc.ports import free_port

from .conftest import ROOT
from .goldens import MINIMAL

pytestmark = [pytest.mark.slow, pytest.mark.e2e]


def live(tmp_path: Path, ik_bin: Path, name: str = "trial"):
    from hrc.bench.client import live_trial

    port = free_port()
    return port, live_trial(MINIMAL, tmp_path / name, port, stall_timeout_s=0.0)


def place_h1(driver: LiveClient, scene: dict) -> None:
    """The driver does the participant's part of minimal.toml: H1 onto its target."""
    h1 = next(p for p in scene["parts"] if p["id"] == "H1")
    above = grab(driver, h1)
    tx, ty, tz = h1["target"]["xyz"]
    over = (tx, ty, tz + 0.10)
    move(driver, above, over, 1.0, REST_LEFT)
    release = (tx, ty, tz + 0.018)
    move(driver, over, release, 1.0, REST_LEFT, 10)
    driver.hands(REST_LEFT, release, 0.0, 0.0)
    move(driver, release, over, 0.0, REST_LEFT, 10)
    move(driver, over, REST_RIGHT, 0.0, REST_LEFT)  # out of the robots' way


def of_kind(client: LiveClient, kind: str, timeout: float = 30.0) -> dict:
    got = client.wait_for(lambda m: m.msg.get("type") == kind, timeout)
    assert got is not None, f"no {kind} message; got {[m.msg.get('type') for m in client.messages]}"
    return got[1].msg


def stalled_client(port: int) -> socket.socket:
    """A WebSocket client that opens the connection and never reads a byte (a tiny receive
    window, so the bridge's sends to it block within a second or two)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        (
            "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n"
        ).encode()
    )
    return sock


def get(url: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=10) as resp:
            return resp.status, resp.read()
    except urllib.error.HTTPError as exc:
        return exc.code, b""


def test_clients_get_scene_frames_and_events_of_a_live_trial(tmp_path, ik_bin) -> None:
    port, trial = live(tmp_path, ik_bin)
    ws_url = f"ws://127.0.0.1:{port}/ws"
    with trial as (_session, result):
        driver = connect_when_up(ws_url)
        spectator = connect_when_up(ws_url)
        try:
            hello = of_kind(driver, "hello")
            assert hello["protocol"] == 1 and hello["role"] == "driver"
            assert hello["scenario"] == "minimal"
            assert of_kind(spectator, "hello")["role"] == "spectator"

            scene = of_kind(driver, "scene")
            assert {p["id"] for p in scene["parts"]} == {"H1", "RA1", "S1"}
            h1 = next(p for p in scene["parts"] if p["id"] == "H1")
            assert h1["kind"] == "terminal block" and h1["start"]["xyz"] == [-0.2, -0.38, 0.02]
            assert re.fullmatch(r"#[0-9a-f]{6}", h1["color"])
            r1 = next(r for r in scene["robots"] if r["id"] == "r1")
            assert r1["color"] == "#ebc823"  # yellow, as the scenario says
            assert r1["urdf_url"] == "/robots/arm5.urdf" and len(r1["joint_names"]) == 5
            assert next(p for p in scene["parts"] if p["id"] == "RA1")["color"] == r1["color"]
            assert {c["id"] for c in scene["cues"]} >= {"target:RA1", "outline:H1", "waiting:r2"}
            assert scene["continue_button"] == [0.4, -0.3, 0.02]
            assert scene["board"]["size"] == [0.6, 0.4, 0.02]

            # the page's files: the URDF the scene names; nothing outside it
            http = f"http://127.0.0.1:{port}"
            status, body = get(http + r1["urdf_url"])
            assert status == 200 and body == (ROOT / "robots" / "arm5.urdf").read_bytes()
            for bad in (
                "/robots/../scenarios/minimal.toml",
                "/robots/%2e%2e/scenarios/minimal.toml",
                "/robots/panda.urdf",  # a robot file, but not this scenario's
                "/robots/..%2f..%2fpyproject.toml",
                "/assets/../../../pyproject.toml",
                "/etc/passwd",
            ):
                assert get(http + bad)[0] == 404, bad
            assert get(http + "/")[0] == 200

            # the first frame has everything; the robots' joints in the scene's order
            first = of_kind(driver, "frame", 150)  # the logger may take long to start
            assert set(first["objects"]) == {"H1", "RA1"}  # S1 comes from the feeder later
            assert first["run"] == "waiting_first_grab" and first["task_t_s"] is None

            # bad frames: an error each, and nothing changes
            driver.send({"type": "subscribe", "rate_hz": 1000})
            driver.send({"type": "launch"})
            driver.ws.send("{not json")
            driver.hands(REST_LEFT, (0.0, 0.0, 0.3), 0.0, float("nan"))
            spectator.hands(REST_LEFT, (0.0, 0.0, 0.3), 0.0, 1.0)
            assert driver.wait_for(lambda m: len(driver.of_type("error")) >= 4, 10)
            errors = " | ".join(e["error"] for e in driver.of_type("error"))
            for words in ("rate_hz", "unknown message type 'launch'", "not valid JSON", "grip"):
                assert words in errors, errors
            assert of_kind(spectator, "error")["error"].startswith("spectator")
            driver.send({"type": "ping", "id": 7, "client_time_ms": 12.5})
            pong = of_kind(driver, "pong")
            assert pong["id"] == 7 and pong["client_time_ms"] == 12.5

            place_h1(driver, scene)
            placed = driver.wait_for(
                lambda m: m.msg.get("kind") == "part_placed" and m.msg.get("part") == "H1", 120
            )
            assert placed is not None, [m.msg for m in driver.messages if m.msg["type"] != "frame"]
            ev = placed[1].msg
            assert ev["hand"] == "right" and ev["task_t_s"] > 0
            # the spectator saw the same, and the driver's hands moving in its frames
            assert spectator.wait_for(lambda m: m.msg.get("kind") == "part_placed", 10)
            assert any(
                m.msg["hands"].get("right", {}).get("grip") == 1.0
                for m in spectator.messages
                if m.msg.get("type") == "frame"
            )
            # neither the malformed sample nor the spectator's ever moved the hands
            assert all(
                m.msg["hands"]["right"]["p"] != [0.0, 0.0, 0.3]
                for m in driver.messages
                if m.msg.get("type") == "frame"
            )
            # the robots appear in frames: joints (scene order) and TCP; the task then finishes
            assert set(driver.robots) == {"r1", "r2"}
            assert len(driver.robots["r1"]["q"]) == 5 and len(driver.robots["r1"]["tcp"]) == 3
            done = driver.wait_for(
                lambda m: m.msg.get("type") == "run" and m.msg["state"] == "finished", 180
            )
            assert done is not None
            kinds = [m.msg["kind"] for m in driver.messages if m.msg.get("type") == "event"]
            assert kinds[0] == "task_started" and "task_finished" in kinds
            assert kinds.count("part_placed") == 3
            assert driver.objects["H1"]["placed"] is True

            # only what changed: most frames carry no robot or object at all
            frames = [m.msg for m in driver.messages if m.msg.get("type") == "frame"]
            assert [f["seq"] for f in frames] == list(range(1, len(frames) + 1))
            assert sum(1 for f in frames if not f["objects"]) > len(frames) / 4

            # the driver leaves: the spectator becomes the driver
            mark = len(spectator.messages)
            driver.close()
            promoted = spectator.wait_for(lambda m: m.msg.get("type") == "hello", 10, mark)
            assert promoted is not None and promoted[1].msg["role"] == "driver"
        finally:
            driver.close()
            spectator.close()
    r = result()
    assert r is not None and r.ok, r.message if r else "no result"


def test_a_stalled_client_neither_slows_the_trial_nor_the_others(tmp_path, ik_bin) -> None:
    port, trial = live(tmp_path, ik_bin)
    ws_url = f"ws://127.0.0.1:{port}/ws"
    with trial as (_session, result):
        driver = connect_when_up(ws_url)
        stalled = stalled_client(port)
        stalled_port = stalled.getsockname()[1]
        try:
            scene = of_kind(driver, "scene")
            place_h1(driver, scene)
            done = driver.wait_for(
                lambda m: m.msg.get("type") == "run" and m.msg["state"] == "finished", 180
            )
            assert done is not None, "the task did not finish with a stalled client attached"
            # it got frames to the end (the `run` message is an event; the frame that shows the
            # end comes at the driver's next frame slot)
            last = driver.wait_for(
                lambda m: m.msg.get("type") == "frame" and m.msg["run"] == "finished", 30
            )
            assert last is not None, "no frame showed the finished run"
        finally:
            driver.close()
            stalled.close()
    r = result()
    assert r is not None and r.ok, r.message if r else "no result"
    log = (tmp_path / "trial" / "services" / "human_input.log").read_text()
    # the tick never waited on a client: a send that blocked the tick thread would take seconds
    # (timings are not asserted otherwise: the machine may be loaded)
    compute = re.search(r"hrc.bus.lockstep: \d+ ticks; mean us per tick: .*compute (\d+)", log)
    assert compute is not None and int(compute.group(1)) < 20_000, compute
    summary = re.search(r"VR bridge: .* (\d+) frames sent, (\d+) dropped", log)
    assert summary is not None, log[-2000:]
    assert int(summary.group(2)) > 10, summary.group(0)
    # the stalled client's frames: a few until the buffers filled up, then dropped; the
    # driver's: all it was due
    per_client = {
        int(p): (int(a), int(b))
        for p, a, b in re.findall(
            r"VR client [\d.]+:(\d+) \(\w+\) left: (\d+) frames, (\d+) dropped", log
        )
    }
    assert len(per_client) == 2 and stalled_port in per_client, per_client
    stalled_sent, stalled_dropped = per_client.pop(stalled_port)
    ((driver_sent, driver_dropped),) = per_client.values()
    assert stalled_dropped > stalled_sent, per_client
    assert driver_sent > stalled_sent and driver_dropped <= driver_sent / 10, (
        driver_sent,
        driver_dropped,
        stalled_sent,
    )


def test_a_live_trial_nobody_joins_ends_naming_the_url(tmp_path, ik_bin) -> None:
    from hrc.trial import TrialOptions, VrOptions, run_trial

    port = free_port()
    opts = TrialOptions(
        scenario=MINIMAL,
        out=tmp_path / "trial",
        mode="realtime",
        input="vr",
        vr=VrOptions(port=port, wait_s=2.0),
    )
    result = run_trial(opts, opts.out)
    assert not result.ok and result.exit_code == 3 and result.failed_service == "human_input"
    assert "no VR client connected within 2 s (--vr-wait): nobody opened" in result.message
    assert f"http://127.0.0.1:{port}/" in result.message
