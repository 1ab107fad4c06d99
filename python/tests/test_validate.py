"""The content checks used as input validators."""

from __future__ import annotations

import math

import pytest

from hrc.validate import check_pose
from hrc.wire import pb


def test_a_finite_pose_passes() -> None:
    pose = pb.Pose()
    pose.position.x, pose.orientation.w = 0.3, 1.0
    assert check_pose(pose) is None


@pytest.mark.parametrize("field", ["position.x", "position.z", "orientation.y", "orientation.w"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_nan_or_infinite_value_anywhere_is_refused(field: str, bad: float) -> None:
    pose = pb.Pose()
    part, axis = field.split(".")
    setattr(getattr(pose, part), axis, bad)
    assert check_pose(pose) == "pose has a NaN or infinite value"
