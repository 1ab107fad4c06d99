"""Small geometry helpers on plain tuples (the task logic never needs more)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from hrc.wire import pb

Vec = tuple[float, float, float]


def vec(v: Sequence[float]) -> Vec:
    return (float(v[0]), float(v[1]), float(v[2]))


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def dist(a: Vec, b: Vec) -> float:
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


def from_pb(v: pb.Vec3) -> Vec:
    return (v.x, v.y, v.z)


def to_pb(v: Vec) -> pb.Vec3:
    return pb.Vec3(x=v[0], y=v[1], z=v[2])


def yaw_quat(yaw_deg: float) -> pb.Quat:
    half = math.radians(yaw_deg) / 2.0
    return pb.Quat(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def pose(position: Vec, yaw_deg: float) -> pb.Pose:
    return pb.Pose(position=to_pb(position), orientation=yaw_quat(yaw_deg))


def quat_yaw_deg(q: pb.Quat) -> float:
    """Yaw (rotation about world z) of a quaternion, degrees."""
    siny = 2.0 * (q.w * q.z + q.x * q.y)
    cosy = 1.0 - 2.0 * (q.y * q.y + q.z * q.z)
    return math.degrees(math.atan2(siny, cosy))


def yaw_diff_deg(a: float, b: float) -> float:
    """Smallest absolute difference of two yaws, in [0, 180]."""
    d = (a - b) % 360.0
    return min(d, 360.0 - d)
