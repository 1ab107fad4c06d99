"""The cues in the rerun view: what shows each kind (a target's solid box, an object's outline,
a "Waiting.." label above a robot, the continue button), built from the cue, the scenario and,
for an outline, where its part was last seen."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr

from hrc.geometry import to_array, vec3_from_array, vec3_from_pb, yaw_quat_deg
from hrc.scenario.conventions import WAITING_HEIGHT_M, WAITING_TEXT
from hrc.wire import pb

from hrc_logger.entities import finite, rgb, rgba

WHITE = (255, 255, 255)
CONTINUE_RED = (255, 60, 60)


@dataclass
class CueView:
    cue: pb.Cue
    visible: bool = False
    # The archetype last shown and what it was built from (an outline: its part's pose): a
    # flashing cue is shown again every second, and building an archetype costs ~1 ms.
    shown: Any = None
    shown_for: tuple[float, ...] | None = None


def cue_archetype(
    c: pb.Cue,
    part: pb.PartConfig | None,
    seen: tuple[tuple[float, ...], tuple[float, ...]] | None,
    owner_rgb: tuple[int, int, int],
    robot_base: np.ndarray | None,
    button: np.ndarray,
) -> Any:
    """What shows the cue `c`: ``part`` is its part's configuration, ``seen`` the part's size
    and last pose on world/objects (x, y, z, qx, qy, qz, qw; None before it was seen),
    ``owner_rgb`` its robot's colour, ``robot_base`` its robot's base transform, ``button`` where
    the continue button is."""
    color = rgb(c.color, owner_rgb)
    pos = vec3_from_pb(c.position)
    given = any(abs(v) > 1e-12 for v in pos) and finite(pos)
    p = part
    if c.kind == pb.CUE_KIND_TARGET and p is not None:
        size = np.array([p.size.x, p.size.y, p.size.z]) * 1.15
        return rr.Boxes3D(
            half_sizes=[size / 2],
            centers=[vec3_from_pb(p.target.xyz)],
            quaternions=[yaw_quat_deg(p.target.yaw_deg)],
            colors=[rgba(color, 170)],
            fill_mode="solid",
            labels=[c.text or f"{c.part}"],
            show_labels=False,  # the part it is for carries the name
        )
    elif c.kind == pb.CUE_KIND_OUTLINE and (seen is not None or (p is not None and p.start_given)):
        if seen is not None:  # seen on world/objects
            size = np.array(seen[0])
            center, quat = np.array(seen[1][:3]), np.array(seen[1][3:])
        else:  # not seen on world/objects yet: where the scenario puts it
            assert p is not None
            size = np.array([p.size.x, p.size.y, p.size.z])
            center = to_array(vec3_from_pb(p.start.xyz))
            quat = to_array(yaw_quat_deg(p.start.yaw_deg))
        return rr.Boxes3D(
            half_sizes=[size * 1.3 / 2],
            centers=[center],
            quaternions=[quat],
            colors=[rgba(color, 255)],
            fill_mode="majorwireframe",
        )
    elif c.kind == pb.CUE_KIND_WAITING:
        if not given and robot_base is not None:
            pos = vec3_from_array(robot_base[:3, 3] + np.array([0.0, 0.0, WAITING_HEIGHT_M]))
        return rr.Points3D(
            [pos],
            radii=[0.02],
            colors=[color],
            labels=[c.text or WAITING_TEXT],
            show_labels=True,
        )
    elif c.kind == pb.CUE_KIND_CONTINUE_BUTTON:
        where = pos if given else list(button)
        return rr.Points3D(
            [where],
            radii=[0.03],
            colors=[rgb(c.color, CONTINUE_RED)],
            labels=[c.text or "Continue"],
            show_labels=True,
        )
    else:
        return rr.Points3D([pos], radii=[0.02], colors=[color], labels=[c.text or c.id])
