"""The protective zone of speed and separation monitoring in the view (safety_policy = "ssm",
docs/safety-ssm.md): per robot, translucent spheres of radius S_p (the protective separation
distance at the arm's current speed, `hrc.ssm`) around its link origins, so their union is the
volume a hand or the head may not enter. Coloured by state: green normal, yellow reduced speed,
red protective stop.
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from hrc.ssm import ZONE_ALPHA as ALPHA
from hrc.ssm import ZONE_COLORS as COLORS
from hrc.ssm import Zone as ZoneState


class Zone(ZoneState):
    """The zone's state and size (hrc.ssm.Zone, shared with the participant client), drawn."""

    def archetype(self, centers: np.ndarray) -> rr.Ellipsoids3D:
        r = self.radius
        return rr.Ellipsoids3D(
            centers=centers,
            half_sizes=np.full((len(centers), 3), r),
            colors=[(*COLORS[self.state], ALPHA)],
            fill_mode="solid",
        )
