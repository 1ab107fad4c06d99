"""The content checks used as input validators."""

from __future__ import annotations

import math

import pytest

from hrc.validate import all_finite, check_pose
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


def test_huge_finite_values_pass_even_when_their_sum_overflows() -> None:
    pose = pb.Pose()
    pose.position.x = pose.position.y = 1e308  # the sum is inf: every value is looked at
    assert check_pose(pose) is None
    assert all_finite([1e308, 1e308, -1.0])


@pytest.mark.parametrize(
    "values", [[math.nan], [1.0, math.inf], [math.inf, -math.inf], [1e308, 1e308, math.nan]]
)
def test_all_finite_finds_any_nan_or_infinity(values: list[float]) -> None:
    assert not all_finite(values)


def test_all_finite_of_nothing_is_true() -> None:
    assert all_finite([])
