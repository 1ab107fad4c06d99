"""One simulated hand: a queue of motor steps (minimum-jerk moves, dwells, grip changes) played on
simulation time. Steps chain at their exact end times, not at tick boundaries, so a sequence of
moves does not depend on the tick rate."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from hrc.geometry import Pose, Vec3, distance, wrap_angle_rad, yaw_quat_rad
from hrc.participant.motor import (
    MIN_JERK_PEAK_FACTOR,
    MIN_MOVEMENT_TIME_S,
    MotorParams,
    Segment,
    movement_time,
    path_length,
)
from hrc.scenario.conventions import HAND_RADIUS_M


@dataclass(frozen=True)
class Move:
    goal: Vec3
    yaw_rad: float | None = None  # None keeps the current yaw
    width: float = 0.06  # Fitts target width (m): the accuracy the move needs
    label: str = ""
    via: tuple[Vec3, ...] = ()  # points the hand passes through on its way, in one motion


@dataclass(frozen=True)
class Dwell:
    seconds: float
    label: str = ""


@dataclass(frozen=True)
class Grip:
    value: float
    label: str = ""


Step = Move | Dwell | Grip


class Hand:
    def __init__(
        self, name: str, pos: Vec3, yaw_rad: float, motor: MotorParams, rng: np.random.Generator
    ) -> None:
        self.name = name
        self.pos = pos
        self.yaw_rad = yaw_rad
        self._pose_yaw_rad = yaw_rad
        self.grip = 0.0
        self.motor = motor
        self.rng = rng
        self.plan: deque[Step] = deque()
        self.segment: Segment | None = None
        self.segments: list[Segment] = []  # every reach made (for analysis and tests)
        self._dwell_until: float | None = None
        self._grip_target: float | None = None
        self._cursor: float | None = None  # when the current step started / the last one ended
        self._t_last: float | None = None
        self._pose = Pose(pos, yaw_quat_rad(yaw_rad))  # pose() while pos and yaw_rad stay

    def pose(self) -> Pose:
        """Where the hand is and its yaw as a pose (rebuilt only when either changed)."""
        p = self._pose
        if p.position is not self.pos or self._pose_yaw_rad != self.yaw_rad:
            p = self._pose = Pose(self.pos, yaw_quat_rad(self.yaw_rad))
            self._pose_yaw_rad = self.yaw_rad
        return p

    # ------------------------------------------------------------------ commands
    def do(self, *steps: Step) -> None:
        self.plan.extend(steps)

    def cancel(self) -> None:
        """Stops where it is now (the grip keeps its value); what it does next starts now, not
        when the cancelled step started (which made the hand jump along its next move)."""
        self.plan.clear()
        self.segment = None
        self._dwell_until = None
        self._grip_target = None
        self._cursor = None

    @property
    def busy(self) -> bool:
        return (
            bool(self.plan)
            or self.segment is not None
            or self._dwell_until is not None
            or self._grip_target is not None
        )

    def pending_grip_change(self) -> bool:
        return self._grip_target is not None or any(isinstance(s, Grip) for s in self.plan)

    def goal(self) -> Vec3:
        """Where the hand is heading (its current move's end), or where it is."""
        if self.segment is not None:
            return self.segment.p1
        for s in self.plan:
            if isinstance(s, Move):
                return s.goal
        return self.pos

    def _grip_rate(self, target: float, grip: float) -> float:
        return 1.0 / (self.motor.grip_close_s if target > grip else self.motor.grip_open_s)

    def _plan_ahead(self, t: float) -> tuple[list[tuple[float, float, float]], float]:
        """The hand's plan from time ``t`` (after its advance to ``t``): its grip ramps in order
        as (start, grip from, grip to), and when it is done. Lower bounds: moves not started
        yet count at their shortest (the peak speed cap), the rest at their planned length."""
        ramps: list[tuple[float, float, float]] = []
        g, at, pos = self.grip, t, self.pos
        if self._grip_target is not None:
            v = self._grip_target
            ramps.append((at, g, v))
            at, g = at + abs(v - g) / self._grip_rate(v, g), v
        if self.segment is not None:
            at, pos = max(at, self.segment.t_end), self.segment.p1
        if self._dwell_until is not None:
            at = max(at, self._dwell_until)
        for step in self.plan:
            if isinstance(step, Move):
                d = distance(pos, step.goal)
                if d >= 1e-6:
                    at += max(
                        MIN_MOVEMENT_TIME_S, MIN_JERK_PEAK_FACTOR * d / self.motor.peak_hand_speed
                    )
                pos = step.goal
            elif isinstance(step, Dwell):
                at += max(0.0, step.seconds)
            else:
                v = min(1.0, max(0.0, step.value))
                ramps.append((at, g, v))
                at, g = at + abs(v - g) / self._grip_rate(v, g), v
        return ramps, at

    def grip_crossing_not_before(self, t: float, threshold: float) -> float | None:
        """A time before which the grip does not cross ``threshold`` (either way) as the hand
        goes through its plan from time ``t`` (after its advance to ``t``); None if the plan
        never crosses it. A lower bound (:meth:`_plan_ahead`)."""
        for at, g, v in self._plan_ahead(t)[0]:
            if (g < threshold) != (v < threshold):
                return at + abs(threshold - g) / self._grip_rate(v, g)
        return None

    def free_not_before(self, t: float) -> float:
        """A time before which the hand stays busy as it goes through its plan from time ``t``
        (after its advance to ``t``); ``t`` if it is not busy. A lower bound
        (:meth:`_plan_ahead`)."""
        return self._plan_ahead(t)[1]

    # ------------------------------------------------------------------ time
    def advance(self, t: float) -> None:
        if self._t_last is None:
            self._t_last = t
        dt = max(0.0, t - self._t_last)
        self._t_last = t
        if self._cursor is None:
            self._cursor = t
        # A grip ramp runs alongside (the fingers close while the hand is still).
        if self._grip_target is not None:
            rate = 1.0 / (
                self.motor.grip_close_s if self._grip_target > self.grip else self.motor.grip_open_s
            )
            step = rate * dt
            if abs(self._grip_target - self.grip) <= step:
                self.grip = self._grip_target
            else:
                self.grip += step if self._grip_target > self.grip else -step
        for _ in range(64):  # a few zero-length steps may complete in one tick
            if self.segment is not None:
                if self.segment.done(t):
                    self.pos, self.yaw_rad = self.segment.p1, self.segment.yaw1_rad
                    self._cursor = self.segment.t_end
                    self.segment = None
                    continue
                self.pos, self.yaw_rad = self.segment.position(t), self.segment.yaw_rad(t)
                return
            if self._dwell_until is not None:
                if t >= self._dwell_until:
                    self._cursor = self._dwell_until
                    self._dwell_until = None
                    continue
                return
            if self._grip_target is not None:
                if self.grip == self._grip_target:
                    self._grip_target = None
                    self._cursor = t
                    continue
                return
            if not self.plan:
                self._cursor = t
                return
            self._start(self.plan.popleft(), max(self._cursor, t - 1.0))

    def _start(self, step: Step, t0: float) -> None:
        if isinstance(step, Move):
            yaw1_rad = (
                self.yaw_rad
                if step.yaw_rad is None
                else (self.yaw_rad + wrap_angle_rad(step.yaw_rad - self.yaw_rad))
            )
            via = tuple(v for v in step.via if distance(v, self.pos) >= 1e-6)
            d = path_length((self.pos, *via, step.goal))
            if d < 1e-6 and abs(yaw1_rad - self.yaw_rad) < 1e-6:
                return
            mt = movement_time(d, step.width, self.motor, self.rng)
            if d < 1e-6:  # a pure turn of the wrist
                mt = max(mt, 0.2)
            # The turn, too, moves no point of the hand faster than the peak speed: a point
            # then moves at most 2 x peak_hand_speed (hand_speed_bound).
            turn = abs(yaw1_rad - self.yaw_rad) * HAND_RADIUS_M
            mt = max(mt, MIN_JERK_PEAK_FACTOR * turn / self.motor.peak_hand_speed)
            self.segment = Segment(t0, mt, self.pos, step.goal, self.yaw_rad, yaw1_rad, via)
            self.segments.append(self.segment)
        elif isinstance(step, Dwell):
            if step.seconds > 0:
                self._dwell_until = t0 + step.seconds
        else:
            self._grip_target = min(1.0, max(0.0, step.value))
