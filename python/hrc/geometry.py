"""Positions, rotations and poses, and their wire and numpy forms: the project's one geometry
module (every service uses it; none keeps a copy).

Conventions:
- a position or vector is a ``Vec3``, a 3-tuple of floats in metres, world frame (x right, y away
  from the participant towards the robots, z up);
- a rotation is a ``Quat``, the tuple ``(x, y, z, w)`` (pybullet's order and the wire's field
  order); on the wire an all-zero ``Quat`` is an unset field and means the identity;
- yaw is the rotation about world z, positive counter-clockwise seen from above; every name that
  holds a yaw says its unit (``yaw_deg`` or ``yaw_rad``);
- a ``Pose`` is a position and an orientation; ``compose(a, b)`` is ``a * b`` (b expressed in a's
  frame).

The float operations are written in a fixed order on purpose: the golden trials compare their
outputs exactly, so rewriting an expression (even into a mathematically equal one) can change
them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from hrc.wire import pb

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

ORIGIN: Vec3 = (0.0, 0.0, 0.0)
IDENTITY: Quat = (0.0, 0.0, 0.0, 1.0)
_ZERO_LENGTH = 1e-12  # a quaternion shorter than this has no direction


class Pose(NamedTuple):
    """A position and an orientation (a tuple, so it unpacks as ``pos, rot = pose``)."""

    position: Vec3 = ORIGIN
    orientation: Quat = IDENTITY


# ---------------------------------------------------------------- vectors


def vec3(v: Sequence[float]) -> Vec3:
    """Any 3-sequence (list, numpy array, tuple of ints) as a ``Vec3`` of floats."""
    return (float(v[0]), float(v[1]), float(v[2]))


def add(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a: Sequence[float], s: float) -> Vec3:
    return (a[0] * s, a[1] * s, a[2] * s)


def distance(a: Sequence[float], b: Sequence[float]) -> float:
    """Euclidean distance between two points."""
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


def lerp(a: float, b: float, u: float) -> float:
    return a + (b - a) * u


def lerp3(a: Sequence[float], b: Sequence[float], u: float) -> Vec3:
    return (lerp(a[0], b[0], u), lerp(a[1], b[1], u), lerp(a[2], b[2], u))


def rotate_z_rad(v: Sequence[float], angle_rad: float) -> Vec3:
    """v turned about the z axis by ``angle_rad``."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


# ---------------------------------------------------------------- angles


def wrap_angle_rad(a_rad: float) -> float:
    """An angle into [-pi, pi)."""
    return (a_rad + math.pi) % (2.0 * math.pi) - math.pi


def yaw_difference_deg(a_deg: float, b_deg: float) -> float:
    """Smallest absolute angle between two yaws, in [0, 180]."""
    d = (a_deg - b_deg) % 360.0
    return min(d, 360.0 - d)


# ---------------------------------------------------------------- quaternions


def quat_norm(q: Sequence[float]) -> float:
    return math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)


def normalized(q: Sequence[float], *, zero: Quat | None = None) -> Quat:
    """q scaled to unit length. A unit quaternion (within 1e-12) comes back unchanged, so a replay
    reproduces a recording bit for bit. A zero-length q gives ``zero``, or raises ValueError when
    ``zero`` is None."""
    n = quat_norm(q)
    if n < _ZERO_LENGTH:
        if zero is None:
            raise ValueError("quaternion has zero length")
        return zero
    if abs(n - 1.0) < _ZERO_LENGTH:
        return (q[0], q[1], q[2], q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def quat_mul(a: Sequence[float], b: Sequence[float]) -> Quat:
    """The rotation a * b (b first, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quat_conj(q: Sequence[float]) -> Quat:
    """The conjugate: the inverse rotation of a unit quaternion."""
    return (-q[0], -q[1], -q[2], q[3])


def rotate(q: Sequence[float], v: Sequence[float]) -> Vec3:
    """v rotated by the unit quaternion q."""
    x, y, z, w = q
    vx, vy, vz = v
    # t = 2 * cross(q.xyz, v); v' = v + w * t + cross(q.xyz, t)
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


def slerp(a: Quat, b: Quat, u: float) -> Quat:
    """Spherical interpolation from a (u = 0) to b (u = 1) along the shorter arc."""
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
    if dot < 0.0:
        b = (-b[0], -b[1], -b[2], -b[3])
        dot = -dot
    if dot > 0.9995:  # nearly equal: linear interpolation is exact enough and stable
        return normalized(
            (lerp(a[0], b[0], u), lerp(a[1], b[1], u), lerp(a[2], b[2], u), lerp(a[3], b[3], u))
        )
    theta = math.acos(min(1.0, dot))
    s = math.sin(theta)
    wa = math.sin((1.0 - u) * theta) / s
    wb = math.sin(u * theta) / s
    return (
        wa * a[0] + wb * b[0],
        wa * a[1] + wb * b[1],
        wa * a[2] + wb * b[2],
        wa * a[3] + wb * b[3],
    )


def yaw_quat_rad(yaw_rad: float) -> Quat:
    """The rotation about world z by ``yaw_rad``."""
    return (0.0, 0.0, math.sin(yaw_rad / 2.0), math.cos(yaw_rad / 2.0))


def yaw_quat_deg(yaw_deg: float) -> Quat:
    """The rotation about world z by ``yaw_deg``."""
    return yaw_quat_rad(math.radians(yaw_deg))


def pitch_quat_rad(pitch_rad: float) -> Quat:
    """The rotation about x by ``pitch_rad`` (positive tilts +y towards +z)."""
    return (math.sin(pitch_rad / 2.0), 0.0, 0.0, math.cos(pitch_rad / 2.0))


def rpy_quat_deg(rpy_deg: Sequence[float]) -> Quat:
    """URDF's roll, pitch, yaw (about the fixed x, y, z axes, in that order: Rz·Ry·Rx), degrees."""
    qx = (
        math.sin(math.radians(rpy_deg[0]) / 2.0),
        0.0,
        0.0,
        math.cos(math.radians(rpy_deg[0]) / 2.0),
    )
    qy = (
        0.0,
        math.sin(math.radians(rpy_deg[1]) / 2.0),
        0.0,
        math.cos(math.radians(rpy_deg[1]) / 2.0),
    )
    return quat_mul(yaw_quat_deg(rpy_deg[2]), quat_mul(qy, qx))


def quat_rpy_deg(q: Sequence[float]) -> Vec3:
    """The inverse of `rpy_quat_deg` (pitch in [-90, 90] degrees)."""
    x, y, z, w = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return (math.degrees(roll), math.degrees(pitch), quat_yaw_deg(q))


def quat_yaw_rad(q: Sequence[float]) -> float:
    """The yaw (about world z) of a rotation, radians in [-pi, pi]."""
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_yaw_deg(q: Sequence[float]) -> float:
    """The yaw (about world z) of a rotation, degrees in [-180, 180]."""
    return math.degrees(quat_yaw_rad(q))


def look_quat(origin: Sequence[float], target: Sequence[float]) -> Quat:
    """The orientation whose +y axis points from origin to target with no roll (the identity
    looks along +y); the identity when the two points coincide."""
    d = sub(target, origin)
    horiz = math.hypot(d[0], d[1])
    if horiz < 1e-9 and abs(d[2]) < 1e-9:
        return IDENTITY
    yaw_rad = math.atan2(-d[0], d[1])
    pitch_rad = math.atan2(d[2], horiz)
    return quat_mul(yaw_quat_rad(yaw_rad), pitch_quat_rad(pitch_rad))


# ---------------------------------------------------------------- poses


def yaw_pose_deg(position: Sequence[float], yaw_deg: float) -> Pose:
    """A pose at ``position`` turned ``yaw_deg`` about world z (the scenario's poses)."""
    return Pose(vec3(position), yaw_quat_deg(yaw_deg))


def compose(a: Pose, b: Pose) -> Pose:
    """The pose a * b: b expressed in a's frame, seen in the frame a is expressed in."""
    pos_a, rot_a = a
    pos_b, rot_b = b
    r = rotate(rot_a, pos_b)
    return Pose((pos_a[0] + r[0], pos_a[1] + r[1], pos_a[2] + r[2]), quat_mul(rot_a, rot_b))


def relative(a: Pose, b: Pose) -> Pose:
    """Pose b expressed in frame a: inverse(a) * b."""
    pos_a, rot_a = a
    pos_b, rot_b = b
    inv = quat_conj(rot_a)
    return Pose(rotate(inv, sub(pos_b, pos_a)), quat_mul(inv, rot_b))


def interpolate_pose(a: Pose, b: Pose, u: float) -> Pose:
    """The pose a fraction ``u`` of the way from a to b: position linear, orientation slerp."""
    return Pose(lerp3(a.position, b.position, u), slerp(a.orientation, b.orientation, u))


def point_box_distance(point: Sequence[float], box: Pose, half_extents: Sequence[float]) -> float:
    """Distance from a point to the surface of an oriented box centred at ``box`` (0 inside)."""
    center, rot = box
    local = rotate(quat_conj(rot), sub(point, center))
    d2 = 0.0
    for c, h in zip(local, half_extents, strict=True):
        excess = abs(c) - h
        if excess > 0.0:
            d2 += excess * excess
    return math.sqrt(d2)


# ---------------------------------------------------------------- the wire (hrc.wire pb)


def vec3_from_pb(v: pb.Vec3) -> Vec3:
    return (v.x, v.y, v.z)


def vec3_to_pb(v: Sequence[float]) -> pb.Vec3:
    return pb.Vec3(x=v[0], y=v[1], z=v[2])


def quat_from_pb(q: pb.Quat) -> Quat:
    """The rotation as sent; the all-zero quaternion (an unset field) is the identity."""
    quat = (q.x, q.y, q.z, q.w)
    return IDENTITY if quat == (0.0, 0.0, 0.0, 0.0) else quat


def quat_to_pb(q: Sequence[float]) -> pb.Quat:
    return pb.Quat(x=q[0], y=q[1], z=q[2], w=q[3])


def pose_from_pb(msg: pb.Pose, *, unit: bool = False) -> Pose:
    """The pose as sent (an unset orientation is the identity); with ``unit``, its orientation
    scaled to unit length (see :func:`normalized`; a zero-length one is the identity)."""
    q = quat_from_pb(msg.orientation)
    return Pose(vec3_from_pb(msg.position), normalized(q, zero=IDENTITY) if unit else q)


def pose_to_pb(pose: Pose) -> pb.Pose:
    return pb.Pose(position=vec3_to_pb(pose.position), orientation=quat_to_pb(pose.orientation))


def pose_into_pb(dst: pb.Pose, pose: Pose) -> None:
    """Writes ``pose`` into a message's pose field in place (the same bytes as
    :func:`pose_to_pb`, a third of the time: no sub-messages built and copied)."""
    pos, rot = dst.position, dst.orientation
    pos.x, pos.y, pos.z = pose.position
    rot.x, rot.y, rot.z, rot.w = pose.orientation


def pose_yaw_from_pb(msg: pb.PoseYaw) -> Pose:
    """A scenario pose (position and ``yaw_deg``) as a full pose."""
    return yaw_pose_deg(vec3_from_pb(msg.xyz), msg.yaw_deg)


def pose_yaw_to_pb(position: Sequence[float], yaw_deg: float) -> pb.PoseYaw:
    return pb.PoseYaw(xyz=vec3_to_pb(position), yaw_deg=yaw_deg)


# ---------------------------------------------------------------- numpy


def to_array(v: Sequence[float]) -> npt.NDArray[np.float64]:
    """A vector or quaternion as a float64 numpy array."""
    return np.array(v, dtype=np.float64)


def vec3_from_array(a: npt.NDArray[np.float64]) -> Vec3:
    """The first three entries of a numpy array as a ``Vec3`` of Python floats."""
    return (float(a[0]), float(a[1]), float(a[2]))
