"""The clock master side of the tick protocol (used by the physics service and the bus bench).

lockstep: publish tick k, wait for every participant's ack of k (the barrier), apply, step, k + 1.
realtime: the same, paced by the wall clock; the barrier's deadline is the next exchange's start
and a late participant's miss is counted (its last outputs stay in force). An exchange spans
several ticks where the service's span allows it (as in lockstep), at most one headset frame.
A participant that leaves the bus, misses the lockstep barrier timeout, or asks for an abort
(its step failed), ends the run with an error naming it (``RunEnd.failed_participant``).

Observers (the logger) never take part in the barrier. Each acks the newest clock tick it has
received every OBSERVER_ACK_TICKS; lockstep keeps the clock at most OBSERVER_WINDOW_TICKS ahead
of that (what it has not taken yet waits in the router's queue for it, which must not overflow),
so a frozen observer stops a lockstep run after the barrier timeout, named. Realtime never waits
for an observer: the router drops what it cannot take (docs/ARCHITECTURE.md, "Observers"), and
one that left the bus (its link's lease ran out while it was frozen) may come back within
OBSERVER_RETURN_S.

Why one file of over 600 lines: the barrier, the exchange spans and the judging of faults act
on one clock's state within each tick; the protocol is docs/ARCHITECTURE.md, "Tick protocol".
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

from hrc.bus.bus import Bus, M
from hrc.bus.inbox import Inbox
from hrc.service_table import EXPERIMENTER, OBSERVERS, PARTICIPANTS
from hrc.wire import pb

log = logging.getLogger(__name__)

ClockModeName = Literal["lockstep", "realtime"]
MODES: dict[str, pb.ClockMode.ValueType] = {
    "lockstep": pb.CLOCK_MODE_LOCKSTEP,
    "realtime": pb.CLOCK_MODE_REALTIME,
}


def control_problem(owner: str, ctl: pb.RunControl) -> str | None:
    """Why a stop or abort on ``owner``'s key (``run/control/<owner>``) is refused, or None. The
    key is the proof of who sent it (the router lets only ``<owner>`` put on it:
    hrc.bus.access), so the header must name the same sender; and only the experimenter (``hrc
    run``, the judge of processes) may blame another service."""
    claimed = ctl.header.sender
    if claimed != owner:
        return f"a run control on {owner!r}'s key claims to come from {claimed!r}"
    if ctl.failed_service and ctl.failed_service != owner and owner != EXPERIMENTER:
        return f"{owner!r} may not name another service ({ctl.failed_service!r}) as failed"
    return None


@dataclass
class ClockSettings:
    mode: ClockModeName = "lockstep"
    tick_hz: float = 240.0
    ticks: int = 0  # 0: until a stop request
    # the services whose acks close the barrier, and those that must be there but never ack
    participants: list[str] = field(default_factory=lambda: list(PARTICIPANTS))
    observers: list[str] = field(default_factory=lambda: list(OBSERVERS))
    # tools the first tick waits for (their tokens) that never hold the clock nor end the run
    watchers: list[str] = field(default_factory=list)
    barrier_timeout_s: float = 10.0
    start_timeout_s: float = 60.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"clock mode {self.mode!r} is not one of {', '.join(MODES)}")
        if not self.tick_hz > 0:
            raise ValueError(f"tick_hz must be > 0, got {self.tick_hz}")
        if self.ticks < 0:
            raise ValueError(f"ticks must be >= 0, got {self.ticks}")


# Lockstep: the clock runs at most this many ticks ahead of the newest tick an observer has
# acknowledged. A tick's messages to an observer are about 1 KB (batched per exchange), so the
# window stays far below what the router queues for it (hrc.bus.access: 16 batches of 64 KiB).
OBSERVER_WINDOW_TICKS = 240
OBSERVER_ACK_TICKS = 60  # an observer acks every this many ticks (four acks per window)
# A service that left the bus (its link closed) fails the run after this grace, so that hrc run,
# which sees its process end, can name the cause first (RunControl.failed_service).
LOST_GRACE_S = 1.0
# Realtime: an observer that left may come back this long after (a frozen logger's link closes
# when its lease runs out; after a SIGCONT it reconnects, and records what it lost).
OBSERVER_RETURN_S = 30.0
# Realtime: an exchange spans at most this long (a headset's frame at 90 Hz, the thesis's frame
# loop). A live participant's page samples its hands at most this often, so no sample waits for
# more than one exchange, and the page gets the robots' states at least at its frame rate; two
# ticks at 240 Hz instead of one halve the exchanges per second, each of which costs the services
# more than its ticks' computation (a 10 s realtime thesis trial: a fifth less CPU).
REALTIME_EXCHANGE_MAX_S = 1.0 / 90.0
# An observer acks the arrival of run/end with this tick. At the end the clock master stays
# until each observer has it (or has left): a slow observer (the logger behind on a loaded
# machine) reads run/end only after its backlog, and a link closed before that would lose it.
# It waits while the observer's acks advance (it is still reading), at most OBSERVER_LINGER_S,
# and gives up on one whose acks stop for OBSERVER_STALL_S (frozen).
RUN_END_RECEIVED = 2**62
OBSERVER_STALL_S = 2.0
OBSERVER_LINGER_S = 8.0


def left_the_bus(name: str) -> str:
    """The failure of a service whose link closed (one wording for every record)."""
    return (
        f"service '{name}' left the bus (its link closed: the process ended, or it was not "
        "responding for the link's lease)"
    )


# After a declared event at tick e (TickAck.next_event_tick) the ticks e + 1 .. e + REACTION_TICKS
# start exchanges: the chain of reactions to it (e.g. a robot's REACHED at e -> the orchestrator's
# next command at e + 1 -> the IK's motion from e + 2 -> what a placement unblocks at e + 3) then
# keeps the timing of one-tick exchanges (docs/ARCHITECTURE.md, "Exchange step").
REACTION_TICKS = 3


# The clock master's last line of a lockstep run (physics.log) begins so: what
# :func:`exchange_counts` reads back.
_EXCHANGES_LINE = re.compile(r"(\d+) ticks in (\d+) exchanges")


def exchange_counts(log_text: str) -> tuple[int, int] | None:
    """(ticks, exchanges) of a run, from the clock master's log (a trial's
    services/physics.log); None if the run logged none."""
    found = _EXCHANGES_LINE.search(log_text)
    return (int(found[1]), int(found[2])) if found else None


class DeclaredEvents:
    """The events the participants declared with their acks, and the longest exchange they
    allow from a tick on.

    A participant's declaration is its earliest coming event as it knows it at its ack, so its
    next ack replaces it (an arm slowed by a speed scale declares its motion's end later at each
    ack: kept, every such declaration would end an exchange and start a reaction chain for
    nothing). An event is reached when an exchange is planned over it (:meth:`planned`); its
    reaction chain then follows."""

    def __init__(self, reaction_ticks: int = REACTION_TICKS) -> None:
        self.reaction_ticks = reaction_ticks
        # participant -> the tick of its next event, as its latest ack declared; tick 0 is
        # everyone's first change: the first states, commands and cues
        self._next: dict[str, int] = {"(start)": 0}
        # events an exchange was planned over, until their reaction chains are past
        self._reached: set[int] = set()
        # participant -> (first tick, period): ticks that start an exchange (no chain), as its
        # latest ack declared (TickAck.next_sample_tick, sample_period_ticks)
        self._samples: dict[str, tuple[int, int]] = {}

    def add(self, tick: int, participant: str = "") -> None:
        """``participant``'s next event is at ``tick`` (0: none). Replaces what it declared
        before."""
        if tick > 0:
            self._next[participant] = tick
        else:
            self._next.pop(participant, None)

    def set_samples(self, participant: str, tick: int, period: int = 0) -> None:
        """``participant`` reads its inputs at ``tick`` and every ``period`` ticks after it
        (0: only there): exchanges start there. Replaces what it declared before."""
        if tick > 0:
            self._samples[participant] = (tick, period)
        else:
            self._samples.pop(participant, None)

    def limit(self, k: int, n: int) -> int:
        """At most ``n`` ticks from ``k``, ending the exchange at each declared event e and
        starting one at each tick e + 1 .. e + reaction_ticks, and at each declared sample."""
        d = self.reaction_ticks
        for e in list(self._reached):
            if e + d <= k:
                self._reached.discard(e)  # its reactions are past
            elif e < k:  # e < k < e + d: a tick of the reaction chain
                n = 1
        for e in self._next.values():
            if k <= e:
                n = min(n, e - k + 1)
        for name, (s, period) in list(self._samples.items()):
            if s <= k:
                if not period:
                    del self._samples[name]  # it starts this exchange, or is past
                    continue
                s += -(-(k + 1 - s) // period) * period  # the first of the grid after k
            n = min(n, s - k)
        return max(1, n)

    def planned(self, k: int, n: int) -> None:
        """The exchange k .. k + n - 1 runs: the events declared in it are reached."""
        for name, e in list(self._next.items()):
            if e < k + n:  # (one before k was never planned over: declared too late, dropped)
                if k <= e:
                    self._reached.add(e)
                del self._next[name]


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
        self.inbox = Inbox(bus, gapless=True)
        self._cond = threading.Condition(threading.Lock())
        self._acked: dict[str, int] = {p: -1 for p in settings.participants}
        # observer -> the newest clock tick it has acknowledged receiving (lockstep's window)
        self._observed: dict[str, int] = {o: -1 for o in settings.observers}
        self._window = OBSERVER_WINDOW_TICKS if settings.mode == "lockstep" else 0
        self._marks: dict[tuple[str, str], int] = {}  # highest seq acked per (key, sender)
        self._fresh: dict[tuple[str, str], int] = {}  # marks that moved since the last barrier
        self._announce: dict[tuple[str, str], int] = {}  # ... not yet listed by a clock tick
        self._barrier_tick = 0  # the tick whose acks are awaited
        # realtime: participant -> wall time (monotonic) since when it has been missing barriers
        self._late_since: dict[str, float] = {}
        # The lockstep transition (apply k, step, publish k + 1) runs on whichever thread claims
        # it: the ack thread inline, or the run() thread. See run().
        self._inline = False
        self._claimed = False
        self._ending: tuple[bool, str] | None = None
        self._crash: BaseException | None = None
        self._published_at = time.perf_counter()
        self.ticks_done = 0
        self._mode = MODES[settings.mode]
        self._publish_world: Callable[[int, float], None] = lambda k, t: None
        self._step_world: Callable[[int, float], None] = lambda k, t: None
        self._span_of: Callable[[int, int], int] = lambda k, n: 1
        self.events = DeclaredEvents()
        self.max_span = 1  # the clock master's longest exchange (set by run())
        self._substep: Callable[[int, float], None] = lambda k, t: None
        self._span = 1  # ticks in the current exchange
        self.exchanges = 0
        self._alive: set[str] = set()
        self._lost: dict[str, float] = {}  # service -> when it left (monotonic)
        self._stop: tuple[bool, str] | None = None
        self._aborted_by = ""  # the sender of the abort that ends the run
        self.misses: Counter[str] = Counter()
        self.compute_us: dict[str, int] = {}
        self._compute_total: Counter[str] = Counter()
        self._own_s: defaultdict[str, float] = defaultdict(
            float
        )  # physics's own time per phase of the tick
        self._clock_pub = bus.publisher(bus.keys.clock(), express=True)
        self._end_pub = bus.publisher(bus.keys.run_end(), express=True)

    def input(
        self,
        key: str,
        msg_type: type[M],
        handler: Callable[[str, M], None],
        validate: Callable[[M], str | None] | None = None,
    ) -> None:
        self.inbox.add(key, msg_type, handler, validate)

    def start(self) -> None:
        keys = self.bus.keys
        self.bus.subscribe(keys.clock_acks(), pb.TickAck, self._on_ack)
        # A stop or a fail takes effect at a tick boundary fixed by the tick it was sent in
        # (through the inbox, like any input), so the run's length is the same on every
        # machine. An abort is also seen at once, so a stuck barrier can be broken.
        self.inbox.add(keys.run_controls(), pb.RunControl, self._on_control)
        self.bus.subscribe(keys.run_controls(), pb.RunControl, self._on_abort)
        self.bus.watch_liveliness(self._on_liveliness)
        self.bus.serve_stats()
        self.bus.serve_replay()
        self.bus.declare_token()

    # ------------------------------------------------------------------ zenoh threads
    def _on_ack(self, key: str, ack: pb.TickAck) -> None:
        name = self.bus.keys.last_segment(key)
        inline = False
        with self._cond:
            if name in self._observed:
                if ack.header.tick <= self._observed[name]:
                    return
                self._observed[name] = ack.header.tick
                if ack.header.tick == RUN_END_RECEIVED:
                    self._cond.notify_all()  # _linger
                    return
                if not self._window:  # realtime: nothing waits for an observer's acks
                    return
            elif name not in self._acked:
                log.warning("ack from %r, which is not a participant of this run", name)
                return
            elif ack.header.tick > self._acked[name]:
                self._acked[name] = ack.header.tick
                self.compute_us[name] = ack.compute_us
                self._compute_total[name] += ack.compute_us
                self.events.add(ack.next_event_tick, name)
                self.events.set_samples(name, ack.next_sample_tick, ack.sample_period_ticks)
            for m in ack.published:
                mk = (m.key, m.sender)
                if m.seq > self._marks.get(mk, 0):
                    self._marks[mk] = self._fresh[mk] = m.seq
            # The last ack of the barrier: run the transition right here if nothing is missing
            # (saves waking the run() thread), else wake it -- unless a transition is under way,
            # whose thread looks again when it is done. Earlier acks wake nobody.
            if self._complete(self._barrier_tick):
                inline = self._try_inline()
                if not inline and not self._claimed:
                    self._cond.notify_all()
        if inline:
            self._transition()

    def _on_abort(self, key: str, ctl: pb.RunControl) -> None:
        # (a forged one is counted once, when the inbox hands it over)
        owner = self.bus.keys.last_segment(key)
        if ctl.command == pb.RunControl.COMMAND_ABORT and control_problem(owner, ctl) is None:
            self._on_control(key, ctl)

    def _on_control(self, key: str, ctl: pb.RunControl) -> None:
        problem = control_problem(self.bus.keys.last_segment(key), ctl)
        if problem is not None:
            self.bus.reject(key, ctl.header.sender, problem)
            return
        with self._cond:
            if self._stop is None:
                ok = ctl.command not in (pb.RunControl.COMMAND_ABORT, pb.RunControl.COMMAND_FAIL)
                who = ctl.header.sender
                if not ok and ctl.failed_service:  # hrc run names a service whose process ended
                    self._stop = (ok, ctl.reason)
                    self._aborted_by = ctl.failed_service
                else:
                    self._stop = (ok, f"{'stopped' if ok else 'aborted'} by {who}: {ctl.reason}")
                    if not ok:
                        self._aborted_by = who
            self._cond.notify_all()

    def _on_liveliness(self, service: str, alive: bool) -> None:
        with self._cond:
            if alive:
                self._alive.add(service)
                if self._lost.pop(service, None) is not None:
                    log.warning("service '%s' is back on the bus", service)
            elif service in self._alive:
                self._alive.discard(service)
                if service in self.settings.participants or service in self.settings.observers:
                    self._lost.setdefault(service, time.monotonic())
                    log.warning("service '%s' left the bus", service)
            self._cond.notify_all()

    # ------------------------------------------------------------------ main thread
    def _grace_s(self, name: str) -> float:
        """How long ``name`` may be gone before the run fails."""
        if name in self.settings.observers and self.settings.mode == "realtime":
            return OBSERVER_RETURN_S
        return LOST_GRACE_S

    def _check_lost(self) -> None:
        """RunFailed for a service gone longer than its grace. Under the lock."""
        now = time.monotonic()
        for name, since in self._lost.items():
            if now - since < self._grace_s(name):
                continue
            if name in self.settings.observers and self.settings.mode == "realtime":
                raise RunFailed(
                    f"observer '{name}' left the bus and did not come back within "
                    f"{OBSERVER_RETURN_S:g} s",
                    name,
                )
            raise RunFailed(left_the_bus(name), name)

    def _wait(self, timeout: float) -> None:
        """``self._cond.wait``, but awake when a gone service's grace runs out."""
        now = time.monotonic()
        for name, since in self._lost.items():
            timeout = min(timeout, max(0.0, since + self._grace_s(name) - now) + 0.01)
        self._cond.wait(timeout)

    def _complete(self, k: int) -> bool:
        """Every participant acked k and (lockstep) no observer is a window behind. Under the
        lock."""
        if any(t < k for t in self._acked.values()):
            return False
        return not self._window or all(t >= k - self._window for t in self._observed.values())

    def wait_ready(self) -> None:
        expected = (
            set(self.settings.participants)
            | set(self.settings.observers)
            | set(self.settings.watchers)
        )
        deadline = time.monotonic() + self.settings.start_timeout_s
        with self._cond:
            while not expected <= self._alive:
                # hrc run saw a service end before it came up (a busy port, a failed connect):
                # its abort ends the start at once, naming that service, instead of the wait
                # running on to the start timeout with the others waiting for tick 0
                if self._stop is not None and not self._stop[0]:
                    raise RunFailed(self._stop[1], self._aborted_by)
                self._check_lost()
                left = deadline - time.monotonic()
                if left <= 0:
                    missing = ", ".join(sorted(expected - self._alive))
                    raise RunFailed(
                        f"services never came up within {self.settings.start_timeout_s:g} s: "
                        f"{missing}",
                        sorted(expected - self._alive)[0],
                    )
                self._wait(min(left, 0.5))

    def _barrier(self, k: int, deadline: float | None) -> None:
        """All participants acked k and their outputs of k are here; RunFailed on loss/timeout."""
        self._await_acks(k, deadline)
        # An ack may still overtake the outputs it vouches for (they come from other senders'
        # sessions via the router, or on another priority); each ack lists what its sender
        # published, so wait for those messages too.
        with self._cond:
            if self._stop is not None and not self._stop[0]:
                return  # aborting: nothing more to wait for
            marks = self._fresh_marks()
            self._consume_fresh()
        if deadline is None:
            missing = self.inbox.wait_for(marks, self.settings.barrier_timeout_s, replay=True)
            if missing:
                m = missing[0]
                got = self.inbox.last_seq(m.key, m.sender)
                raise RunFailed(
                    f"tick {k}: {m.key} #{m.seq} from '{m.sender}' was acknowledged "
                    f"but never arrived within {self.settings.barrier_timeout_s:g} s "
                    f"(received up to #{got})",
                    m.sender,
                )
        else:  # realtime: whatever is late is applied with the next tick
            self.inbox.wait_for(marks, max(0.0, deadline - time.monotonic()))

    def _fresh_marks(self) -> list[pb.PublishedMark]:
        """The marks acked since the last barrier, as messages. Under the lock."""
        return [
            pb.PublishedMark(key=key, sender=sender, seq=seq)
            for (key, sender), seq in self._fresh.items()
        ]

    def _consume_fresh(self) -> None:
        """The fresh marks, waited for, go to the next clock tick's list. Under the lock."""
        self._announce.update(self._fresh)
        self._fresh = {}

    def _missed_barrier(self, k: int) -> RunFailed:
        """The error for a barrier of tick k that timed out. Under the lock."""
        timeout = self.settings.barrier_timeout_s
        late = [p for p in self.settings.participants if self._acked[p] < k]
        if late:
            return RunFailed(
                f"participant '{late[0]}' not responding: no ack of tick {k} within {timeout:g} s",
                late[0],
            )
        behind = [o for o, t in self._observed.items() if t < k - self._window]
        o = behind[0]
        return RunFailed(
            f"observer '{o}' not responding: no ack within {timeout:g} s (it has received the "
            f"clock up to tick {self._observed[o]}; lockstep keeps the clock at most "
            f"{self._window} ticks ahead of its observers)",
            o,
        )

    def _check_late(self, k: int, late: list[str], now: float) -> None:
        """Realtime: a participant that keeps missing the barrier for longer than the barrier
        timeout (alive, but not answering) ends the run, as in lockstep. Under the lock."""
        for p in list(self._late_since):
            if p not in late:
                del self._late_since[p]
        for p in late:
            self._late_since.setdefault(p, now)
        over = [p for p in late if now - self._late_since[p] >= self.settings.barrier_timeout_s]
        if not over:
            return
        # Several can be over at one check (the clock thread itself was held up, or the others'
        # acks queue behind a router that cannot deliver to the stopped one): the one at fault
        # is the one that stopped answering first, not the first in the participants' list.
        p = min(over, key=lambda q: (self._acked[q], self._late_since[q]))
        since = self._late_since[p]
        raise RunFailed(
            f"participant '{p}' not responding: missed every barrier for "
            f"{now - since:.1f} s up to tick {k} (realtime; last ack: tick "
            f"{self._acked[p]}; barrier timeout "
            f"{self.settings.barrier_timeout_s:g} s)",
            p,
        )

    def _await_acks(self, k: int, deadline: float | None) -> None:
        parts = self.settings.participants
        timeout_at = time.monotonic() + self.settings.barrier_timeout_s
        with self._cond:
            while True:
                self._check_lost()
                late = [p for p in parts if self._acked[p] < k]
                if not late:
                    self._late_since.clear()
                    return
                now = time.monotonic()
                if deadline is not None:
                    if now >= deadline:
                        self.misses.update(late)
                        self._check_late(k, late, now)
                        return
                    wait = deadline - now
                else:
                    if now >= timeout_at:
                        raise self._missed_barrier(k)
                    wait = timeout_at - now
                if self._stop is not None and not self._stop[0]:
                    return
                self._wait(wait)

    # ------------------------------------------------------------------ one tick's two halves
    def realtime_max_span(self) -> int:
        """The longest exchange in realtime, in ticks: those within REALTIME_EXCHANGE_MAX_S
        (at least 1), and at most the service's ``max_span``."""
        within = int(REALTIME_EXCHANGE_MAX_S * self.settings.tick_hz + 1e-9)
        return max(1, min(self.max_span, within))

    def _choose_span(self, k: int) -> int:
        """Ticks in the exchange that starts at k: the service's choice (from the simulated
        state only), at most ``max_span`` (realtime: :meth:`realtime_max_span`), never past an
        event a participant declared nor the run's last tick."""
        cap = self.max_span if self.settings.mode == "lockstep" else self.realtime_max_span()
        if self.settings.ticks:
            cap = min(cap, self.settings.ticks - k)
        cap = self.events.limit(k, cap)
        n = max(1, min(cap, int(self._span_of(k, cap))))
        self.events.planned(k, n)
        return n

    def _publish_tick(self, k: int) -> None:
        """World state of k, then clock tick k (the participants' cue to compute the ticks of
        the exchange k .. k + span - 1)."""
        sim = k * self.dt
        ta = time.perf_counter()
        self._publish_world(k, sim)
        # What the exchange published on a key (substeps and this) goes out in one put.
        self.bus.flush_batches()
        self._span = n = self._choose_span(k)
        self.exchanges += 1
        tick = pb.ClockTick(mode=self._mode, dt=self.dt, participants=self.settings.participants)
        if n > 1:
            tick.span = n
        # Only what moved since the previous clock tick (see Bus.new_marks).
        tick.published.extend(
            pb.PublishedMark(key=key, sender=snd, seq=seq)
            for (key, snd), seq in self._announce.items()
        )
        self._announce.clear()
        tick.published.extend(self.bus.new_marks(exclude=self._clock_pub.key))
        with self._cond:
            self._barrier_tick = k  # before the put: acks of k may come back at once
        self._clock_pub.put(tick, k, sim)
        self._published_at = tb = time.perf_counter()
        self._own_s["publish"] += tb - ta

    def _apply_tick(self, k: int) -> tuple[bool, str] | None:
        """After the barrier of the exchange that starts at k: for each of its ticks t, apply
        the outputs of t and step (in between, the service reports what happened at the tick
        reached). The next exchange starts at ``ticks_done``. Returns how the run ends (ok,
        reason) if it ends after this exchange, else None; a stop ends it after the tick it was
        sent in."""
        tc = time.perf_counter()
        self._own_s["barrier"] += tc - self._published_at
        self.bus.begin_batch()  # flushed before the next clock tick (or the end)
        stop: tuple[bool, str] | None = None
        for i in range(self._span):
            t = k + i
            if i:
                self._substep(t, t * self.dt)
            self.inbox.deliver_through(t)
            self._step_world(t, t * self.dt)
            self.ticks_done = t + 1
            with self._cond:
                stop = self._stop
            if stop is not None:
                break
        self._own_s["step"] += time.perf_counter() - tc
        if stop is not None:
            return stop
        if self.settings.ticks and self.ticks_done >= self.settings.ticks:
            return (True, "ticks")
        return None

    # ------------------------------------------------------------------ lockstep
    def _try_inline(self) -> bool:
        """Under the lock, on the ack thread: may this thread run the tick transition itself?
        Only when every ack and every output they list is here (nothing to wait for); it then
        claims the transition and takes the fresh marks. Otherwise run() must do it (and wait)."""
        if (
            not self._inline
            or self._claimed
            or self._ending is not None
            or self._lost
            or self._stop is not None
        ):
            return False
        k = self._barrier_tick
        if not self._complete(k):
            return False
        wanted = self._fresh_marks()
        if wanted and self.inbox.missing(wanted):
            return False
        self._consume_fresh()
        self._claimed = True
        return True

    def _transition(self) -> None:
        """With the claim held and the barrier of the current tick k complete: applies k,
        publishes k + 1, and goes on with k + 1 if its barrier is complete too by then. Runs on
        the ack thread (inline) or on run()'s; one at a time. Errors reach run()."""
        while True:
            k = self._barrier_tick
            try:
                end = self._apply_tick(k)
                if end is None:
                    self._publish_tick(self.ticks_done)
            except BaseException as exc:  # raised again by run()
                with self._cond:
                    self._crash = exc
                    self._claimed = False
                    self._cond.notify_all()
                return
            with self._cond:
                if end is not None and self._ending is None:
                    self._ending = end
                self._claimed = False
                if self._try_inline():  # the acks of k + 1 came back meanwhile
                    continue
                # Wake run() only if it has something to do; else the next ack carries on.
                if (
                    self._ending is not None
                    or self._lost
                    or self._stop is not None
                    or self._complete(self._barrier_tick)
                ):
                    self._cond.notify_all()
                return

    def _run_lockstep(self) -> tuple[bool, str]:
        """run()'s part: the transitions that could not run inline (outputs still missing),
        and the watch over timeouts, lost participants and aborts."""
        s = self.settings
        self._publish_tick(0)
        while True:
            with self._cond:
                while True:
                    if self._crash is not None:
                        raise self._crash
                    if not self._claimed:
                        if self._ending is not None:
                            return self._ending
                        self._check_lost()
                        k = self._barrier_tick
                        aborting = self._stop is not None and not self._stop[0]
                        if aborting or self._complete(k):
                            self._claimed = True
                            break
                        waited = time.perf_counter() - self._published_at
                        if waited >= s.barrier_timeout_s:
                            raise self._missed_barrier(k)
                        self._wait(s.barrier_timeout_s - waited)
                    else:
                        self._wait(s.barrier_timeout_s)
            try:
                self._barrier(k, None)  # the acks are in: wait for the outputs they list
            except BaseException:
                with self._cond:
                    self._claimed = False
                raise
            self._transition()

    # ------------------------------------------------------------------ realtime
    def _run_realtime(self, t0: float) -> tuple[bool, str]:
        """Paced by the wall clock on the run() thread; the barrier's deadline is the next
        exchange's start."""
        k = 0
        while True:
            self._publish_tick(k)
            self._barrier(k, t0 + (k + self._span) * self.dt)
            end = self._apply_tick(k)
            if end is not None:
                return end
            k = self.ticks_done
            pause = t0 + k * self.dt - time.monotonic()
            if pause > 0:
                time.sleep(pause)

    def run(
        self,
        publish_world: Callable[[int, float], None],
        step: Callable[[int, float], None],
        span: Callable[[int, int], int] | None = None,
        substep: Callable[[int, float], None] | None = None,
        max_span: int = 1,
    ) -> pb.RunEnd:
        """Runs the clock to the end and publishes ``run/end``; returns it.

        lockstep: the thread that receives the last ack of tick k (or the last output it
        vouches for) applies k, steps and publishes k + 1 itself, saving a thread hand-off per
        tick; this thread takes over whenever something must be waited for, and watches the
        timeouts. realtime: everything on this thread.

        ``span(k, n)``: how many ticks (at most n) the exchange starting at k covers
        (lockstep), at most ``max_span``, and never past an event a participant declared (see
        :class:`DeclaredEvents`);
        ``substep(t, sim)``: called inside an exchange when tick t is reached, before its
        inputs are applied (the world's reports of t, e.g. contacts that began).
        """
        s = self.settings
        self._mode = MODES[s.mode]
        self._publish_world, self._step_world = publish_world, step
        if span is not None:
            self._span_of = span
        self.max_span = max(1, max_span)
        if substep is not None:
            self._substep = substep
        t0 = time.monotonic()
        ok, reason, failed = True, "", ""
        try:
            self.wait_ready()
            t0 = time.monotonic()
            if s.mode == "realtime":
                ok, reason = self._run_realtime(t0)
            else:
                with self._cond:
                    self._inline = True
                ok, reason = self._run_lockstep()
            if not ok:
                failed = self._aborted_by  # a service that failed asked for the abort
        except RunFailed as exc:
            ok, reason, failed = False, exc.reason, exc.participant
            log.error("run failed: %s", reason)
        finally:
            self._halt()
        k = self.ticks_done
        wall = time.monotonic() - t0
        end = pb.RunEnd(
            ok=ok,
            reason=reason,
            failed_participant=failed,
            ticks=k,
            sim_time=k * self.dt,
            wall_s=wall,
            mode=self._mode,
            realtime_factor=(k * self.dt / wall) if wall > 0 else 0.0,
            last_clock_seq=self._clock_pub.seq,
        )
        for p, n in self.misses.items():
            end.deadline_misses[p] = n
        if k:
            n = max(1, self.exchanges)
            parts = ", ".join(f"{p} {self._compute_total[p] / n:.0f}" for p in s.participants)
            own = ", ".join(f"{name} {v / n * 1e6:.0f}" for name, v in self._own_s.items())
            log.info(  # (its start is read back by exchange_counts)
                "%d ticks in %d exchanges (mean span %.2f); mean us per exchange: "
                "participants' compute %s; physics %s",
                k,
                self.exchanges,
                k / n,
                parts,
                own,
            )
        self.bus.flush_batches()  # a last exchange's world state, if any
        # What no clock tick listed: the last exchange's outputs (acked, or acked since a
        # barrier that never closed) and our own last puts. Observers read on until they have
        # them instead of waiting for the session to go quiet (hrc.bus.observer).
        with self._cond:
            last = {**self._announce, **self._fresh}
        end.published.extend(
            pb.PublishedMark(key=key, sender=snd, seq=seq) for (key, snd), seq in last.items()
        )
        end.published.extend(self.bus.new_marks(exclude=self._clock_pub.key))
        self._end_pub.put(end, k, k * self.dt)
        self._linger()
        return end

    def _halt(self) -> None:
        """No tick after this: stop the inline path and wait for a transition under way."""
        deadline = time.monotonic() + self.settings.barrier_timeout_s
        with self._cond:
            self._inline = False
            if self._ending is None:
                self._ending = (False, "halted")
            while self._claimed and time.monotonic() < deadline:
                self._cond.wait(0.1)

    def _linger(self, timeout: float = 3.0) -> None:
        """Stays until the other services have left, so run/end reaches them before we go:
        participants up to ``timeout``; an observer until it has acked run/end's arrival, while
        its acks advance (see RUN_END_RECEIVED)."""
        participants = set(self.settings.participants)
        start = time.monotonic()
        progress = {o: (self._observed[o], start) for o in self.settings.observers}

        def waiting_for(now: float) -> set[str]:
            left = self._alive & participants if now - start < timeout else set()
            for o, (seen, since) in progress.items():
                got = self._observed[o]
                if got != seen:  # still reading
                    progress[o] = (got, since := now)
                if (
                    o in self._alive
                    and got < RUN_END_RECEIVED
                    and now - since < OBSERVER_STALL_S
                    and now - start < OBSERVER_LINGER_S
                ):
                    left.add(o)
            return left

        with self._cond:
            while waiting_for(time.monotonic()):
                self._cond.wait(0.05)
            unreceived = {o for o, t in self._observed.items() if t < RUN_END_RECEIVED}
            if still := self._alive & (participants | unreceived):
                log.warning("still present after run end: %s", ", ".join(sorted(still)))
