"""Our URDF FK (used by the view) agrees with rerun's own URDF joint transforms and with
geometry."""

from __future__ import annotations

import math
import random
from pathlib import Path

import numpy as np
import pytest
from rerun.urdf import UrdfTree

from hrc.paths import project_root
from hrc.urdf_fk import (
    UrdfError,
    UrdfModel,
    matrix_to_quat_xyzw,
    point_polyline_distance,
    polyline_distances,
    yaw_transform,
)

ARM5 = project_root() / "robots" / "arm5.urdf"


def _same_rotation(q1: tuple[float, ...], q2: np.ndarray) -> bool:
    return abs(abs(float(np.dot(np.asarray(q1), q2 / np.linalg.norm(q2)))) - 1.0) < 1e-6


def test_joint_transforms_match_rerun_urdf_loader() -> None:
    model = UrdfModel.from_file(ARM5)
    tree = UrdfTree.from_file_path(ARM5, frame_prefix="r1/")
    rng = random.Random(3)
    for _ in range(20):
        for j in tree.joints():
            ours = model.by_name[j.name]
            lo, hi = (j.limit_lower, j.limit_upper) if j.joint_type == "revolute" else (0.0, 0.0)
            q = rng.uniform(lo, hi)
            t = ours.local(q)
            theirs = j.compute_transform(q, clamp=False)
            trans = np.asarray(theirs.translation.pa_array.to_pylist()[0])
            quat = np.asarray(theirs.quaternion.pa_array.to_pylist()[0])
            assert np.allclose(t[:3, 3], trans, atol=1e-6), j.name
            assert _same_rotation(matrix_to_quat_xyzw(t[:3, :3]), quat), j.name
            assert (ours.parent, ours.child) == (j.parent_link, j.child_link)


def test_arm_points_straight_up_at_zero_and_bends_as_documented() -> None:
    model = UrdfModel.from_file(ARM5)
    assert model.movable == [
        "j1_base_yaw",
        "j2_shoulder",
        "j3_elbow",
        "j4_wrist_pitch",
        "j5_wrist_roll",
    ]
    base = yaw_transform([0.45, 0.55, 0.0], 180.0)
    tool = model.link_poses({}, base)["tool"]
    assert np.allclose(tool[:3, 3], [0.45, 0.55, 0.10 + 0.10 + 0.42 + 0.40 + 0.05 + 0.05])
    # shoulder pitched 90 deg: the arm lies along +x of the base (world -x for yaw 180)
    tool = model.link_poses({"j2_shoulder": math.pi / 2}, base)["tool"]
    assert np.allclose(tool[:3, 3], [0.45 - (0.42 + 0.40 + 0.10), 0.55, 0.20], atol=1e-9)
    # tool pointing down: j2 + j3 + j4 = pi  ->  tool z = world -z
    tool = model.link_poses(
        {"j2_shoulder": 0.5, "j3_elbow": 1.5, "j4_wrist_pitch": math.pi - 2.0}, base
    )["tool"]
    assert np.allclose(tool[:3, 2], [0, 0, -1], atol=1e-9)


def test_quaternion_round_trip() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        x, y, z, w = q
        r = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        assert _same_rotation(matrix_to_quat_xyzw(r), q)


def test_point_polyline_distance() -> None:
    pts = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 0]])
    assert point_polyline_distance(np.array([0.5, 0.3, 0.0]), pts) == pytest.approx(0.3)
    assert point_polyline_distance(np.array([2.0, 0.5, 0.0]), pts) == pytest.approx(1.0)
    assert point_polyline_distance(np.array([-1.0, 0, 0]), pts) == pytest.approx(1.0)
    assert point_polyline_distance(np.array([0, 0, 2.0]), pts[:1]) == pytest.approx(2.0)


@pytest.mark.parametrize(
    "text,match",
    [
        ("<robot", "not XML"),
        ("<model/>", "not <robot>"),
        (
            '<robot name="a"><link name="a"/><link name="b"/>'
            '<joint name="j" type="ball"><parent link="a"/>'
            '<child link="b"/></joint></robot>',
            "type 'ball'",
        ),
        (
            '<robot name="a"><link name="a"/><link name="b"/>'
            '<joint name="j" type="revolute"><parent link="a"/>'
            '<child link="b"/><origin xyz="0 0"/></joint></robot>',
            "expected 3 numbers",
        ),
        (
            '<robot name="a"><link name="a"/><link name="b"/>'
            '<joint name="j" type="revolute"><parent link="a"/>'
            '<child link="b"/><axis xyz="0 0 0"/></joint></robot>',
            "axis is zero",
        ),
        ('<robot name="a"><link name="a"/><link name="b"/></robot>', "one root link"),
    ],
)
def test_bad_urdf_is_named(text: str, match: str) -> None:
    with pytest.raises(UrdfError, match=match):
        UrdfModel.from_string(text, "x.urdf")


def test_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(UrdfError, match=r"nope\.urdf"):
        UrdfModel.from_file(tmp_path / "nope.urdf")


MIXED = """<robot name="mixed">
  <link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <joint name="rev" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.4 -0.5 2.9"/><axis xyz="0.3 0.5 -0.8"/></joint>
  <joint name="slide" type="prismatic"><parent link="b"/><child link="c"/>
    <origin xyz="0 0.2 0.1" rpy="1.2 0.3 -0.7"/><axis xyz="0 1 1"/></joint>
  <joint name="fix" type="fixed"><parent link="c"/><child link="d"/>
    <origin xyz="0.05 0 0" rpy="3.1 0 0"/></joint>
</robot>"""


@pytest.mark.parametrize("urdf", [MIXED, ARM5.read_text()])
def test_joint_columns_are_the_joint_transforms_row_by_row(urdf: str) -> None:
    """The view sends joint transforms in columns (local_columns): each row must be the joint's
    own transform at that position, as one rerun log call per state showed it."""
    model = UrdfModel.from_string(urdf)
    qs = np.random.default_rng(5).uniform(-3.2, 3.2, 40)
    for j in model.joints:
        translations, quats = j.local_columns(qs)
        for q, t, quat in zip(qs, translations, quats, strict=True):
            local = j.local(float(q))
            assert np.allclose(t, local[:3, 3], atol=1e-12), j.name
            assert np.allclose(quat, matrix_to_quat_xyzw(local[:3, :3]), atol=1e-9), j.name


@pytest.mark.parametrize("urdf", [MIXED, ARM5.read_text()])
def test_chain_columns_are_the_chains_row_by_row(urdf: str) -> None:
    """The view computes hand-robot distances for a whole column (chain_points_columns,
    polyline_distances): each row must be what the chain and distance of that state give."""
    model = UrdfModel.from_string(urdf)
    rng = np.random.default_rng(7)
    qs = rng.uniform(-3.2, 3.2, (30, len(model.joints)))
    hands = rng.uniform(-1.0, 1.0, (30, 3))
    base = yaw_transform([0.45, 0.55, 0.0], 180.0)
    for j in model.joints:
        stack = j.local_stack(qs[:, 0])
        for q, local in zip(qs[:, 0], stack, strict=True):
            assert np.allclose(local, j.local(float(q)), atol=1e-12), j.name
    chains = model.chain_points_columns(qs, base)
    distances = polyline_distances(hands, chains)
    for q, hand, chain, d in zip(qs, hands, chains, distances, strict=True):
        named = dict(zip([j.name for j in model.joints], q, strict=True))
        assert np.allclose(model.joint_vector(named), q)
        expected = model.chain_points(named, base)
        assert np.allclose(chain, expected, atol=1e-12)
        assert d == pytest.approx(point_polyline_distance(hand, expected), abs=1e-12)
    one = polyline_distances(hands[:2], chains[:2, :1])  # a single point: plain distance
    assert np.allclose(one, np.linalg.norm(hands[:2] - chains[:2, 0], axis=1))
