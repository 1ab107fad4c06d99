"""The protective separation distance of speed and separation monitoring (ISO/TS 15066, 5.5.4)
and the allowed robot speed derived from it: the one implementation of the formula
(docs/safety-ssm.md). The orchestrator's policy (hrc_orchestrator.ssm), the logger's view of the
protective zone and the participant client's (the VR bridge's stream) use it.

    S_p(v) = S_h + S_r + S_s + C + Z_d + Z_r
    S_h = v_h (T_r + T_s),  T_s = v / a   (the human's approach while the robot reacts and stops)
    S_r = v T_r                           (the robot's travel during its reaction time)
    S_s = v^2 / (2 a)                     (its stopping distance at constant deceleration a)

Allowed speed from a separation S: the largest v with S_p(v) <= S (a quadratic in v), as in the
velocity-scaling formulation of Marvel and Norcross (2017):

    v_allowed = -(a T_r + v_h) + sqrt((a T_r + v_h)^2 + 2 a (S - v_h T_r - C - Z_d - Z_r))
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hrc.scenario import Ssm
from hrc.wire import pb


def scan_ticks(p: Ssm, dt: float) -> int:
    """The separation sensor's scan period in ticks (at least one): the monitor decides at the
    ticks that are multiples of it (docs/safety-ssm.md)."""
    return max(1, round(p.scan_period_s / dt))


def loop_ticks(scan: int) -> int:
    """Ticks from a separation measured at a scan to the arm moving at the speed chosen from
    it: what the monitor decides at a scan reaches the IK service at the next scan (``scan``
    ticks later, whatever the exchanges), which computes the tick after it, which physics
    then applies. With a scan at every tick, 3 (physics -> orchestrator -> IK -> physics)."""
    return scan + 2


def protective_distance(p: Ssm, robot_speed: float) -> float:
    """S_p (m) for a robot moving at `robot_speed` (m/s) towards a person approaching at
    p.human_speed."""
    v, a = max(0.0, robot_speed), p.deceleration
    stop_time = v / a
    s_h = p.human_speed * (p.reaction_time_s + stop_time)
    s_r = v * p.reaction_time_s
    s_s = v * v / (2.0 * a)
    return s_h + s_r + s_s + _constant(p)


def _constant(p: Ssm) -> float:
    return p.intrusion_distance_m + p.sensing_uncertainty_m + p.position_uncertainty_m


def allowed_speed(p: Ssm, separation: float) -> float:
    """The largest robot speed (m/s) whose protective distance fits in `separation` (m);
    0 at or below the protective distance of a robot at rest."""
    a = p.deceleration
    room = separation - p.human_speed * p.reaction_time_s - _constant(p)
    if not room > 0.0:  # also for NaN
        return 0.0
    b = a * p.reaction_time_s + p.human_speed
    return -b + math.sqrt(b * b + 2.0 * a * room)


def stop_distance(p: Ssm) -> float:
    """A robot makes a protective stop when the separation falls below this: the protective
    distance at the lowest speed it moves at (p.min_speed)."""
    return protective_distance(p, p.min_speed)


def resume_distance(p: Ssm) -> float:
    """A stopped robot resumes once the separation is at least this (the hysteresis)."""
    return stop_distance(p) + p.resume_margin_m


# The zone's colours by state (RGB) and its opacity (of 255): the logger's view and the
# participant client draw it alike.
ZONE_COLORS = {
    "normal": (60, 190, 80),
    "reduced": (240, 200, 40),
    "stopped": (220, 40, 40),
}
ZONE_ALPHA = 45


@dataclass
class Zone:
    """A robot's protective zone as the views show it: spheres of radius S_p (at the arm's current
    speed) around its link origins, in a state: normal, reduced (speed scale below 1) or stopped
    (between PROTECTIVE_STOP and PROTECTIVE_RESUME). Fed the robot's states and task events."""

    params: Ssm
    speed: float = 0.0  # the arm's TCP speed (m/s), from its latest state
    reduced: bool = False  # its speed scale is below 1
    stopped: bool = False  # between PROTECTIVE_STOP and PROTECTIVE_RESUME

    @property
    def state(self) -> str:
        return "stopped" if self.stopped else "reduced" if self.reduced else "normal"

    @property
    def radius(self) -> float:
        return protective_distance(self.params, self.speed)

    def observe(self, st: pb.RobotState) -> None:
        self.speed = st.tcp_speed
        self.reduced = st.HasField("speed_scale") and st.speed_scale < 1.0

    def event(self, ev: pb.TaskEvent) -> bool:
        """Takes a protective stop / resume; True if it was one."""
        if ev.kind == pb.TASK_EVENT_KIND_PROTECTIVE_STOP:
            self.stopped = True
        elif ev.kind == pb.TASK_EVENT_KIND_PROTECTIVE_RESUME:
            self.stopped = False
        else:
            return False
        return True
