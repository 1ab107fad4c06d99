"""``hrc bench client``: what a participant client gets from a live trial (docs/client-protocol.md).

Runs the thesis scenario as a live trial (``--input vr``, realtime) with two WebSocket clients of
its own (Python; a driver and a spectator), and prints:

- **latency**: from the driver sending a hand pose into a robot to the first frame it receives
  in which that robot moves towards its retreat pose (p50 / p99 / max over ``--n`` collisions),
  and to the ``collision`` event;
- **bytes per second** (and frames per second) each client received while the robots moved.

Goal (issue 13): latency p99 within 3 display frames at 90 Hz, 33 ms. Timings depend on the
machine's load: the load average is printed with the figures.

More figures (the page's frame time, measured in a browser) plug in as functions of
:class:`BenchContext` in :data:`EXTRA_FIGURES`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
import os
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from websockets.sync.client import ClientConnection, connect

from hrc import scenario as sc
from hrc.bench.page import BenchContext, page_figures
from hrc.bus import Bus, access
from hrc.paths import project_root
from hrc.ports import free_port
from hrc.service_table import EXPERIMENTER
from hrc.trial import TrialOptions, TrialResult, VrOptions, run_trial
from hrc.wire import pb

log = logging.getLogger(__name__)

Vec = tuple[float, float, float]
REST_LEFT: Vec = (-0.22, -0.56, 0.10)
REST_RIGHT: Vec = (0.22, -0.56, 0.10)
HEAD: Vec = (0.0, -0.70, 0.60)
GOAL_MS = 33.0
DEFAULT_N = 12


def _pose(p: Vec) -> dict[str, list[float]]:
    return {"position": list(p), "orientation": [0.0, 0.0, 0.0, 1.0]}


@dataclass
class Received:
    t: float  # time.perf_counter() at arrival
    msg: dict[str, Any]
    size: int


class LiveClient:
    """A participant client in Python: a reader thread keeps every message (with its arrival
    time) and the world merged from the frames' deltas."""

    def __init__(self, url: str) -> None:
        self.ws: ClientConnection = connect(url, open_timeout=10, max_size=None)
        self.messages: list[Received] = []
        self.robots: dict[str, dict[str, Any]] = {}
        self.objects: dict[str, dict[str, Any]] = {}
        self.cond = threading.Condition()
        self.closed = False
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for raw in self.ws:
                t = time.perf_counter()
                text = raw if isinstance(raw, str) else raw.decode()
                msg = json.loads(text)
                with self.cond:
                    if msg.get("type") == "frame":
                        for rid, r in msg["robots"].items():
                            self.robots[rid] = r
                        for oid, o in msg["objects"].items():
                            self.objects[oid] = o
                    self.messages.append(Received(t, msg, len(text)))
                    self.cond.notify_all()
        except Exception:  # closed: the waiting side sees `closed`
            pass
        finally:
            with self.cond:
                self.closed = True
                self.cond.notify_all()

    def send(self, obj: dict[str, Any]) -> None:
        self.ws.send(json.dumps(obj))

    def hands(self, left: Vec, right: Vec, left_grip: float, right_grip: float) -> None:
        self.send(
            {
                "head": _pose(HEAD),
                "left": _pose(left),
                "right": _pose(right),
                "left_grip": left_grip,
                "right_grip": right_grip,
            }
        )

    def wait_for(
        self, pred: Callable[[Received], bool], timeout: float, after: int = 0
    ) -> tuple[int, Received] | None:
        """The first message from index ``after`` on that satisfies ``pred``."""
        end = time.monotonic() + timeout
        i = after
        with self.cond:
            while True:
                while i < len(self.messages):
                    if pred(self.messages[i]):
                        return i, self.messages[i]
                    i += 1
                left = end - time.monotonic()
                if left <= 0 or self.closed:
                    return None
                self.cond.wait(left)

    def of_type(self, kind: str) -> list[dict[str, Any]]:
        with self.cond:
            return [m.msg for m in self.messages if m.msg.get("type") == kind]

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.ws.close()
        self._thread.join(5)


def move(client: LiveClient, a: Vec, b: Vec, grip: float, hold: Vec, steps: int = 20) -> None:
    """The right hand from a to b (grip as given), the left one at ``hold``."""
    for i in range(steps + 1):
        s = i / steps
        p = (a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s, a[2] + (b[2] - a[2]) * s)
        client.hands(hold, p, 0.0, grip)
        time.sleep(0.02)


def grab(client: LiveClient, part: dict[str, Any], lift: float = 0.10) -> Vec:
    """Grabs a part at its start with the right hand and lifts it; returns where the hand is.
    Waits for the trial to tick first (it joins the run once a client has connected)."""
    if client.wait_for(lambda m: m.msg.get("type") == "frame" and m.msg["tick"] > 10, 150) is None:
        raise RuntimeError("the trial never started ticking")
    x, y, z = part["start"]["xyz"]
    grasp = (x, y, z + min(0.02, part["size"][2] / 2))
    above = (x, y, z + lift)
    move(client, REST_RIGHT, above, 0.0, REST_LEFT)
    move(client, above, grasp, 0.0, REST_LEFT, 10)
    client.hands(REST_LEFT, grasp, 0.0, 1.0)
    time.sleep(0.4)
    move(client, grasp, above, 1.0, REST_LEFT, 10)
    return above


def percentile(xs: list[float], q: float) -> float:
    """Nearest-rank percentile (q in [0, 100])."""
    if not xs:
        return math.nan
    s = sorted(xs)
    return s[max(0, min(len(s) - 1, math.ceil(q / 100 * len(s)) - 1))]


EXTRA_FIGURES: list[Callable[[BenchContext], dict[str, Any]]] = [page_figures]


@contextlib.contextmanager
def live_trial(
    scenario: Path, out: Path, vr_port: int, stall_timeout_s: float = 0.0
) -> Iterator[tuple[str, Callable[[], TrialResult | None]]]:
    """A live trial running in a thread; yields (session, result getter); stops it at the end."""
    session, port = f"bc{uuid.uuid4().hex[:8]}", free_port()
    loaded = sc.load(scenario, motion_check=False)
    opts = TrialOptions(
        scenario=scenario,
        out=out,
        mode="realtime",
        ticks=10**9,
        session=session,
        port=port,
        stall_timeout_s=stall_timeout_s,
        participant=loaded.participant.name,
        parts_total=len(loaded.parts),
        input="vr",
        vr=VrOptions(port=vr_port, wait_s=60.0),
    )
    result: dict[str, TrialResult] = {}
    runner = threading.Thread(target=lambda: result.setdefault("r", run_trial(opts, out)))
    runner.start()
    try:
        yield session, lambda: result.get("r")
    finally:
        with (
            contextlib.suppress(Exception),
            Bus(access.join(session, port, timeout_s=5.0), EXPERIMENTER) as bus,
        ):
            time.sleep(0.3)
            bus.publisher(bus.keys.run_control(bus.sender)).put(
                pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason="bench done")
            )
            time.sleep(0.3)
        runner.join(60)


def connect_when_up(url: str, timeout: float = 90.0, **kw: Any) -> LiveClient:
    end = time.monotonic() + timeout
    while True:
        try:
            return LiveClient(url, **kw)
        except OSError:
            if time.monotonic() > end:
                raise
            time.sleep(0.2)


def _collide_again_and_again(
    driver: LiveClient, held: Vec, robots: list[str], stop: threading.Event
) -> None:
    """Touches each robot in turn, waits for the robots to go on, again, until ``stop``."""
    k = 0
    while not stop.is_set():
        rid = robots[k % len(robots)]
        k += 1
        with driver.cond:
            tcp = driver.robots.get(rid, {}).get("tcp")
            mark = len(driver.messages)
        if tcp is None:
            stop.wait(0.5)
            continue
        driver.hands((tcp[0], tcp[1], tcp[2] + 0.02), held, 0.0, 1.0)
        driver.wait_for(lambda m: m.msg.get("kind") == "collision", 3.0, mark)
        driver.hands(REST_LEFT, held, 0.0, 1.0)
        driver.wait_for(lambda m: m.msg.get("kind") == "continued", 15.0, mark)
        stop.wait(0.5)


@contextlib.contextmanager
def robots_kept_busy(driver: LiveClient, held: Vec, robots: list[str]) -> Iterator[None]:
    stop = threading.Event()
    worker = threading.Thread(
        target=_collide_again_and_again, args=(driver, held, robots, stop), daemon=True
    )
    worker.start()
    try:
        yield
    finally:
        stop.set()
        worker.join(20)
        driver.hands(REST_LEFT, held, 0.0, 1.0)


def towards(a: list[float], b: list[float], goal: Vec, at_least: float) -> bool:
    """The step a -> b has a component of ``at_least`` metres towards ``goal``."""
    d = [b[i] - a[i] for i in range(3)]
    g = [goal[i] - a[i] for i in range(3)]
    norm = math.sqrt(sum(x * x for x in g)) or 1.0
    return sum(d[i] * g[i] for i in range(3)) / norm >= at_least


def measure(n: int, scenario: Path) -> dict[str, Any]:
    s = sc.load(scenario, motion_check=False)
    retreat = {rid: (r.retreat[0], r.retreat[1], r.retreat[2]) for rid, r in s.robots.items()}
    vr_port = free_port()
    url = f"ws://127.0.0.1:{vr_port}/ws"
    figures: dict[str, Any] = {"scenario": s.scenario.name, "n": 0}
    with (
        tempfile.TemporaryDirectory(prefix="hrc-bench-client-") as tmp,
        live_trial(scenario, Path(tmp) / "trial", vr_port) as (_session, _result),
    ):
        driver = connect_when_up(url)
        spectator = connect_when_up(url)
        try:
            scene = driver.wait_for(lambda m: m.msg.get("type") == "scene", 30)
            if scene is None:
                raise RuntimeError("no scene from the bridge")
            parts = {p["id"]: p for p in scene[1].msg["parts"]}
            first = next(iter(s.sequence_of(sc.HUMAN)), None)
            if first is None:
                raise RuntimeError(f"{scenario}: no part for the participant to start the task")
            held = grab(driver, parts[first])
            started = driver.wait_for(lambda m: m.msg.get("kind") == "task_started", 10)
            if started is None:
                raise RuntimeError(f"the grab of {first} did not start the task")
            t_window, i_driver = time.perf_counter(), len(driver.messages)
            i_spect = len(spectator.messages)
            latencies: list[float] = []
            event_latencies: list[float] = []
            motion_latencies: list[float] = []
            robots = sorted(retreat)
            misses = 0
            for k in range(n):
                rid = robots[k % len(robots)]
                with driver.cond:
                    tcp = driver.robots.get(rid, {}).get("tcp")
                    mark = len(driver.messages)
                if tcp is None:
                    misses += 1
                    continue
                touch = (tcp[0], tcp[1], tcp[2] + 0.02)
                t0 = time.perf_counter()
                driver.hands(touch, held, 0.0, 1.0)
                hit = driver.wait_for(
                    lambda m: m.msg.get("type") == "event" and m.msg.get("kind") == "collision",
                    3.0,
                    mark,
                )
                if hit is None:
                    misses += 1
                    driver.hands(REST_LEFT, held, 0.0, 1.0)
                    time.sleep(0.5)
                    continue
                event_latencies.append((hit[1].t - t0) * 1000)
                seen = _retreat_frames(driver, rid, retreat[rid], hit[1].msg["tick"], mark)
                if seen is None:
                    misses += 1
                else:
                    latencies.append((seen[0].t - t0) * 1000)
                    motion_latencies.append((seen[1].t - t0) * 1000)
                driver.hands(REST_LEFT, held, 0.0, 1.0)
                driver.wait_for(
                    lambda m: m.msg.get("type") == "event" and m.msg.get("kind") == "continued",
                    15.0,
                    hit[0],
                )
                time.sleep(0.5)  # the robots resume: the next touch meets a moving arm
            window = time.perf_counter() - t_window
            figures.update(
                n=len(latencies),
                misses=misses,
                retreat_latency_ms=_stats(latencies),
                collision_event_latency_ms=_stats(event_latencies),
                retreat_motion_1mm_ms=_stats(motion_latencies),
                goal_p99_ms=GOAL_MS,
                clients={
                    "driver": _traffic(driver, i_driver, window),
                    "spectator": _traffic(spectator, i_spect, window),
                },
            )
            ctx = BenchContext(
                url.replace("ws://", "http://").removesuffix("/ws") + "/",
                scenario,
                n,
                lambda: robots_kept_busy(driver, held, robots),
            )
            for extra in EXTRA_FIGURES:
                figures.update(extra(ctx))
        finally:
            driver.close()
            spectator.close()
    figures["load_average"] = [round(x, 2) for x in os.getloadavg()]
    return figures


def _page_line(key: str, fig: dict[str, Any]) -> str:
    """The page's figures of one mode (bench_page) in three lines."""
    if "full" not in fig:
        return f"{key}: {fig}"
    full, cpu, goal = fig["full"], fig["cpu_only"], fig["goal"]
    return (
        f"{key}: page work per frame (update + render call) p50 {cpu['work_ms']['p50']:.2f} ms"
        f"  p95 {cpu['work_ms']['p95']:.2f} ms at {cpu['viewport']} (goal p95 <= "
        f"{goal['work_ms_p95']:g} ms), {full['draw_calls']['per_view']:g} draw calls per view "
        f"(goal <= {goal['draw_calls_per_view']}): {'met' if goal['met'] else 'NOT met'}\n"
        f"  at {full['viewport']}: work p50 {full['work_ms']['p50']:.2f} ms  p95 "
        f"{full['work_ms']['p95']:.2f} ms, frame interval p50 {full['interval_ms']['p50']} ms; "
        f"rasterisation (chromium's GPU process) {full['cpu_ms_per_frame']['gpu']} CPU ms per "
        f"frame; frames {full['frames']} ({full['frames_both_robots_moving']} with both robots "
        "moving)"
    )


def _retreat_frames(
    client: LiveClient, rid: str, goal: Vec, tick: int, after: int
) -> tuple[Received, Received] | None:
    """After the collision of ``tick``: the first frame showing robot ``rid`` under a new
    command (the retreat: its state from the tick it began), and the first in which its TCP has
    moved 1 mm towards ``goal`` (the arm accelerates smoothly: this adds its dynamics)."""
    before: dict[str, Any] | None = None
    with client.cond:  # the robot just before the touch
        for m in client.messages[:after][::-1]:
            if m.msg.get("type") == "frame" and rid in m.msg["robots"]:
                before = m.msg["robots"][rid]
                break
    if before is None:
        return None
    old_command, start = before["command"], before["tcp"]

    def commanded(m: Received) -> bool:
        r = m.msg["robots"].get(rid) if m.msg.get("type") == "frame" else None
        return r is not None and m.msg["tick"] >= tick and r["command"] != old_command

    first = client.wait_for(commanded, 3.0, after)
    if first is None:
        return None
    start = first[1].msg["robots"][rid]["tcp"]

    def moved(m: Received) -> bool:
        r = m.msg["robots"].get(rid) if m.msg.get("type") == "frame" else None
        return r is not None and towards(start, r["tcp"], goal, 1e-3)

    second = client.wait_for(moved, 3.0, first[0])
    return None if second is None else (first[1], second[1])


def _stats(xs: list[float]) -> dict[str, float | None]:
    """p50 / p99 / max in ms (None without samples: JSON has no NaN)."""
    if not xs:
        return {"p50": None, "p99": None, "max": None}
    return {
        "p50": round(percentile(xs, 50), 1),
        "p99": round(percentile(xs, 99), 1),
        "max": round(max(xs), 1),
    }


def _traffic(client: LiveClient, start: int, window: float) -> dict[str, float]:
    with client.cond:
        got = client.messages[start:]
    frames = [m for m in got if m.msg.get("type") == "frame"]
    dropped = frames[-1].msg["dropped"] if frames else 0
    return {
        "bytes_per_s": round(sum(m.size for m in got) / window),
        "frames_per_s": round(len(frames) / window, 1),
        "dropped": dropped,
    }


def run(args: argparse.Namespace) -> int:
    n = args.n or DEFAULT_N
    if n < 1:
        print(f"--n must be >= 1, got {n}", file=sys.stderr)
        return 2
    scenario = project_root() / "scenarios" / "thesis.toml"
    try:
        figures = measure(n, scenario)
    except (RuntimeError, OSError) as exc:
        print(f"client bench failed: {exc}", file=sys.stderr)
        return 1
    if getattr(args, "json", False):
        print(json.dumps(figures))
        return 0
    lat, ev = figures["retreat_latency_ms"], figures["collision_event_latency_ms"]
    mo = figures["retreat_motion_1mm_ms"]
    if lat["p50"] is None:
        print("no collision was measured", file=sys.stderr)
        return 1
    print(f"scenario {figures['scenario']}, {figures['n']} collisions ({figures['misses']} missed)")
    print(
        f"hand pose -> retreat visible  p50 {lat['p50']:.1f} ms  p99 {lat['p99']:.1f} ms  "
        f"max {lat['max']:.1f} ms  (goal p99 <= {GOAL_MS:g} ms)"
    )
    print(f"hand pose -> collision event p50 {ev['p50']:.1f} ms  p99 {ev['p99']:.1f} ms")
    print(f"hand pose -> TCP 1 mm back   p50 {mo['p50']:.1f} ms  p99 {mo['p99']:.1f} ms")
    for name, c in figures["clients"].items():
        print(
            f"{name:<10} {c['bytes_per_s'] / 1024:.1f} KiB/s, {c['frames_per_s']:.1f} frames/s, "
            f"{c['dropped']} dropped"
        )
    for key, value in figures.items():
        if key not in {
            "scenario",
            "n",
            "misses",
            "retreat_latency_ms",
            "collision_event_latency_ms",
            "retreat_motion_1mm_ms",
            "goal_p99_ms",
            "clients",
            "load_average",
        }:
            print(_page_line(key, value) if key.startswith("page_") else f"{key}: {value}")
    print(f"load average {figures['load_average']}")
    return 0
