"""A small URDF forward-kinematics model (numpy): the logger's view and `hrc robot add`.

The view animates each robot by logging one transform per joint (parent link frame -> child link
frame) and measures hand-robot distances against the arm's link chain; both need the joint
transforms of the URDF at the joint positions reported on ``robot/<id>/state``.
Only what the view needs: joint origins (xyz, rpy), axes, revolute/continuous/prismatic/fixed.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from hrc.geometry import vec3

Mat = npt.NDArray[np.float64]  # transforms (4 x 4, or stacks of them), points, joint vectors

MOVABLE = ("revolute", "continuous", "prismatic")
KNOWN_TYPES = (*MOVABLE, "fixed")


class UrdfError(ValueError):
    """The URDF cannot be used for the view (names the file and what is wrong)."""


def rpy_matrix(roll: float, pitch: float, yaw: float) -> Mat:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def axis_angle_matrix(axis: Sequence[float], angle: float) -> Mat:
    """Rodrigues' rotation about a unit axis."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    return np.array(
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    )


def matrix_to_quat_xyzw(r: Mat) -> tuple[float, float, float, float]:
    """Rotation matrix -> unit quaternion (x, y, z, w) with w >= 0 (Shepperd's method)."""
    m = r
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w, x = 0.25 * s, (m[2, 1] - m[1, 2]) / s
        y, z = (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        w, x = (m[2, 1] - m[1, 2]) / s, 0.25 * s
        y, z = (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        w, x = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s
        y, z = 0.25 * s, (m[1, 2] + m[2, 1]) / s
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        w, x = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s
        y, z = (m[1, 2] + m[2, 1]) / s, 0.25 * s
    q = np.array([x, y, z, w])
    q /= np.linalg.norm(q)
    if q[3] < 0:
        q = -q
    return float(q[0]), float(q[1]), float(q[2]), float(q[3])


def quat_mul_xyzw(a: Mat, b: Mat) -> Mat:
    """Hamilton products a * b of (x, y, z, w) quaternions, row by row (N x 4, broadcast)."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def transform(rot: Mat, xyz: Sequence[float] | Mat) -> Mat:
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = xyz
    return t


def yaw_transform(xyz: Sequence[float], yaw_deg: float) -> Mat:
    """A base pose as the scenario writes it: position plus yaw about world z."""
    return transform(rpy_matrix(0.0, 0.0, math.radians(yaw_deg)), xyz)


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str
    parent: str
    child: str
    origin: Mat  # 4x4, parent link frame -> joint frame at q = 0
    axis: tuple[float, float, float]

    def local(self, q: float) -> Mat:
        """Parent link frame -> child link frame at joint position ``q``."""
        if self.kind in ("revolute", "continuous"):
            return self.origin @ transform(axis_angle_matrix(self.axis, q), (0.0, 0.0, 0.0))
        if self.kind == "prismatic":
            return self.origin @ transform(np.eye(3), np.asarray(self.axis) * q)
        return self.origin

    def local_stack(self, qs: Mat) -> Mat:
        """``local(q)`` for many joint positions at once: N x 4 x 4."""
        n = len(qs)
        out = np.broadcast_to(self.origin, (n, 4, 4)).copy()
        if self.kind in ("revolute", "continuous"):
            x, y, z = self.axis
            c, s = np.cos(qs), np.sin(qs)
            t = 1.0 - c
            rot = np.empty((n, 3, 3))  # Rodrigues, as axis_angle_matrix, row by row
            rot[:, 0, 0], rot[:, 0, 1], rot[:, 0, 2] = (
                t * x * x + c,
                t * x * y - s * z,
                t * x * z + s * y,
            )
            rot[:, 1, 0], rot[:, 1, 1], rot[:, 1, 2] = (
                t * x * y + s * z,
                t * y * y + c,
                t * y * z - s * x,
            )
            rot[:, 2, 0], rot[:, 2, 1], rot[:, 2, 2] = (
                t * x * z - s * y,
                t * y * z + s * x,
                t * z * z + c,
            )
            out[:, :3, :3] = self.origin[:3, :3] @ rot
        elif self.kind == "prismatic":
            shift = np.outer(qs, np.asarray(self.axis))
            out[:, :3, 3] += shift @ self.origin[:3, :3].T
        return out

    def local_columns(self, qs: Sequence[float] | Mat) -> tuple[Mat, Mat]:
        """``local(q)`` for many joint positions at once, as rerun takes them: translations
        (N x 3) and unit quaternions (x, y, z, w; w >= 0; N x 4). The view sends a joint's
        transforms in columns, so one call per column replaces a 4x4 product per row."""
        q = np.asarray(qs, dtype=np.float64)
        n = len(q)
        rot = self.origin[:3, :3]
        t0 = self.origin[:3, 3]
        q0 = np.asarray(matrix_to_quat_xyzw(rot))
        axis = np.asarray(self.axis, dtype=np.float64)
        if self.kind in ("revolute", "continuous"):
            half = q / 2.0
            turn = np.column_stack([np.outer(np.sin(half), axis), np.cos(half)])
            quats = quat_mul_xyzw(np.broadcast_to(q0, (n, 4)), turn)
            translations = np.broadcast_to(t0, (n, 3)).copy()
        else:
            quats = np.broadcast_to(q0, (n, 4)).copy()
            shift = np.outer(q, axis) if self.kind == "prismatic" else np.zeros((n, 3))
            translations = t0 + shift @ rot.T
        quats /= np.linalg.norm(quats, axis=1, keepdims=True)
        quats[quats[:, 3] < 0] *= -1.0
        return translations, quats


def _floats(text: str | None, n: int, default: float, what: str) -> tuple[float, ...]:
    if text is None:
        return (default,) * n
    parts = text.split()
    if len(parts) != n:
        raise UrdfError(f"{what}: expected {n} numbers, got {text!r}")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise UrdfError(f"{what}: not numbers: {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise UrdfError(f"{what}: NaN or infinite value in {text!r}")
    return values


class UrdfModel:
    """The kinematic tree of one URDF: joints in parent-before-child order."""

    def __init__(self, name: str, root: str, joints: list[Joint]) -> None:
        self.name = name
        self.root = root
        self.joints = joints
        self.by_name = {j.name: j for j in joints}
        self.movable = [j.name for j in joints if j.kind in MOVABLE]

    @classmethod
    def from_file(cls, path: str | Path) -> UrdfModel:
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except OSError as exc:
            raise UrdfError(f"URDF {p}: cannot read: {exc}") from None
        return cls.from_string(text, str(p))

    @classmethod
    def from_string(cls, text: str, source: str = "<string>") -> UrdfModel:
        try:
            robot = ET.fromstring(text)
        except ET.ParseError as exc:
            raise UrdfError(f"URDF {source}: not XML: {exc}") from None
        if robot.tag != "robot":
            raise UrdfError(f"URDF {source}: root element is <{robot.tag}>, not <robot>")
        links = [link.get("name", "") for link in robot.findall("link")]
        joints: list[Joint] = []
        for j in robot.findall("joint"):
            name = j.get("name") or ""
            kind = j.get("type") or ""
            where = f"URDF {source}: joint {name!r}"
            if kind not in KNOWN_TYPES:
                raise UrdfError(f"{where}: type {kind!r} is not one of {', '.join(KNOWN_TYPES)}")
            parent, child = j.find("parent"), j.find("child")
            if parent is None or child is None:
                raise UrdfError(f"{where}: needs <parent> and <child>")
            origin = j.find("origin")
            xyz = _floats(
                origin.get("xyz") if origin is not None else None, 3, 0.0, f"{where} origin xyz"
            )
            rpy = _floats(
                origin.get("rpy") if origin is not None else None, 3, 0.0, f"{where} origin rpy"
            )
            axis_el = j.find("axis")
            axis = vec3(
                _floats(
                    axis_el.get("xyz") if axis_el is not None else None, 3, 0.0, f"{where} axis"
                )
            )
            if axis_el is None:
                axis = (1.0, 0.0, 0.0)  # the URDF default
            norm = math.sqrt(sum(a * a for a in axis))
            if kind in MOVABLE and norm < 1e-12:
                raise UrdfError(f"{where}: axis is zero")
            if norm > 0:
                axis = (axis[0] / norm, axis[1] / norm, axis[2] / norm)
            joints.append(
                Joint(
                    name,
                    kind,
                    parent.get("link", ""),
                    child.get("link", ""),
                    transform(rpy_matrix(*rpy), xyz),
                    axis,
                )
            )
        children = {j.child for j in joints}
        roots = [link for link in links if link not in children]
        if len(roots) != 1:
            raise UrdfError(f"URDF {source}: expected one root link, found {roots or 'none'}")
        # Parent-before-child order, so a single pass computes every link's pose.
        ordered: list[Joint] = []
        known = {roots[0]}
        pending = list(joints)
        while pending:
            ready = [j for j in pending if j.parent in known]
            if not ready:
                raise UrdfError(
                    f"URDF {source}: joints not connected to the root: "
                    f"{', '.join(j.name for j in pending)}"
                )
            for joint in ready:
                ordered.append(joint)
                known.add(joint.child)
                pending.remove(joint)
        return cls(robot.get("name", ""), roots[0], ordered)

    def joint_transforms(self, q: Mapping[str, float]) -> dict[str, Mat]:
        """Every joint's local transform (parent link -> child link); missing joints at 0."""
        return {j.name: j.local(float(q.get(j.name, 0.0))) for j in self.joints}

    def link_poses(self, q: Mapping[str, float], base: Mat | None = None) -> dict[str, Mat]:
        """Every link's pose in the world (``base`` places the root link; identity if None)."""
        poses = {self.root: np.eye(4) if base is None else base}
        for j in self.joints:
            poses[j.child] = poses[j.parent] @ j.local(float(q.get(j.name, 0.0)))
        return poses

    def chain_points(self, q: Mapping[str, float], base: Mat | None = None) -> Mat:
        """Origins of the links in tree order (root first): the arm's skeleton, N x 3."""
        poses = self.link_poses(q, base)
        order = [self.root] + [j.child for j in self.joints]
        return np.array([poses[link][:3, 3] for link in order])

    def joint_vector(self, q: Mapping[str, float]) -> Mat:
        """``q`` as one position per joint in tree order (``self.joints``; missing: 0), the
        input of :meth:`chain_points_columns`."""
        return np.array([float(q.get(j.name, 0.0)) for j in self.joints])

    def chain_points_columns(self, qs: Mat, base: Mat | None = None) -> Mat:
        """``chain_points`` for many joint vectors at once (N x len(joints), as
        :meth:`joint_vector` gives them): N x (1 + len(joints)) x 3. The view computes the
        hand-robot distances of a whole column in one go instead of a chain per row."""
        n = len(qs)
        root = np.eye(4) if base is None else base
        poses = {self.root: np.broadcast_to(root, (n, 4, 4))}
        for i, j in enumerate(self.joints):
            poses[j.child] = poses[j.parent] @ j.local_stack(qs[:, i])
        order = [self.root] + [j.child for j in self.joints]
        return np.stack([poses[link][:, :3, 3] for link in order], axis=1)


def polyline_distances(p: Mat, pts: Mat) -> Mat:
    """Row by row ``point_polyline_distance``: points ``p`` (N x 3), polylines ``pts``
    (N x L x 3, L >= 1) -> N distances."""
    if pts.shape[1] == 1:
        return np.asarray(np.linalg.norm(p - pts[:, 0], axis=1))
    a, b = pts[:, :-1], pts[:, 1:]
    ab = b - a
    denom = np.einsum("nij,nij->ni", ab, ab)
    ap = p[:, None, :] - a
    safe = np.where(denom > 0, denom, 1.0)
    t = np.where(denom > 0, np.einsum("nij,nij->ni", ap, ab) / safe, 0.0)
    t = np.clip(t, 0.0, 1.0)
    closest = a + ab * t[:, :, None]
    return np.asarray(np.min(np.linalg.norm(closest - p[:, None, :], axis=2), axis=1))


def point_polyline_distance(p: Mat, pts: Mat) -> float:
    """Shortest distance from point ``p`` to the polyline through ``pts`` (N x 3, N >= 1)."""
    if len(pts) == 1:
        return float(np.linalg.norm(p - pts[0]))
    a, b = pts[:-1], pts[1:]
    ab = b - a
    denom = np.einsum("ij,ij->i", ab, ab)
    t = np.where(denom > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(denom > 0, denom, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    closest = a + ab * t[:, None]
    return float(np.min(np.linalg.norm(closest - p, axis=1)))
