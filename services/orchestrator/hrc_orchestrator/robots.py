"""Phase machines of the transport robot (r1) and the screwing robot (r2): see
docs/task-semantics.md, "Transport robot" and "Screwing robot".

Per part, transport:  to_pick -> (Attach) to_intermediate -> [waiting] -> to_place -> (Release)
                      returning -> next part ...; no parts left: to_home -> finished.
Per screw, screwing:  to_feeder -> (Spawn, Attach) to_intermediate -> [waiting] -> to_place ->
                      (Release) screwing (dwell >= screw_time_s) -> returning -> next ...

A phase advances only when the robot reports REACHED for the very command that phase sent
(RobotState.command_id), and only while no safety rule overrides the robot. The one exception is
the dependency wait: it ends as soon as the `after` parts are done, even during a collision (the
robot then heads for the place once it is released).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from hrc import scenario as sc
from hrc.geometry import Vec3, pose_to_pb, vec3, vec3_from_pb, vec3_to_pb, yaw_pose_deg
from hrc.scenario.conventions import APPROACH_HEIGHT_M, grasp_point
from hrc.wire import pb

from hrc_orchestrator import events as ev
from hrc_orchestrator.board import Board
from hrc_orchestrator.idle import IntervalClock

DWELL_EPS = 1e-9  # tick times are sums of floats; a dwell of exactly screw_time_s must count


class Phase(str, enum.Enum):
    NOT_STARTED = "not_started"
    TO_PICK = "to_pick"
    TO_FEEDER = "to_feeder"
    TO_INTERMEDIATE = "to_intermediate"
    WAITING = "waiting"
    TO_PLACE = "to_place"
    SCREWING = "screwing"
    RETURNING = "returning"
    TO_HOME = "to_home"
    FINISHED = "finished"


@dataclass(frozen=True)
class Motion:
    """A robot command without its id; equal motions are not sent twice."""

    kind: pb.RobotCommand.Kind.ValueType  # KIND_MOVE | KIND_HOLD
    target: Vec3 = (0.0, 0.0, 0.0)
    yaw_deg: float = 0.0
    approach: float = 0.0
    depart: float = 0.0
    detour: bool = False  # a safety interruption (retreat): the arm comes back to its task move

    @staticmethod
    def move(target: Vec3, yaw_deg: float, approach: float = 0.0, depart: float = 0.0) -> Motion:
        return Motion(pb.RobotCommand.KIND_MOVE, target, yaw_deg, approach, depart)

    @staticmethod
    def detour_to(target: Vec3, yaw_deg: float) -> Motion:
        return Motion(pb.RobotCommand.KIND_MOVE, target, yaw_deg, detour=True)

    @property
    def is_move(self) -> bool:
        return self.kind == pb.RobotCommand.KIND_MOVE

    def to_proto(self, robot: str, command_id: int) -> pb.RobotCommand:
        return pb.RobotCommand(
            robot=robot,
            command_id=command_id,
            kind=self.kind,
            target=vec3_to_pb(self.target),
            yaw_deg=self.yaw_deg,
            approach_height=self.approach,
            depart_height=self.depart,
            detour=self.detour,
        )


HOLD = Motion(pb.RobotCommand.KIND_HOLD)


MOVING_SPEED_MPS = 1e-3  # a TCP slower than 1 mm/s counts as standing still


@dataclass
class SpeedStats:
    """TCP speed figures of one arm, one sample per tick (docs/metrics.md):

    - `avg_moving`: the thesis's average, over the ticks in which the TCP moved (speed above
      MOVING_SPEED_MPS), up to the robot's last placement;
    - `avg_over_time`: over every tick up to home, standstill included;
    - `max`: the highest speed up to home.
    """

    n: int = 0
    total: float = 0.0
    n_moving: int = 0
    total_moving: float = 0.0
    max: float = 0.0

    def sample(self, speed: float, *, until_done: bool) -> None:
        self.n += 1
        self.total += speed
        self.max = max(self.max, speed)
        if until_done and speed > MOVING_SPEED_MPS:
            self.n_moving += 1
            self.total_moving += speed

    @property
    def avg_moving(self) -> float:
        return self.total_moving / self.n_moving if self.n_moving else 0.0

    @property
    def avg_over_time(self) -> float:
        return self.total / self.n if self.n else 0.0


class RobotAgent:
    """One arm: its phase machine, the command it was sent, its speed and idle figures."""

    def __init__(self, robot: sc.Robot, sequence: list[str], board: Board) -> None:
        self.cfg = robot
        self.id = robot.id
        self.screwing = robot.role == sc.RobotRole.SCREWING
        self.sequence = list(sequence)
        self.board = board
        self.index = 0
        self.phase = Phase.NOT_STARTED
        self.goal: Motion | None = None  # what the phase wants the arm to do
        self.carrying: str = ""  # part held from grab to placement
        self.dwell_since: float | None = None
        self.completion_s: float | None = None  # its last placement (the thesis's "done")
        self.home_s: float | None = None  # back home after it
        self.idle = IntervalClock()
        # command bookkeeping
        self.sent: Motion | None = None
        self.sent_id = 0
        self.state: pb.RobotState | None = None
        self._unreachable_reported = 0
        self.speed = SpeedStats()
        self._seen: list[tuple[int, float]] = []  # (tick, TCP speed) of states not yet sampled
        self._due: list[tuple[int, bool]] = []  # (tick, until_done) of samples not yet taken
        self._last_speed: float | None = None  # of the latest state sampled

    # ------------------------------------------------------------------ observations
    @property
    def part(self) -> str:
        return self.sequence[self.index] if self.index < len(self.sequence) else ""

    @property
    def finished(self) -> bool:
        return self.phase == Phase.FINISHED

    @property
    def tcp(self) -> Vec3 | None:
        return vec3_from_pb(self.state.tcp.position) if self.state is not None else None

    def observe(self, state: pb.RobotState) -> None:
        self.state = state
        self._seen.append((state.header.tick, state.tcp_speed))

    def sample_speed(self, tick: int, sampling: bool, first: bool) -> None:
        """One sample per tick t (while ``sampling``) of the latest state stamped before t
        (states come on change: an unchanged arm sends none, and its last state still holds).
        Inside an exchange the states of its ticks come only at its end (``first``: the tick
        opens one): its samples wait until then, so the figures are those of one-tick
        exchanges."""
        if sampling and not self.finished:
            self._due.append((tick, self.completion_s is None))
        if not first:
            return
        seen, j = self._seen, 0
        for t, until_done in self._due:
            while j < len(seen) and seen[j][0] < t:
                self._last_speed = seen[j][1]
                j += 1
            if self._last_speed is not None:
                self.speed.sample(self._last_speed, until_done=until_done)
        for _tick, speed in seen[j:]:
            self._last_speed = speed
        self._seen, self._due = [], []

    def reached(self, motion: Motion | None) -> bool:
        """The arm reports REACHED for the command that sent exactly `motion`."""
        return (
            motion is not None
            and self.sent == motion
            and self.state is not None
            and self.state.command_id == self.sent_id
            and self.state.status == pb.MOTION_STATUS_REACHED
        )

    def record_sent(self, motion: Motion) -> int:
        self.sent = motion
        self.sent_id += 1
        return self.sent_id

    # ------------------------------------------------------------------ targets
    def _intermediate(self, yaw_deg: float, depart: bool) -> Motion:
        return Motion.move(
            vec3(self.cfg.intermediate), yaw_deg, 0.0, APPROACH_HEIGHT_M if depart else 0.0
        )

    def _pick(self, part_id: str) -> Motion:
        part = self.board.parts[part_id]
        if self.screwing:
            feeder = vec3(self.cfg.feeder or (0.0, 0.0, 0.0))
            return Motion.move(grasp_point(feeder, part.size), 0.0, APPROACH_HEIGHT_M)
        assert part.start is not None  # checked by the scenario loader
        return Motion.move(
            grasp_point(vec3(part.start.xyz), part.size), part.start.yaw, APPROACH_HEIGHT_M
        )

    def _place(self, part_id: str) -> Motion:
        part = self.board.parts[part_id]
        return Motion.move(
            grasp_point(vec3(part.target.xyz), part.size), part.target.yaw, APPROACH_HEIGHT_M
        )

    # ------------------------------------------------------------------ phase machine
    def _enter(self, phase: Phase, t: float, goal: Motion | None) -> None:
        self.phase = phase
        self.goal = goal
        if phase not in (Phase.WAITING, Phase.FINISHED):
            label = "" if phase == Phase.TO_HOME else (self.carrying or self.part)
            self.board.emit(ev.robot_phase(t, self.id, phase.value, label))

    def _next_part(self, t: float) -> None:
        if self.index < len(self.sequence):
            self._enter(
                Phase.TO_FEEDER if self.screwing else Phase.TO_PICK, t, self._pick(self.part)
            )
        else:
            self._enter(Phase.TO_HOME, t, Motion.move(vec3(self.cfg.home), 0.0))

    def start(self, t: float) -> None:
        if self.phase == Phase.NOT_STARTED:
            if not self.sequence:
                self._done(t)  # nothing to place: done at once, then home
            self._next_part(t)

    def advance(self, t: float, active: bool) -> None:
        """One tick of the phase machine; `active` is False while a safety rule overrides it."""
        if self.phase in (Phase.NOT_STARTED, Phase.FINISHED):
            return
        if self.phase == Phase.WAITING:
            if not self.board.missing_deps(self.carrying):
                waited = self.idle.end(t) or 0.0
                self.board.emit(ev.robot_wait_over(t, self.id, self.carrying, waited))
                self._enter(Phase.TO_PLACE, t, self._place(self.carrying))
            return
        if not active:
            self.dwell_since = None  # an interrupted dwell starts again once back at the hole
            return
        self._check_unreachable(t)
        if not self.reached(self.goal):
            return
        if self.phase == Phase.SCREWING:
            if self.dwell_since is None:
                self.dwell_since = t
            if self.dwell_over(t):
                self.dwell_since = None
                self._enter(Phase.RETURNING, t, self._returning())
            return
        handler = {
            Phase.TO_PICK: self._grab,
            Phase.TO_FEEDER: self._grab,
            Phase.TO_INTERMEDIATE: self._at_intermediate,
            Phase.TO_PLACE: self._release,
            Phase.RETURNING: self._back_at_intermediate,
            Phase.TO_HOME: self._home,
        }[self.phase]
        handler(t)

    def dwell_end(self) -> float | None:
        """While screwing at the hole: the least task time t with
        ``t - dwell_since >= screw_time`` (advance()'s test; the dwell's end is a timer)."""
        if self.phase != Phase.SCREWING or self.dwell_since is None:
            return None
        return self.dwell_since + self.cfg.screw_time_or_default - DWELL_EPS

    def dwell_over(self, t: float) -> bool:
        """advance()'s test of the dwell at task time ``t``."""
        assert self.dwell_since is not None
        return t - self.dwell_since >= self.cfg.screw_time_or_default - DWELL_EPS

    def _returning(self) -> Motion:
        yaw_deg = self.goal.yaw_deg if self.goal is not None else 0.0
        return self._intermediate(yaw_deg, depart=True)

    def _grab(self, t: float) -> None:
        part_id = self.part
        part = self.board.parts[part_id]
        if self.screwing:
            feeder = vec3(self.cfg.feeder or (0.0, 0.0, 0.0))
            self.board.command(
                pb.WorldCommand(
                    spawn=pb.Spawn(
                        object=part_id,
                        pose=pose_to_pb(yaw_pose_deg(feeder, 0.0)),
                        size=vec3_to_pb(part.size),
                        kind=part.kind,
                        owner=self.id,
                    )
                )
            )
        self.board.command(pb.WorldCommand(attach=pb.Attach(object=part_id, holder=self.id)))
        self.carrying = part_id
        self.board.mark_grabbed(part_id, t)
        self.board.emit(ev.part_grabbed(t, self.id, part_id))
        self._enter(Phase.TO_INTERMEDIATE, t, self._intermediate(part.target.yaw, depart=True))

    def _at_intermediate(self, t: float) -> None:
        missing = self.board.missing_deps(self.carrying)
        if missing:
            self.phase = Phase.WAITING  # the goal stays: hold at the intermediate pose
            self.idle.begin(t)
            self.board.emit(ev.robot_waiting(t, self.id, self.carrying, missing))
        else:
            self._enter(Phase.TO_PLACE, t, self._place(self.carrying))

    def _release(self, t: float) -> None:
        part_id = self.carrying
        part = self.board.parts[part_id]
        snap = yaw_pose_deg(part.target.xyz, part.target.yaw)
        self.board.command(
            pb.WorldCommand(release=pb.Release(object=part_id, snap=True, pose=pose_to_pb(snap)))
        )
        self.board.mark_placed(part_id, t)
        self.board.emit(ev.part_placed(t, self.id, part_id))
        self.carrying = ""
        if self.index == len(self.sequence) - 1:
            self._done(t)
        if self.screwing:
            # The dwell counts from now: the goal is unchanged, the arm stays at the hole.
            self.dwell_since = t
            self.phase = Phase.SCREWING
            self.board.emit(ev.robot_phase(t, self.id, Phase.SCREWING.value, part_id))
        else:
            self._enter(Phase.RETURNING, t, self._returning())

    def _back_at_intermediate(self, t: float) -> None:
        self.index += 1
        self._next_part(t)

    def _done(self, t: float) -> None:
        """The last placement: the robot's list is empty (the thesis's "task FINISHED")."""
        self.completion_s = t
        self.board.emit(
            ev.robot_finished(t, self.id, self.speed.max, self.speed.avg_moving, self.idle.total)
        )

    def _home(self, t: float) -> None:
        self.phase = Phase.FINISHED
        self.home_s = t
        self.idle.end(t)

    def _check_unreachable(self, t: float) -> None:
        st = self.state
        if (
            st is not None
            and st.status == pb.MOTION_STATUS_UNREACHABLE
            and st.command_id == self.sent_id
            and self._unreachable_reported != self.sent_id
        ):
            self._unreachable_reported = self.sent_id
            self.board.emit(ev.robot_unreachable(t, self.id, st.detail))
