"""Checks of received messages' content, used as input validators (``Bus.subscribe`` and
``Inbox`` take one): a message that fails is counted and logged like a malformed payload and
never reaches service code."""

from __future__ import annotations

import math
from collections.abc import Sequence

from hrc.wire import pb


def all_finite(values: Sequence[float]) -> bool:
    """No NaN or infinity among ``values``. Per message and tick, so one sum first: it is finite
    exactly when every term is, unless it overflows (then each value is looked at)."""
    return math.isfinite(sum(values)) or all(math.isfinite(v) for v in values)


def check_pose(pose: pb.Pose) -> str | None:
    """None, or why the pose is refused: NaN/inf values are rejected at the door."""
    p, q = pose.position, pose.orientation
    if not all_finite((p.x, p.y, p.z, q.x, q.y, q.z, q.w)):
        return "pose has a NaN or infinite value"
    return None
