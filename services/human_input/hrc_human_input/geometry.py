"""Small vector and quaternion helpers (quaternions are (x, y, z, w), world frame of SPEC §2)."""

from __future__ import annotations

import math

import numpy as np

Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]

IDENTITY: Quat = (0.0, 0.0, 0.0, 1.0)


def lerp(a: float, b: float, u: float) -> float:
    return a + (b - a) * u


def lerp3(a: Vec, b: Vec, u: float) -> Vec:
    return (lerp(a[0], b[0], u), lerp(a[1], b[1], u), lerp(a[2], b[2], u))


def dist(a: Vec, b: Vec) -> float:
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a: Vec, s: float) -> Vec:
    return (a[0] * s, a[1] * s, a[2] * s)


def quat_norm(q: Quat) -> float:
    return math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)


def normalize(q: Quat) -> Quat:
    n = quat_norm(q)
    if n < 1e-12:
        raise ValueError("quaternion has zero length")
    # Leave unit quaternions bit-identical so a replay reproduces a recording exactly.
    if abs(n - 1.0) < 1e-12:
        return q
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def slerp(a: Quat, b: Quat, u: float) -> Quat:
    """Spherical interpolation along the shorter arc."""
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
    if dot < 0.0:
        b = (-b[0], -b[1], -b[2], -b[3])
        dot = -dot
    if dot > 0.9995:  # nearly equal: linear interpolation is exact enough and stable
        q = tuple(lerp(a[i], b[i], u) for i in range(4))
        return normalize(q)  # type: ignore[arg-type]
    theta = math.acos(min(1.0, dot))
    s = math.sin(theta)
    wa = math.sin((1.0 - u) * theta) / s
    wb = math.sin(u * theta) / s
    return (wa * a[0] + wb * b[0], wa * a[1] + wb * b[1], wa * a[2] + wb * b[2],
            wa * a[3] + wb * b[3])


def quat_mul(a: Quat, b: Quat) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def yaw_quat(yaw_rad: float) -> Quat:
    return (0.0, 0.0, math.sin(yaw_rad / 2.0), math.cos(yaw_rad / 2.0))


def pitch_quat(pitch_rad: float) -> Quat:
    """Rotation about x (positive tilts +y towards +z)."""
    return (math.sin(pitch_rad / 2.0), 0.0, 0.0, math.cos(pitch_rad / 2.0))


def yaw_of(q: Quat) -> float:
    """Yaw about world z (radians) of a rotation."""
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def wrap_angle(a: float) -> float:
    """Into [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def rot_z(v: Vec, angle: float) -> Vec:
    c, s = math.cos(angle), math.sin(angle)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


def look_quat(origin: Vec, target: Vec) -> Quat:
    """Orientation whose +y axis points from origin to target, z up (identity looks along +y)."""
    d = np.subtract(target, origin)
    horiz = math.hypot(d[0], d[1])
    if horiz < 1e-9 and abs(d[2]) < 1e-9:
        return IDENTITY
    yaw = math.atan2(-d[0], d[1])
    pitch = math.atan2(d[2], horiz)
    return quat_mul(yaw_quat(yaw), pitch_quat(pitch))
