"""Python -> C++ and C++ -> Python messages arrive intact over real Zenoh (hrc-bus-probe)."""

from __future__ import annotations

import subprocess
import threading

import pytest

from hrc.bus import Bus, BusConfig
from hrc.paths import bus_probe_binary
from hrc.wire import pb

from .conftest import free_port, wait_until


@pytest.fixture
def probe() -> str:
    path = bus_probe_binary()
    if not path.exists():
        pytest.fail(f"{path} is missing: build it with scripts/setup.sh")
    return str(path)


def _human(i: int, session: str) -> pb.HumanState:
    m = pb.HumanState(source=pb.INPUT_SOURCE_VR, left_grip=i / 10, right_grip=1 - i / 10)
    m.head.position.z = 1.6 + i
    m.left_hand.position.x = -0.25 * i
    m.right_hand.orientation.w = 0.5
    m.right_hand.orientation.z = 0.8660254037844386
    return m


def test_python_to_cpp_and_back_is_byte_identical(probe: str, session_id: str) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    with Bus(BusConfig(session=session_id, listen=[ep]), "pytester") as bus:
        back: list[pb.HumanState] = []
        raw_back: list[bytes] = []
        bus.subscribe(bus.keys.bench("pong"), pb.HumanState, lambda _k, m: back.append(m))
        bus.session.declare_subscriber(
            bus.keys.bench("pong"), lambda s: raw_back.append(s.payload.to_bytes())
        )
        proc = subprocess.Popen(
            [
                probe,
                "echo",
                "--session",
                session_id,
                "--connect",
                ep,
                "--in",
                "bench/ping",
                "--out",
                "bench/pong",
                "--type",
                "HumanState",
                "--count",
                "5",
                "--timeout-s",
                "30",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert wait_until(lambda: "bus_probe" in bus.alive_services(0.3), 20)
            pub = bus.publisher(bus.keys.bench("ping"))
            sent = []
            for i in range(5):
                msg = _human(i, session_id)
                pub.put(msg, tick=i, sim_time=i / 240)
                sent.append(msg.SerializeToString())
            assert wait_until(lambda: len(back) == 5, 10)
            _out, err = proc.communicate(timeout=20)
            assert proc.returncode == 0, err
        finally:
            if proc.poll() is None:
                proc.kill()
        assert raw_back == sent  # decoded and re-encoded by C++: the same bytes
        assert [m.header.tick for m in back] == list(range(5))
        assert back[3].left_hand.position.x == -0.75 and back[3].head.position.z == 4.6


def test_cpp_to_python_delivers_every_field(probe: str, session_id: str) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    got: list[pb.RobotState] = []
    senders: list[bytes] = []
    lock = threading.Lock()
    with Bus(BusConfig(session=session_id, listen=[ep]), "pytester") as bus:
        key = bus.keys.robot_state("probe_robot")
        bus.subscribe(key, pb.RobotState, lambda _k, m: got.append(m))

        def raw(sample) -> None:
            with lock:
                senders.append(sample.attachment.to_bytes() if sample.attachment else b"")

        bus.session.declare_subscriber(key, raw)
        proc = subprocess.run(
            [
                probe,
                "publish",
                "--session",
                session_id,
                "--connect",
                ep,
                "--key",
                "robot/probe_robot/state",
                "--type",
                "RobotState",
                "--count",
                "5",
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert proc.returncode == 0, proc.stderr
        assert wait_until(lambda: len(got) == 5, 10)
    assert bus.stats.decode_errors[key] == 0
    assert set(senders) == {b"bus_probe"}
    for i, m in enumerate(got, start=1):
        assert m.header.session == session_id and m.header.sender == "bus_probe"
        assert m.header.seq == i and m.header.tick == i and m.header.sim_time == 0.5 * i
        assert m.robot == "probe_robot"
        assert list(m.joint_names) == [f"joint_{j}" for j in range(1, 7)]
        assert list(m.joint_positions) == [i + 0.125 * (j + 1) for j in range(6)]
        assert (m.tcp.position.x, m.tcp.position.y, m.tcp.position.z) == (0.25 * i, -1.5, 2.75)
        assert (m.tcp.orientation.z, m.tcp.orientation.w) == (0.6, 0.8)
        assert m.tcp_speed == 0.0625 * i and m.command_id == 1000 + i
        assert m.status == pb.MOTION_STATUS_MOVING
        assert m.detail == f"probe message {i} of 5"
