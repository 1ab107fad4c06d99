"""The ssm safety policy's per-robot monitor (docs/safety-ssm.md): at each scan of the
separation sensor, the separation -> the robot's speed scale for the IK service, protective stops
and resumes (with hysteresis); a touch stops it at once; the ssm metrics. The formula itself is
`hrc.ssm`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from hrc.scenario import Ssm
from hrc.ssm import allowed_speed, loop_ticks, protective_distance, resume_distance, stop_distance

SCALE_STEP = 0.02  # the scale sent to the IK service is rounded down to this step


class SsmState(enum.StrEnum):
    NORMAL = "normal"  # full speed allowed
    REDUCED = "reduced"  # scaled below full speed
    STOPPED = "stopped"  # protective stop


@dataclass
class Change:
    """A protective stop or resume decided this tick (the monitor's caller emits the event)."""

    stopped: bool
    number: int
    separation_m: float
    protective_distance_m: float = 0.0
    stopped_s: float = 0.0
    body: str = ""


class SsmMonitor:
    """One robot: its separation, state, scale and figures."""

    def __init__(self, params: Ssm, max_speed: float, scan: int = 1) -> None:
        self.p = params
        self.max_speed = max_speed
        self.scan = scan  # ticks between two scans (hrc.ssm.scan_ticks)
        # Ticks between a separation measured at a scan and the arm moving at the speed chosen
        # from it (hrc.ssm.loop_ticks): the separation the speed is chosen for is what is left
        # after both sides close in for that long, so that the arm's actual speed keeps
        # S >= S_p(actual speed) (the check below) despite the loop.
        self.loop_ticks = loop_ticks(scan)
        # a stop for a touch, decided off a scan: sent at once (not at the scan's sending tick)
        self.urgent = False
        self.state = SsmState.NORMAL
        # The stop as the arm gets it: STOPPED from the tick its scale goes out (:meth:`due`)
        # until a resume goes out. What the task does about a stopped arm (the near-collision
        # hold passing to its partner) waits for it, so that it too goes out on a sending tick,
        # which every exchange ends at, never on a scan's own tick (inside an exchange).
        self.stopped_at_arm = False
        self.separation = params.sensing_range_m
        self.body = ""
        self.scale = 1.0  # what the IK service should apply (rounded down to SCALE_STEP)
        self.touched = False  # a hand touches the robot: stopped whatever the separation
        self.stops = 0
        self.stop_since = 0.0
        self.stop_s = 0.0
        self.reduced_s = 0.0
        self.min_separation: float | None = None

    def due(self, tick: int) -> bool:
        """What the scans decided goes out at ``tick``: the tick before the next scan, so
        that it reaches the IK service at that scan whatever the exchanges
        (docs/safety-ssm.md), or at once for a touch."""
        return self.urgent or (tick + 1) % self.scan == 0

    def observe(self, separation: float, body: str) -> None:
        self.separation, self.body = separation, body

    def update(
        self, t: float, dt: float, running: bool, speed: float = 0.0, tick: int = 0
    ) -> Change | None:
        """One tick: at a scan (``tick`` a multiple of ``scan``), the state and scale for the
        latest separation, the stop or resume if one happens; between scans only a touch
        stops the robot (at once). Time at reduced speed and in stops counts from the previous
        tick. ``speed``: the arm's actual TCP speed (m/s, its latest state): as ISO/TS 15066
        asks, the separation must also be at least S_p at that speed (the scale caps the speed
        to come, the arm may still be slowing down), else a protective stop."""
        if running:
            if self.state == SsmState.REDUCED:
                self.reduced_s += dt
            elif self.state == SsmState.STOPPED:
                self.stop_s += dt
        if tick % self.scan:
            if self.touched and running and self.state != SsmState.STOPPED:
                return self._stop(t, dt, speed, too_fast=False)
            return None
        if running and (self.min_separation is None or self.separation < self.min_separation):
            self.min_separation = self.separation  # (as the sensor saw it, at its scans)
        latency_s = self.loop_ticks * dt
        allowed = allowed_speed(self.p, self.separation - (self.p.human_speed + speed) * latency_s)
        change: Change | None = None
        if self.state == SsmState.STOPPED:
            # Resume once clear of the stop distance and of S_p at the speed the arm still has
            # (it may still be braking): with the margin, no stop-resume chattering.
            clear = max(
                resume_distance(self.p),
                protective_distance(self.p, speed) + self.p.resume_margin_m,
            )
            if self.touched or self.separation < clear:
                return None
            change = Change(False, self.stops, self.separation, stopped_s=t - self.stop_since)
        else:
            too_fast = speed > self.p.min_speed and self.separation < protective_distance(
                self.p, speed
            )
            if self.touched or too_fast or allowed < max(self.p.min_speed, 1e-9):
                if not running:
                    return None  # before the start the robots stand still anyway
                return self._stop(t, dt, speed, too_fast)
        raw = min(1.0, allowed / self.max_speed)
        # Rounded down to a step (fewer speed messages), except below the first step: an
        # allowed speed of at least min_speed must never round to a standstill that no
        # protective stop accounts for.
        if raw >= 1.0:
            self.scale = 1.0
        elif raw < SCALE_STEP:
            self.scale = raw
        else:
            self.scale = math.floor(raw / SCALE_STEP) * SCALE_STEP
        self.state = SsmState.NORMAL if self.scale >= 1.0 else SsmState.REDUCED
        return change

    def _stop(self, t: float, dt: float, speed: float, too_fast: bool) -> Change:
        self.state, self.scale = SsmState.STOPPED, 0.0
        self.urgent = self.touched  # a touch is acted on at once, scan or not
        self.stops += 1
        self.stop_since = t
        s_p = (
            protective_distance(self.p, speed)
            if too_fast
            else stop_distance(self.p) + (self.p.human_speed + speed) * self.loop_ticks * dt
        )
        return Change(True, self.stops, self.separation, s_p, body=self.body)
