"""``log.txt``: the thesis-style human-readable log (docs/task-semantics.md#outputs).

One line per event, task time in seconds, in the words of the thesis's Unity log, after a
settings line (the conditions of the trial: ``hrc.metrics.settings_line``), e.g.

    SETTINGS: anticipation on, safety policy retreat, seed 1; r1 max TCP speed 0.5 m/s, ...
    2024-05-02 14:03:11 - TASK STARTED.
    12.35 sec : Near-collision 1 between the robots.
    20.10 sec : Collision 1 occurred between r1 and left hand.
    23.42 sec : Continuing after robot-hand collision 1. Delayed 3.32 sec.
    61.00 sec : r1 - task FINISHED. Max speed reached : 0.500 m/s, average speed : 0.231 m/s.
        Waited human for 4.20 sec.
    70.25 sec : Human - task FINISHED. Idle (hands outside the workspace) for 2.10 sec.
    75.40 sec : TASK FINISHED. 1 total collisions.
    75.400 sec : 1 total near-collisions between the robots.

(The r1 line is one line in log.txt, wrapped here.)

The orchestrator writes the line into ``TaskEvent.text``; when present it is used as is (line
breaks folded into spaces, so each event stays one line), except the start line, always built
from ``wall_time`` when that is set (the thesis dates each trial). Otherwise the formatter of
the kind below writes it, so log.txt never lacks a line. Only the kinds in ``LOG_KINDS`` go to
log.txt (the thesis's log); every event goes to events.jsonl.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Callable
from dataclasses import dataclass

from hrc.wire import pb

K = pb.TaskEventKind


def kind_name(kind: pb.TaskEventKind.ValueType) -> str:
    """``TASK_EVENT_KIND_COLLISION`` -> ``COLLISION`` (unknown numbers stay readable)."""
    try:
        return K.Name(kind).removeprefix("TASK_EVENT_KIND_")
    except ValueError:
        return f"KIND_{kind}"


def secs(t: float) -> str:
    return f"{t:.2f}" if math.isfinite(t) else "?"


def wall_clock(iso: str) -> str:
    """ISO 8601 (TASK_STARTED.wall_time) -> ``YYYY-MM-DD HH:MM:SS`` in the time zone it carries."""
    if not iso:
        return "(no wall time)"
    try:
        return dt.datetime.fromisoformat(iso.replace("Z", "+00:00")).strftime("%Y-%m-%d %H:%M:%S")
    except ValueError:
        return iso


def _mps(v: float) -> str:
    return f"{v:.3f}" if math.isfinite(v) else "?"


@dataclass
class LogCounters:
    """What the text log counts itself (used when an event carries no payload)."""

    collisions: int = 0
    near_collisions: int = 0


def _task_started(ev: pb.TaskEvent, c: LogCounters) -> str:
    return f"{wall_clock(ev.wall_time)} - TASK STARTED."


def _near(ev: pb.TaskEvent, c: LogCounters) -> str:
    n = ev.near_collision.number if ev.HasField("near_collision") else c.near_collisions
    return f"{secs(ev.task_time)} sec : Near-collision {n} between the robots."


def _collision(ev: pb.TaskEvent, c: LogCounters) -> str:
    n = ev.collision.number if ev.HasField("collision") else c.collisions
    hand = f"{ev.hand} hand" if ev.hand else "hand"
    return (
        f"{secs(ev.task_time)} sec : Collision {n} occurred between {ev.robot or '?'} and {hand}."
    )


def _continued(ev: pb.TaskEvent, c: LogCounters) -> str:
    if ev.HasField("continued"):
        n, delay = ev.continued.number, secs(ev.continued.delay_s)
    else:
        n, delay = c.collisions, "?"
    return (
        f"{secs(ev.task_time)} sec : Continuing after robot-hand collision "
        f"{n}. Delayed {delay} sec."
    )


def _robot_finished(ev: pb.TaskEvent, c: LogCounters) -> str:
    robot = ev.robot or ev.agent or "robot"
    line = f"{secs(ev.task_time)} sec : {robot} - task FINISHED."
    if ev.HasField("robot_finished"):
        f = ev.robot_finished
        line += (
            f" Max speed reached : {_mps(f.max_tcp_speed_mps)} m/s, average speed : "
            f"{_mps(f.avg_tcp_speed_mps)} m/s. Waited human for {secs(f.idle_s)} sec."
        )
    return line


def _human_finished(ev: pb.TaskEvent, c: LogCounters) -> str:
    line = f"{secs(ev.task_time)} sec : Human - task FINISHED."
    if ev.HasField("human_finished"):
        line += f" Idle (hands outside the workspace) for {secs(ev.human_finished.idle_s)} sec."
    return line


def _task_finished(ev: pb.TaskEvent, c: LogCounters) -> str:
    n = ev.task_finished.human_robot_collisions if ev.HasField("task_finished") else c.collisions
    return f"{secs(ev.task_time)} sec : TASK FINISHED. {n} total collisions."


def near_total_line(ev: pb.TaskEvent, c: LogCounters) -> str:
    """The thesis log's count of near-collisions, written right after TASK FINISHED."""
    n = ev.task_finished.near_collisions if ev.HasField("task_finished") else c.near_collisions
    return f"{ev.task_time:.3f} sec : {n} total near-collisions between the robots."


def _unreachable(ev: pb.TaskEvent, c: LogCounters) -> str:
    what = f" ({ev.part})" if ev.part else ""
    return (
        f"{secs(ev.task_time)} sec : {ev.robot or ev.agent or 'robot'} - target unreachable{what}."
    )


def _protective_stop(ev: pb.TaskEvent, c: LogCounters) -> str:
    x = ev.protective_stop
    return (
        f"{secs(ev.task_time)} sec : {ev.robot} PROTECTIVE STOP {x.number}: separation "
        f"{x.separation_m:.3f} m, protective distance {x.protective_distance_m:.3f} m."
    )


def _protective_resume(ev: pb.TaskEvent, c: LogCounters) -> str:
    x = ev.protective_resume
    return (
        f"{secs(ev.task_time)} sec : {ev.robot} resumes after protective stop {x.number} "
        f"(stopped {secs(x.stopped_s)} sec)."
    )


FORMATTERS: dict[int, Callable[[pb.TaskEvent, LogCounters], str]] = {
    K.TASK_EVENT_KIND_TASK_STARTED: _task_started,
    K.TASK_EVENT_KIND_NEAR_COLLISION: _near,
    K.TASK_EVENT_KIND_COLLISION: _collision,
    K.TASK_EVENT_KIND_CONTINUED: _continued,
    K.TASK_EVENT_KIND_ROBOT_FINISHED: _robot_finished,
    K.TASK_EVENT_KIND_HUMAN_FINISHED: _human_finished,
    K.TASK_EVENT_KIND_TASK_FINISHED: _task_finished,
    K.TASK_EVENT_KIND_ROBOT_UNREACHABLE: _unreachable,
    # ssm only (docs/safety-ssm.md): beyond the thesis, logged like its collisions
    K.TASK_EVENT_KIND_PROTECTIVE_STOP: _protective_stop,
    K.TASK_EVENT_KIND_PROTECTIVE_RESUME: _protective_resume,
}
LOG_KINDS = frozenset(FORMATTERS)


class ThesisLog:
    """Turns task events into log.txt lines (pure; the writer is separate)."""

    def __init__(self) -> None:
        self.counters = LogCounters()

    def line_for(self, ev: pb.TaskEvent) -> str | None:
        """The log.txt line of ``ev``, or None if its kind is not in the thesis log."""
        if ev.kind == K.TASK_EVENT_KIND_COLLISION:
            self.counters.collisions += 1
        elif ev.kind == K.TASK_EVENT_KIND_NEAR_COLLISION:
            self.counters.near_collisions += 1
        fmt = FORMATTERS.get(ev.kind)
        if fmt is None:
            return None
        if ev.kind == K.TASK_EVENT_KIND_TASK_STARTED and ev.wall_time:
            return fmt(ev, self.counters)  # the thesis's start line: always the date and time
        text = " ".join(ev.text.split()) if ev.text.strip() else ""
        return text or fmt(ev, self.counters)

    def lines_for(self, ev: pb.TaskEvent) -> list[str]:
        """The log.txt lines of ``ev``: its line, and after TASK FINISHED the near-collision
        count (the thesis log ends with both)."""
        line = self.line_for(ev)
        if line is None:
            return []
        if ev.kind == K.TASK_EVENT_KIND_TASK_FINISHED:
            return [line, near_total_line(ev, self.counters)]
        return [line]


def loss_lines(losses: list[pb.LossSpan], task_start_sim: float) -> list[str]:
    """One line per span of simulated time in which messages never reached the logger (it was
    stopped or starved, and the bus dropped what it could not take), in task time."""

    def at(sim_s: float) -> str:
        return secs(max(0.0, sim_s - task_start_sim))

    return [
        f"{at(sp.to_s)} sec : RECORDING INCOMPLETE: {sp.messages} message(s) lost between "
        f"{at(sp.from_s)} and {at(sp.to_s)} sec (the logger could not take them; "
        "metrics.json, recording)."
        for sp in losses
    ]


def run_end_line(
    end: pb.RunEnd | None, reason: str, task_finished: bool, last_task_time: float
) -> str | None:
    """A closing line when the run did not end with TASK FINISHED (so the log says why)."""
    if end is not None and end.ok and task_finished:
        return None
    if end is None or not end.ok:
        why = (end.reason if end is not None else reason) or "unknown"
        who = (
            f" (service '{end.failed_participant}')"
            if end is not None and end.failed_participant
            else ""
        )
        return f"{secs(last_task_time)} sec : RUN ENDED WITH AN ERROR{who}: {why}"
    if not task_finished:
        why = end.reason or "stopped"
        return f"{secs(last_task_time)} sec : RUN ENDED before the task finished ({why})."
    return None
