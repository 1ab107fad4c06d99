"""``hrc bench bus``: Zenoh round-trip latency Python<->Python and Python<->C++ on loopback, and
lockstep ticks per second with the five services idle (``scenarios/empty.toml``)."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import zenoh

from hrc.bus import Bus, BusConfig
from hrc.paths import bus_probe_binary, project_root
from hrc.wire import pb

LOCKSTEP_TICKS = 20000


def _percentile(sorted_us: list[float], q: float) -> float:
    i = min(len(sorted_us) - 1, max(0, round(q * (len(sorted_us) - 1))))
    return sorted_us[i]


def _wait_ready(proc: subprocess.Popen[str], what: str, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    assert proc.stdout is not None
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if "ready" in line:
            return
        if proc.poll() is not None:
            break
    raise RuntimeError(f"{what} did not get ready (exit {proc.poll()})")


def measure_rtt(
    echo_argv: list[str], session: str, port: int, n: int, what: str
) -> dict[str, float]:
    """Median and p99 round trip (µs) of a ~100-byte HumanState through an echo peer."""
    cfg = BusConfig(session=session, listen=[f"tcp/127.0.0.1:{port}"])
    with Bus(cfg, "bench") as bus:
        got = threading.Event()
        ping = bus.session.declare_publisher(
            bus.keys.bench("ping"), express=True, congestion_control=zenoh.CongestionControl.BLOCK
        )
        sub = bus.session.declare_subscriber(bus.keys.bench("pong"), lambda _s: got.set())
        proc = subprocess.Popen(
            echo_argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
        )
        try:
            _wait_ready(proc, what)
            msg = pb.HumanState(source=pb.INPUT_SOURCE_SCRIPTED, left_grip=0.5, right_grip=0.25)
            msg.header.session = session
            msg.left_hand.position.x = 0.1
            payload = msg.SerializeToString()
            # Let the peers finish connecting: ping until the first answer comes back.
            deadline = time.monotonic() + 10
            while True:
                got.clear()
                ping.put(payload)
                if got.wait(0.2):
                    break
                if time.monotonic() > deadline:
                    raise RuntimeError(f"{what} never answered")
            samples: list[float] = []
            for i in range(n + n // 10):
                got.clear()
                t0 = time.perf_counter()
                ping.put(payload)
                if not got.wait(2.0):
                    raise RuntimeError(f"{what}: ping {i} lost")
                if i >= n // 10:  # the first tenth warms up
                    samples.append((time.perf_counter() - t0) * 1e6)
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
            sub.undeclare()
            ping.undeclare()
    samples.sort()
    return {"p50": round(_percentile(samples, 0.5), 1), "p99": round(_percentile(samples, 0.99), 1)}


def measure_lockstep(ticks: int, lowlatency: bool = False) -> float:
    from hrc.trial import TrialOptions, run_trial

    scenario = project_root() / "scenarios" / "empty.toml"
    opts = TrialOptions(scenario=scenario, ticks=ticks, lowlatency=lowlatency)
    with tempfile.TemporaryDirectory(prefix="hrc-bench-") as tmp:
        trial = Path(tmp) / "trial"
        opts.out = trial
        result = run_trial(opts, trial)
        if not result.ok:
            raise RuntimeError(f"lockstep run failed: {result.message}")
        run = json.loads((trial / "metrics.json").read_text())["run"]
    return float(run["ticks"] / run["wall_s"])


def run(args: argparse.Namespace) -> int:
    from hrc.ports import free_port

    n = args.n or 5000
    probe = bus_probe_binary()
    if not probe.exists():
        print(f"{probe} is missing: run scripts/setup.sh", file=sys.stderr)
        return 2
    rtt = {}
    s1, p1 = "benchpy", free_port()
    rtt["py_py"] = measure_rtt(
        [
            sys.executable,
            "-m",
            "hrc.bench.echo",
            "--session",
            s1,
            "--connect",
            f"tcp/127.0.0.1:{p1}",
            "--in",
            "ping",
            "--out",
            "pong",
        ],
        s1,
        p1,
        n,
        "python echo",
    )
    s2, p2 = "benchcpp", free_port()
    rtt["py_cpp"] = measure_rtt(
        [
            str(probe),
            "echo",
            "--session",
            s2,
            "--connect",
            f"tcp/127.0.0.1:{p2}",
            "--in",
            f"hrc/{s2}/bench/ping",
            "--out",
            f"hrc/{s2}/bench/pong",
        ],
        s2,
        p2,
        n,
        "C++ echo",
    )
    # Long enough that the start (services warming up, the scripted participant's head settling
    # in its first ~5 simulated seconds) does not dominate the figure.
    ticks = max(args.n, 2000) if args.n else LOCKSTEP_TICKS
    tps = measure_lockstep(ticks)
    # the baseline: the same run on the low-latency transport (hrc run --lowlatency)
    ll = measure_lockstep(ticks, lowlatency=True)
    result = {
        "rtt_us": rtt,
        "lockstep_ticks_per_s": round(tps, 1),
        "lockstep_lowlatency_ticks_per_s": round(ll, 1),
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"round trip over Zenoh on loopback ({n} samples, ~100-byte HumanState):")
        for k, v in rtt.items():
            print(f"  {k:<7} p50 {v['p50']:8.1f} us   p99 {v['p99']:8.1f} us")
        print(f"lockstep, five services idle: {tps:,.0f} ticks/s (target >= 2,000)")
        ratio = tps / ll if ll else 0.0
        print(f"  same with --lowlatency: {ll:,.0f} ticks/s (standard / low-latency: {ratio:.2f})")
    return 0
