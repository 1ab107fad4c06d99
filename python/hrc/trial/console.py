"""The experimenter's console of a live trial (``hrc run --input vr``): a line per event that
matters to the experimenter (pages connecting and leaving, roles, the task starting, parts
placed, collisions, waits on the participant, the end), and one status line that updates in
place on a terminal (who is connected, run state, task time, parts placed of n, collisions, the
current wait on the participant). Not on a terminal (a log file, a test) the status line is
printed as a line of its own every ``STATUS_EVERY_S``.

It listens on the trial's bus (``task/events``, ``human/clients``) from the CLI's own session;
:meth:`LiveConsole.update` is called from ``hrc run``'s watch loop, so printing never happens
on a Zenoh thread.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass, field
from typing import TextIO

from hrc.bus import Bus
from hrc.wire import pb

K = pb.TaskEventKind
STATUS_EVERY_S = 15.0  # not a terminal: the status line this often
RUN_WORDS = {
    "waiting": "waiting for the first grab",
    "running": "running",
    "finished": "task finished",
    "ended": "ended",
}


@dataclass
class _State:
    clients: list[tuple[str, int]] = field(default_factory=list)  # peer, ClientRole
    run: str = "waiting"
    started_at: float | None = None  # time.monotonic() of TASK_STARTED, less its task time
    finished_task_s: float | None = None
    placed: int = 0
    collisions: int = 0
    open_collisions: int = 0
    wait: str = ""  # what the participant is expected to do; "" when nothing waits on them
    wait_since: float = 0.0  # time.monotonic() the quiet began
    lines: list[str] = field(default_factory=list)


class LiveConsole:
    def __init__(
        self, bus: Bus, participant: str, parts_total: int, out: TextIO | None = None
    ) -> None:
        self.out: TextIO | None = out or sys.stdout
        self.tty = self.out.isatty()
        self.participant = participant
        self.parts_total = parts_total
        self._lock = threading.Lock()
        self._s = _State()
        self._shown = ""  # the status line on screen (terminal) or last printed
        self._printed_at = 0.0
        bus.subscribe(bus.keys.task_events(), pb.TaskEvent, self._on_event)
        bus.subscribe(bus.keys.human_clients(), pb.ParticipantClients, self._on_clients)

    # ------------------------------------------------------------------ zenoh threads
    def _on_clients(self, _key: str, msg: pb.ParticipantClients) -> None:
        with self._lock:
            self._s.clients = [(c.peer, c.role) for c in msg.clients]
            self._s.lines.extend(msg.changes)

    def _on_event(self, _key: str, ev: pb.TaskEvent) -> None:
        now = time.monotonic()
        s = self._s
        with self._lock:
            line = ""
            if ev.kind not in (
                K.TASK_EVENT_KIND_PARTICIPANT_WAIT,
                K.TASK_EVENT_KIND_HUMAN_IDLE_BEGIN,
                K.TASK_EVENT_KIND_HUMAN_IDLE_END,
            ):
                s.wait = ""  # anything else that happens ends a wait on the participant
            if ev.kind == K.TASK_EVENT_KIND_TASK_STARTED:
                s.run, s.started_at = "running", now - ev.task_time
                line = f"task started: {ev.part or 'nothing to grab'}"
            elif ev.kind == K.TASK_EVENT_KIND_PART_PLACED:
                s.placed += 1
                by = "the participant" if ev.agent == "human" else ev.agent
                line = f"{ev.part} placed by {by} ({s.placed}/{self.parts_total})"
            elif ev.kind == K.TASK_EVENT_KIND_COLLISION:
                s.collisions += 1
                s.open_collisions += 1
                line = f"collision {s.collisions}: {ev.robot} and the {ev.hand} hand"
            elif ev.kind == K.TASK_EVENT_KIND_COLLISION_END:
                s.open_collisions = max(0, s.open_collisions - 1)
            elif ev.kind == K.TASK_EVENT_KIND_CONTINUED:
                line = "the robots continue"
            elif ev.kind == K.TASK_EVENT_KIND_PARTICIPANT_WAIT:
                s.wait = ev.participant_wait.what or ev.part
                s.wait_since = now - ev.participant_wait.quiet_s
                line = f"waiting for the participant: {s.wait}"
            elif ev.kind == K.TASK_EVENT_KIND_TASK_FINISHED:
                s.run = "finished"
                s.finished_task_s = ev.task_time
                line = f"task finished at {ev.task_time:.1f} s, {s.collisions} collisions"
            elif ev.kind == K.TASK_EVENT_KIND_STALLED:
                s.run = "ended"
                line = ev.text.strip()
            if line:
                s.lines.append(f"[task {self._task_s(now):6.1f} s] {line}")

    def _task_s(self, now: float) -> float:
        s = self._s
        if s.finished_task_s is not None:
            return s.finished_task_s
        return 0.0 if s.started_at is None else now - s.started_at

    # ------------------------------------------------------------------ the watch loop
    def status(self, now: float | None = None) -> str:
        now = time.monotonic() if now is None else now
        with self._lock:
            s = self._s
            drivers = [p for p, r in s.clients if r == pb.CLIENT_ROLE_DRIVER]
            spectators = len(s.clients) - len(drivers)
            who = f"driver {drivers[0]}" if drivers else "no driver"
            parts = [
                (f"{self.participant}: " if self.participant else "")
                + f"{who}, {spectators} spectator(s)",
                RUN_WORDS.get(s.run, s.run),
                f"task {self._task_s(now):.1f} s",
                f"placed {s.placed}/{self.parts_total}",
                f"collisions {s.collisions}" + (" (open)" if s.open_collisions else ""),
            ]
            if s.wait:
                parts.append(f"waiting for the participant: {s.wait}, {now - s.wait_since:.0f} s")
        return " | ".join(parts)

    def update(self) -> None:
        """Prints the lines that came since the last call and refreshes the status line."""
        now = time.monotonic()
        with self._lock:
            lines, self._s.lines = self._s.lines, []
        status = self.status(now)
        text = ""
        if self.tty:
            if lines:
                text += "\r\x1b[K" + "".join(f"{ln}\n" for ln in lines)
            if lines or status != self._shown:
                text += "\r\x1b[K" + status
                self._shown = status
        else:
            text += "".join(f"{ln}\n" for ln in lines)
            if now - self._printed_at >= STATUS_EVERY_S:
                text += f"status: {status}\n"
                self._printed_at = now
        self._write(text)

    def close(self, end: str = "") -> None:
        self.update()
        text = "\n" if self.tty and self._shown else ""
        if end:  # a terminal shows the last status line already
            text += ("" if self.tty else f"status: {self.status()}\n") + f"run ended: {end}\n"
        self._write(text)

    def _write(self, text: str) -> None:
        """A closed terminal or pipe ends the console, never the trial or its clean-up."""
        if self.out is None or not text:
            return
        try:
            self.out.write(text)
            self.out.flush()
        except (OSError, ValueError):  # EIO, EPIPE; ValueError: the file was closed
            self.out = None
