"""The VR bridge in-process: samples, malformed frames, tokens, the served page, bind safety."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from hrc_human_input.vr_bridge import BridgeConfigError, VrBridge, check_bind, is_loopback

POSE = {"position": [0.1, -0.3, 0.2], "orientation": [0, 0, 0, 1]}
SAMPLE = {"head": POSE, "left": POSE, "right": POSE, "left_grip": 0.0, "right_grip": 1.0}


def wait_for(pred, timeout: float = 5.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return False


def test_accepts_samples_and_answers_malformed_frames() -> None:
    with (
        VrBridge("127.0.0.1", 0, hello={"scenario": "x"}) as bridge,
        connect(f"ws://127.0.0.1:{bridge.bound_port}/ws") as ws,
    ):
        hello = json.loads(ws.recv(timeout=5))
        assert hello["type"] == "hello" and hello["scenario"] == "x"
        assert hello["auth_required"] is False
        ws.send(json.dumps(SAMPLE))
        assert wait_for(lambda: bridge.latest() is not None)
        assert bridge.latest().right_grip == 1.0
        good = bridge.latest()
        for frame, words in [
            ("{nope", "not valid JSON"),
            (json.dumps({**SAMPLE, "left_grip": 2}), "left_grip"),
            (json.dumps({"head": POSE}), "left is missing"),
            (b"\x00\x01", "binary frames"),
        ]:
            ws.send(frame)
            reply = json.loads(ws.recv(timeout=5))
            assert reply["type"] == "error" and words in reply["error"], reply
        assert bridge.latest() is good  # malformed frames change nothing
        assert bridge.stats.rejected == 4 and bridge.stats.accepted == 1


def test_token_in_query_or_first_message() -> None:
    with VrBridge("127.0.0.1", 0, token="s3cret") as bridge:
        port = bridge.bound_port
        with connect(f"ws://127.0.0.1:{port}/ws?token=s3cret") as ws:
            assert json.loads(ws.recv(timeout=5))["auth_required"] is False
            ws.send(json.dumps(SAMPLE))
            assert wait_for(lambda: bridge.latest() is not None)
        with pytest.raises(InvalidStatus):
            connect(f"ws://127.0.0.1:{port}/ws?token=wrong")
        with connect(f"ws://127.0.0.1:{port}/ws") as ws:
            assert json.loads(ws.recv(timeout=5))["auth_required"] is True
            ws.send(json.dumps({"token": "s3cret"}))
            assert json.loads(ws.recv(timeout=5)) == {"type": "auth", "ok": True}
            ws.send(json.dumps({**SAMPLE, "left_grip": 0.5}))
            assert wait_for(lambda: bridge.latest().left_grip == 0.5)
        with connect(f"ws://127.0.0.1:{port}/ws") as ws:
            ws.recv(timeout=5)
            ws.send(json.dumps({**SAMPLE, "left_grip": 0.25}))  # sample before the token
            reply = json.loads(ws.recv(timeout=5))
            assert reply["type"] == "error" and "authenticate first" in reply["error"]
            with pytest.raises(ConnectionClosed):
                ws.recv(timeout=5)
        assert bridge.latest().left_grip == 0.5


def test_serves_the_page() -> None:
    with VrBridge("127.0.0.1", 0) as bridge:
        base = f"http://127.0.0.1:{bridge.bound_port}"
        with urllib.request.urlopen(base + "/", timeout=5) as r:
            body = r.read().decode()
            assert r.headers["Content-Type"].startswith("text/html")
        assert "immersive-vr" in body and "navigator.xr" in body and "/ws" in body
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(base + "/nothing", timeout=5)
        assert err.value.code == 404


def test_non_loopback_bind_needs_a_token() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
    with pytest.raises(BridgeConfigError, match="without a token"):
        check_bind("0.0.0.0", None)
    with pytest.raises(BridgeConfigError):
        VrBridge("0.0.0.0", 0)
    check_bind("0.0.0.0", "tok")  # allowed with a token


def test_port_in_use_is_a_clear_error() -> None:
    with (
        VrBridge("127.0.0.1", 0) as first,
        pytest.raises(BridgeConfigError, match="cannot serve"),
    ):
        VrBridge("127.0.0.1", first.bound_port).start()
