"""Two sessions with different ids on one bus never see each other."""

from __future__ import annotations

import json
import subprocess
import threading

from hrc.bus import Bus, BusConfig
from hrc.wire import pb

from .conftest import HRC, ROOT, free_port, wait_until


def test_two_trials_on_one_router_do_not_mix(tmp_path, ik_bin) -> None:
    port = free_port()
    router = subprocess.Popen(
        [HRC, "router", "--listen", f"tcp/127.0.0.1:{port}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        ep = f"tcp/127.0.0.1:{port}"
        seen: dict[str, set[str]] = {"A": set(), "B": set()}
        lock = threading.Lock()
        with (
            Bus(BusConfig(session="sessA", connect=[ep], listen=[]), "spyA") as spy_a,
            Bus(BusConfig(session="sessB", connect=[ep], listen=[]), "spyB") as spy_b,
        ):

            def watch(tag: str):
                def on(_k: str, m: pb.ClockTick) -> None:
                    with lock:
                        seen[tag].add(m.header.session)

                return on

            spy_a.subscribe(spy_a.keys.clock(), pb.ClockTick, watch("A"))
            spy_b.subscribe(spy_b.keys.clock(), pb.ClockTick, watch("B"))
            procs = {}
            for tag in ("A", "B"):
                procs[tag] = subprocess.Popen(
                    [
                        HRC,
                        "run",
                        str(ROOT / "scenarios" / "empty.toml"),
                        "--out",
                        str(tmp_path / tag),
                        "--ticks",
                        "1500",
                        "--session",
                        f"sess{tag}",
                        "--connect",
                        ep,
                    ],
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    text=True,
                )
            for tag, p in procs.items():
                _out, err = p.communicate(timeout=300)
                assert p.returncode == 0, f"{tag}: {err}"
            assert wait_until(lambda: seen["A"] and seen["B"], 5)
        # each spy saw only its own session's clock (other sessions' headers are rejected as
        # malformed anyway; here nothing of the other session even arrives on our keys)
        assert seen == {"A": {"sessA"}, "B": {"sessB"}}
        for tag in ("A", "B"):
            m = json.loads((tmp_path / tag / "metrics.json").read_text())
            assert m["run"]["ticks"] == 1500
            for log in (tmp_path / tag / "services").glob("*.log"):
                assert "malformed" not in log.read_text(errors="replace"), log
    finally:
        router.terminate()
        router.wait(10)


def test_a_subscriber_of_one_session_gets_nothing_from_another(tmp_path) -> None:
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    got: list[str] = []
    with (
        Bus(BusConfig(session="one", listen=[ep]), "a") as a,
        Bus(BusConfig(session="two", connect=[ep]), "b") as b,
    ):
        b.subscribe(b.keys.task_events(), pb.TaskEvent, lambda _k, m: got.append("two"))
        a.subscribe(a.keys.task_events(), pb.TaskEvent, lambda _k, m: got.append("one"))
        own = b.publisher(b.keys.task_events())
        other = a.publisher(a.keys.task_events())
        assert wait_until(lambda: (own.put(pb.TaskEvent()) and False) or "two" in got)
        for _ in range(20):
            other.put(pb.TaskEvent())
        assert wait_until(lambda: got.count("one") >= 20)
        assert wait_until(lambda: got.count("two") == own.seq)
