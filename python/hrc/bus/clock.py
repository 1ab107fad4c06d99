"""The clock master side of the tick protocol (used by the physics service and the bus bench).

lockstep: publish tick k, wait for every participant's ack of k (the barrier), apply, step, k + 1.
realtime: the same, paced by the wall clock; the barrier's deadline is the next tick's start and a
late participant's miss is counted (its last outputs stay in force).
A participant that loses liveliness, or misses the lockstep barrier timeout, ends the run with an
error naming it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable, Literal

from google.protobuf.message import Message

from hrc.bus.bus import Bus, Validator
from hrc.bus.inbox import Handler, Inbox
from hrc.wire import pb

log = logging.getLogger(__name__)

ClockModeName = Literal["lockstep", "realtime"]
MODES: dict[str, int] = {"lockstep": pb.CLOCK_MODE_LOCKSTEP, "realtime": pb.CLOCK_MODE_REALTIME}


@dataclass
class ClockSettings:
    mode: ClockModeName = "lockstep"
    tick_hz: float = 240.0
    ticks: int = 0  # 0: until a stop request
    participants: list[str] = field(default_factory=lambda: ["ik_cpp", "orchestrator", "human_input"])
    observers: list[str] = field(default_factory=lambda: ["logger"])
    barrier_timeout_s: float = 10.0
    start_timeout_s: float = 60.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"clock mode {self.mode!r} is not one of {', '.join(MODES)}")
        if not self.tick_hz > 0:
            raise ValueError(f"tick_hz must be > 0, got {self.tick_hz}")
        if self.ticks < 0:
            raise ValueError(f"ticks must be >= 0, got {self.ticks}")


class RunFailed(Exception):
    def __init__(self, reason: str, participant: str = "") -> None:
        super().__init__(reason)
        self.reason = reason
        self.participant = participant


class ClockMaster:
    """Drives the session's clock. Register inputs with :meth:`input`, then :meth:`run`."""

    def __init__(self, bus: Bus, settings: ClockSettings) -> None:
        self.bus = bus
        self.settings = settings
        self.dt = 1.0 / settings.tick_hz
        self.inbox = Inbox(bus)
        self._cond = threading.Condition()
        self._acked: dict[str, int] = {p: -1 for p in settings.participants}
        self._marks: dict[tuple[str, str], int] = {}
        self._alive: set[str] = set()
        self._lost: list[str] = []
        self._stop: tuple[bool, str] | None = None
        self.misses: Counter[str] = Counter()
        self.compute_us: dict[str, int] = {}
        self._compute_total: Counter[str] = Counter()
        self._own_s: Counter[str] = Counter()  # physics's own time per phase of the tick
        self._clock_pub = bus.publisher(bus.keys.clock(), express=True)
        self._end_pub = bus.publisher(bus.keys.run_end())

    def input(self, key: str, msg_type: type[Message], handler: Handler,
              validate: Validator | None = None) -> None:
        self.inbox.add(key, msg_type, handler, validate)

    def start(self) -> None:
        keys = self.bus.keys
        self.bus.subscribe(keys.clock_acks(), pb.TickAck, self._on_ack)
        # A stop takes effect at a tick boundary fixed by the tick it was sent in (through the
        # inbox, like any input), so the run's length is the same on every machine. An abort is
        # also seen at once, so a stuck barrier can be broken.
        self.inbox.add(keys.run_control(), pb.RunControl, self._on_control)
        self.bus.subscribe(keys.run_control(), pb.RunControl, self._on_abort)
        self.bus.watch_liveliness(self._on_liveliness)
        self.bus.serve_stats()
        self.bus.declare_token()

    # ------------------------------------------------------------------ zenoh threads
    def _on_ack(self, key: str, ack: pb.TickAck) -> None:
        name = self.bus.keys.last_segment(key)
        with self._cond:
            if name not in self._acked:
                log.warning("ack from %r, which is not a participant of this run", name)
                return
            if ack.header.tick > self._acked[name]:
                self._acked[name] = ack.header.tick
                self.compute_us[name] = ack.compute_us
                self._compute_total[name] += ack.compute_us
            for m in ack.published:
                mk = (m.key, m.sender)
                if m.seq > self._marks.get(mk, 0):
                    self._marks[mk] = m.seq
            self._cond.notify_all()

    def _on_abort(self, key: str, ctl: pb.RunControl) -> None:
        if ctl.command == pb.RunControl.COMMAND_ABORT:
            self._on_control(key, ctl)

    def _on_control(self, _key: str, ctl: pb.RunControl) -> None:
        with self._cond:
            if self._stop is None:
                ok = ctl.command != pb.RunControl.COMMAND_ABORT
                who = ctl.header.sender
                self._stop = (ok, f"{'stopped' if ok else 'aborted'} by {who}: {ctl.reason}")
            self._cond.notify_all()

    def _on_liveliness(self, service: str, alive: bool) -> None:
        with self._cond:
            if alive:
                self._alive.add(service)
            elif service in self._alive:
                self._alive.discard(service)
                if service in self.settings.participants or service in self.settings.observers:
                    self._lost.append(service)
            self._cond.notify_all()

    # ------------------------------------------------------------------ main thread
    def _check_lost(self) -> None:
        if self._lost:
            name = self._lost[0]
            raise RunFailed(f"service '{name}' lost liveliness (process gone?)", name)

    def wait_ready(self) -> None:
        expected = set(self.settings.participants) | set(self.settings.observers)
        deadline = time.monotonic() + self.settings.start_timeout_s
        with self._cond:
            while not expected <= self._alive:
                self._check_lost()
                left = deadline - time.monotonic()
                if left <= 0:
                    missing = ", ".join(sorted(expected - self._alive))
                    raise RunFailed(
                        f"services never came up within {self.settings.start_timeout_s:g} s: {missing}",
                        sorted(expected - self._alive)[0])
                self._cond.wait(min(left, 0.5))

    def _barrier(self, k: int, deadline: float | None) -> None:
        """All participants acked k and their outputs of k are here; RunFailed on loss/timeout."""
        self._await_acks(k, deadline)
        # Acks are express (unbatched) and may overtake the outputs they vouch for; each ack
        # lists what its sender published, so wait for those messages too.
        with self._cond:
            if self._stop is not None and not self._stop[0]:
                return  # aborting: nothing more to wait for
            marks = [pb.PublishedMark(key=key, sender=sender, seq=seq)
                     for (key, sender), seq in self._marks.items()]
        if deadline is None:
            missing = self.inbox.wait_for(marks, self.settings.barrier_timeout_s)
            if missing:
                m = missing[0]
                raise RunFailed(f"tick {k}: {m.key} #{m.seq} from '{m.sender}' was acknowledged "
                                f"but never arrived within {self.settings.barrier_timeout_s:g} s",
                                m.sender)
        else:  # realtime: whatever is late is applied with the next tick
            self.inbox.wait_for(marks, max(0.0, deadline - time.monotonic()))

    def _await_acks(self, k: int, deadline: float | None) -> None:
        parts = self.settings.participants
        timeout_at = time.monotonic() + self.settings.barrier_timeout_s
        with self._cond:
            while True:
                self._check_lost()
                late = [p for p in parts if self._acked[p] < k]
                if not late:
                    return
                now = time.monotonic()
                if deadline is not None:
                    if now >= deadline:
                        self.misses.update(late)
                        return
                    wait = deadline - now
                else:
                    if now >= timeout_at:
                        raise RunFailed(
                            f"participant '{late[0]}' missed the barrier of tick {k} "
                            f"(no ack within {self.settings.barrier_timeout_s:g} s)", late[0])
                    wait = timeout_at - now
                if self._stop is not None and not self._stop[0]:
                    return
                self._cond.wait(wait)

    def run(self, publish_world: Callable[[int, float], None],
            step: Callable[[int, float], None]) -> pb.RunEnd:
        """Runs the clock to the end and publishes ``run/end``; returns it."""
        s = self.settings
        mode = MODES[s.mode]
        realtime = s.mode == "realtime"
        k = 0
        t0 = time.monotonic()
        ok, reason, failed = True, "", ""
        try:
            self.wait_ready()
            t0 = time.monotonic()
            while True:
                sim = k * self.dt
                ta = time.perf_counter()
                publish_world(k, sim)
                tick = pb.ClockTick(mode=mode, dt=self.dt, participants=s.participants)
                with self._cond:
                    marks = dict(self._marks)
                for m in self.bus.published_marks():
                    marks[(m.key, m.sender)] = m.seq
                tick.published.extend(pb.PublishedMark(key=key, sender=snd, seq=seq)
                                      for (key, snd), seq in marks.items())
                self._clock_pub.put(tick, k, sim)
                tb = time.perf_counter()
                self._barrier(k, t0 + (k + 1) * self.dt if realtime else None)
                tc = time.perf_counter()
                self.inbox.deliver_through(k)
                step(k, sim)
                td = time.perf_counter()
                self._own_s["publish"] += tb - ta
                self._own_s["barrier"] += tc - tb
                self._own_s["step"] += td - tc
                k += 1
                with self._cond:
                    stop = self._stop
                if stop is not None:
                    ok, reason = stop
                    break
                if s.ticks and k >= s.ticks:
                    reason = "ticks"
                    break
                if realtime:
                    pause = t0 + k * self.dt - time.monotonic()
                    if pause > 0:
                        time.sleep(pause)
        except RunFailed as exc:
            ok, reason, failed = False, exc.reason, exc.participant
            log.error("run failed: %s", reason)
        wall = time.monotonic() - t0
        end = pb.RunEnd(ok=ok, reason=reason, failed_participant=failed, ticks=k,
                        sim_time=k * self.dt, wall_s=wall, mode=mode,
                        realtime_factor=(k * self.dt / wall) if wall > 0 else 0.0)
        for p, n in self.misses.items():
            end.deadline_misses[p] = n
        if k:
            parts = ", ".join(f"{p} {self._compute_total[p] / k:.0f}" for p in s.participants)
            own = ", ".join(f"{name} {v / k * 1e6:.0f}" for name, v in self._own_s.items())
            log.info("mean us per tick: participants' compute %s; physics %s", parts, own)
        self._end_pub.put(end, k, k * self.dt)
        self._linger()
        return end

    def _linger(self, timeout: float = 3.0) -> None:
        """Stays until the other services have left, so run/end reaches them before we go."""
        others = set(self.settings.participants) | set(self.settings.observers)
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._alive & others:
                left = deadline - time.monotonic()
                if left <= 0:
                    log.warning("still present after run end: %s",
                                ", ".join(sorted(self._alive & others)))
                    return
                self._cond.wait(left)
