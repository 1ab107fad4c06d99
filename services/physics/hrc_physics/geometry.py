"""Small pose helpers (positions as 3-tuples, quaternions as (x, y, z, w) like pybullet)."""

from __future__ import annotations

import math
from typing import Sequence

from hrc.wire import pb

Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]

IDENTITY: Quat = (0.0, 0.0, 0.0, 1.0)


def yaw_quat(yaw_deg: float) -> Quat:
    h = math.radians(yaw_deg) / 2.0
    return (0.0, 0.0, math.sin(h), math.cos(h))


def quat_yaw_deg(q: Sequence[float]) -> float:
    """Yaw (about world z) of a rotation, degrees in (-180, 180]."""
    x, y, z, w = q
    return math.degrees(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def yaw_difference_deg(a: float, b: float) -> float:
    """Smallest absolute angle between two yaws, in [0, 180]."""
    d = (a - b) % 360.0
    return min(d, 360.0 - d)


def normalized(q: Sequence[float]) -> Quat:
    """A unit quaternion; the all-zero quaternion (an unset proto field) means identity."""
    n = math.sqrt(sum(v * v for v in q))
    if n < 1e-12:
        return IDENTITY
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def quat_mul(a: Sequence[float], b: Sequence[float]) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def quat_conj(q: Sequence[float]) -> Quat:
    return (-q[0], -q[1], -q[2], q[3])


def rotate(q: Sequence[float], v: Sequence[float]) -> Vec:
    """v rotated by the unit quaternion q."""
    x, y, z, w = q
    vx, vy, vz = v
    # t = 2 * cross(q.xyz, v); v' = v + w * t + cross(q.xyz, t)
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


def compose(pos_a: Vec, rot_a: Quat, pos_b: Vec, rot_b: Quat) -> tuple[Vec, Quat]:
    """Pose a * pose b (b expressed in a's frame)."""
    r = rotate(rot_a, pos_b)
    return (pos_a[0] + r[0], pos_a[1] + r[1], pos_a[2] + r[2]), quat_mul(rot_a, rot_b)


def relative(pos_a: Vec, rot_a: Quat, pos_b: Vec, rot_b: Quat) -> tuple[Vec, Quat]:
    """Pose b expressed in frame a (inverse(a) * b)."""
    inv = quat_conj(rot_a)
    d = (pos_b[0] - pos_a[0], pos_b[1] - pos_a[1], pos_b[2] - pos_a[2])
    return rotate(inv, d), quat_mul(inv, rot_b)


def distance(a: Sequence[float], b: Sequence[float]) -> float:
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


def point_box_distance(point: Vec, center: Vec, rot: Quat, half: Vec) -> float:
    """Distance from a point to the surface of an oriented box (0 when the point is inside)."""
    local = rotate(quat_conj(rot), (point[0] - center[0], point[1] - center[1],
                                    point[2] - center[2]))
    d2 = 0.0
    for c, h in zip(local, half):
        excess = abs(c) - h
        if excess > 0.0:
            d2 += excess * excess
    return math.sqrt(d2)


# ---------------------------------------------------------------- wire conversions

def pose_from_pb(pose: pb.Pose) -> tuple[Vec, Quat]:
    p, q = pose.position, pose.orientation
    return (p.x, p.y, p.z), normalized((q.x, q.y, q.z, q.w))


def pose_to_pb(pos: Sequence[float], rot: Sequence[float]) -> pb.Pose:
    return pb.Pose(position=pb.Vec3(x=pos[0], y=pos[1], z=pos[2]),
                   orientation=pb.Quat(x=rot[0], y=rot[1], z=rot[2], w=rot[3]))

