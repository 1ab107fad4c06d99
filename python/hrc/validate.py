"""Checks of received messages' content, used as input validators (``Bus.subscribe`` and
``Inbox`` take one): a message that fails is counted and logged like a malformed payload and
never reaches service code."""

from __future__ import annotations

import math

from hrc.wire import pb


def check_pose(pose: pb.Pose) -> str | None:
    """None, or why the pose is refused: NaN/inf values are rejected at the door."""
    p, q = pose.position, pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z, q.x, q.y, q.z, q.w)):
        return "pose has a NaN or infinite value"
    return None
