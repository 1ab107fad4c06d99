"""The protective zone of speed and separation monitoring in the view (safety_policy = "ssm",
docs/safety-ssm.md): per robot, translucent spheres of radius S_p (the protective separation
distance at the arm's current speed, `hrc.ssm`) around its link origins, so their union is the
volume a hand or the head may not enter. Coloured by state: green normal, yellow reduced speed,
red protective stop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr

from hrc.scenario import Ssm
from hrc.ssm import protective_distance
from hrc.wire import pb

ALPHA = 45
COLORS = {
    "normal": (60, 190, 80),
    "reduced": (240, 200, 40),
    "stopped": (220, 40, 40),
}


@dataclass
class Zone:
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

    def archetype(self, centers: np.ndarray) -> rr.Ellipsoids3D:
        r = self.radius
        return rr.Ellipsoids3D(
            centers=centers,
            half_sizes=np.full((len(centers), 3), r),
            colors=[(*COLORS[self.state], ALPHA)],
            fill_mode="solid",
        )
