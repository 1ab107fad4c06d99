"""The participant's side of the task: gating, placement judgement, idle time
(docs/task-semantics.md#human).

Only the next part of the human sequence is grabbable. While it is held and its `after` parts are
done, its target cue flashes. A release within the placement tolerance of its target (and with the
`after` parts done) snaps it onto the target; anywhere else it stays where physics leaves it and
can be grabbed again. Human idle time is task time with neither hand inside an envelope box,
counted from the start until the human's last part is placed.
"""

from __future__ import annotations

from hrc import scenario as sc
from hrc.geometry import (
    distance,
    pose_to_pb,
    quat_from_pb,
    quat_yaw_deg,
    vec3,
    vec3_from_pb,
    yaw_difference_deg,
    yaw_pose_deg,
)
from hrc.scenario.conventions import HANDS
from hrc.wire import pb

from hrc_orchestrator import events as ev
from hrc_orchestrator.board import Board
from hrc_orchestrator.idle import IntervalClock


class HumanAgent:
    def __init__(self, scenario: sc.Scenario, board: Board) -> None:
        self.sequence = scenario.sequence_of(sc.HUMAN)
        self.board = board
        self.tol_m = scenario.placement.tolerance_m
        self.tol_deg = scenario.placement.tolerance_deg
        self.index = 0
        self.held_part = ""
        self.held_hand = ""
        self.held_since = 0.0  # task time of the grab of held_part
        self.completion_s: float | None = None
        self.idle = IntervalClock()
        self._in_envelope: dict[tuple[str, str], None] = {}  # (hand, box) touching

    # ------------------------------------------------------------------ state
    @property
    def next_part(self) -> str:
        return self.sequence[self.index] if self.index < len(self.sequence) else ""

    @property
    def done(self) -> bool:
        return self.index >= len(self.sequence)

    @property
    def first_part(self) -> str:
        return self.sequence[0] if self.sequence else ""

    def grabbable(self, part_id: str, blocked: bool) -> bool:
        """Only the next part, and during a collision only if it is already in a hand."""
        if part_id != self.next_part:
            return False
        return not blocked or self.held_part == part_id

    def target_cue_wanted(self) -> bool:
        return bool(self.held_part) and not self.board.missing_deps(self.held_part)

    # ------------------------------------------------------------------ objects
    def grabbed(self, e: pb.ObjectEvent, t: float) -> None:
        if e.object != self.next_part or e.holder not in HANDS:
            return
        self.held_part, self.held_hand = e.object, e.holder
        self.held_since = t
        self.board.mark_grabbed(e.object, t)  # metrics keep the first grab; every grab is an event
        self.board.emit(ev.part_grabbed(t, sc.HUMAN, e.object, e.holder))

    def released(self, e: pb.ObjectEvent, t: float) -> None:
        if e.object != self.held_part or e.holder not in HANDS:
            return
        part = self.board.parts[e.object]
        hand = self.held_hand
        self.held_part, self.held_hand = "", ""
        if e.HasField("pose"):
            distance_m = distance(vec3_from_pb(e.pose.position), vec3(part.target.xyz))
            angle_deg = yaw_difference_deg(
                quat_yaw_deg(quat_from_pb(e.pose.orientation)), part.target.yaw
            )
        else:  # physics' own figures
            distance_m, angle_deg = e.target_distance_m, e.target_angle_deg
        missing = self.board.missing_deps(e.object)
        if missing:
            why = f"its target waits for {', '.join(missing)}"
        elif distance_m > self.tol_m or angle_deg > self.tol_deg:
            why = f"tolerance {self.tol_m * 100:g} cm / {self.tol_deg:g} deg"
        else:
            snap = yaw_pose_deg(part.target.xyz, part.target.yaw)
            self.board.command(
                pb.WorldCommand(
                    release=pb.Release(object=e.object, snap=True, pose=pose_to_pb(snap))
                )
            )
            self.board.mark_placed(e.object, t)
            self.board.emit(ev.part_placed(t, sc.HUMAN, e.object, hand))
            self.index += 1
            if self.done:
                self.finish(t)
            return
        self.board.emit(ev.part_released(t, e.object, hand, distance_m, angle_deg, why))

    def finish(self, t: float) -> None:
        self.completion_s = t
        self.idle.end(t)
        self.board.emit(ev.human_finished(t, self.idle.total))

    # ------------------------------------------------------------------ envelope (idle)
    def envelope(self, c: pb.Contact) -> None:
        key = (c.a, c.b)
        if c.begin:
            self._in_envelope[key] = None
        else:
            self._in_envelope.pop(key, None)

    @property
    def hands_in_workspace(self) -> bool:
        return bool(self._in_envelope)

    def update_idle(self, t: float, running: bool) -> None:
        """Opens/closes the idle interval from the envelope contacts (call after contacts)."""
        if not running or self.completion_s is not None:
            return
        if not self.hands_in_workspace:
            if self.idle.begin(t):
                self.board.emit(ev.human_idle(t, begin=True))
        elif self.idle.running:
            self.idle.end(t)
            self.board.emit(ev.human_idle(t, begin=False))
