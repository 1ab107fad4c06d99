"""hrc.geometry: known rotations, round trips through the wire and numpy, and unit names."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest

from hrc import geometry as g
from hrc.wire import pb

ANGLES_DEG = [-180.0, -135.0, -90.0, -30.0, 0.0, 1e-9, 45.0, 90.0, 179.0]


def canonical(q: g.Quat) -> g.Quat:
    """q or -q (the same rotation), whichever has w >= 0."""
    return q if q[3] >= 0 else (-q[0], -q[1], -q[2], -q[3])


# ---------------------------------------------------------------- known rotations


def test_a_quarter_turn_about_z_takes_x_to_y() -> None:
    q = g.yaw_quat_deg(90.0)
    assert q == pytest.approx((0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)))
    assert g.rotate(q, (1.0, 0.0, 0.0)) == pytest.approx((0.0, 1.0, 0.0), abs=1e-15)
    assert g.rotate(q, (0.0, 0.0, 2.0)) == pytest.approx((0.0, 0.0, 2.0))


def test_degrees_and_radians_give_the_same_bits() -> None:
    for a in ANGLES_DEG:
        assert g.yaw_quat_deg(a) == g.yaw_quat_rad(math.radians(a))
        q = g.yaw_quat_deg(a)
        assert g.quat_yaw_deg(q) == math.degrees(g.quat_yaw_rad(q))


@pytest.mark.parametrize("yaw_deg", ANGLES_DEG)
def test_yaw_round_trip(yaw_deg: float) -> None:
    back = g.quat_yaw_deg(g.yaw_quat_deg(yaw_deg))
    assert g.yaw_difference_deg(back, yaw_deg) == pytest.approx(0.0, abs=1e-9)
    back_rad = g.quat_yaw_rad(g.yaw_quat_rad(math.radians(yaw_deg)))
    assert g.wrap_angle_rad(back_rad - math.radians(yaw_deg)) == pytest.approx(0.0, abs=1e-9)


def test_multiplying_yaws_adds_them_and_the_conjugate_undoes() -> None:
    q = g.quat_mul(g.yaw_quat_deg(30.0), g.yaw_quat_deg(60.0))
    assert q == pytest.approx(g.yaw_quat_deg(90.0))
    assert g.quat_mul(q, g.quat_conj(q)) == pytest.approx(g.IDENTITY)
    # b first, then a: a pitch then a yaw is not a yaw then a pitch
    pitch, yaw = g.pitch_quat_rad(math.pi / 2), g.yaw_quat_rad(math.pi / 2)
    v = (0.0, 1.0, 0.0)
    assert g.rotate(g.quat_mul(yaw, pitch), v) == pytest.approx(
        g.rotate(yaw, g.rotate(pitch, v)), abs=1e-15
    )
    assert g.rotate(g.quat_mul(yaw, pitch), v) == pytest.approx((0.0, 0.0, 1.0), abs=1e-15)


def test_pitch_tilts_y_towards_z() -> None:
    assert g.rotate(g.pitch_quat_rad(math.pi / 2), (0.0, 1.0, 0.0)) == pytest.approx(
        (0.0, 0.0, 1.0), abs=1e-15
    )


def test_look_quat_points_y_at_the_target() -> None:
    assert g.look_quat((0.0, 0.0, 0.0), (0.0, 2.0, 0.0)) == pytest.approx(g.IDENTITY)
    assert g.look_quat((1.0, 1.0, 1.0), (1.0, 1.0, 1.0)) == g.IDENTITY
    origin, target = (0.0, -0.7, 0.6), (0.3, 0.2, 0.0)
    axis = g.rotate(g.look_quat(origin, target), (0.0, 1.0, 0.0))
    d = g.sub(target, origin)
    n = math.sqrt(sum(c * c for c in d))
    assert axis == pytest.approx(tuple(c / n for c in d), abs=1e-12)


def test_rotate_z_rad_turns_counter_clockwise() -> None:
    assert g.rotate_z_rad((1.0, 0.0, 0.5), math.pi / 2) == pytest.approx((0.0, 1.0, 0.5), abs=1e-15)


def test_angles_wrap_and_differ_the_short_way() -> None:
    assert g.wrap_angle_rad(math.pi) == pytest.approx(-math.pi)
    assert g.wrap_angle_rad(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert g.yaw_difference_deg(170.0, -170.0) == pytest.approx(20.0)
    assert g.yaw_difference_deg(0.0, 360.0) == 0.0
    assert g.yaw_difference_deg(10.0, 190.0) == 180.0


def test_slerp_ends_and_the_short_way() -> None:
    a, b = g.yaw_quat_deg(10.0), g.yaw_quat_deg(80.0)
    assert g.slerp(a, b, 0.0) == pytest.approx(a)
    assert g.slerp(a, b, 1.0) == pytest.approx(b)
    assert g.quat_yaw_deg(g.slerp(a, b, 0.5)) == pytest.approx(45.0)
    far = tuple(-c for c in g.yaw_quat_deg(-170.0))  # same rotation, other hemisphere
    assert abs(g.quat_yaw_deg(g.slerp(g.yaw_quat_deg(170.0), far, 0.5))) == pytest.approx(180.0)


# ---------------------------------------------------------------- normalisation


def test_normalized_keeps_unit_quaternions_bit_identical() -> None:
    q = g.yaw_quat_deg(33.0)
    assert g.normalized(q) == q
    assert g.normalized((0.0, 0.0, 0.0, 2.0)) == (0.0, 0.0, 0.0, 1.0)
    assert g.quat_norm(g.normalized((1.0, 2.0, 3.0, 4.0))) == pytest.approx(1.0)


def test_a_zero_quaternion_raises_unless_told_what_it_means() -> None:
    with pytest.raises(ValueError, match="zero length"):
        g.normalized((0.0, 0.0, 0.0, 0.0))
    assert g.normalized((1e-13, 0.0, 0.0, 0.0), zero=g.IDENTITY) == g.IDENTITY


# ---------------------------------------------------------------- poses


def test_compose_and_relative_undo_each_other() -> None:
    a = g.Pose((0.3, -0.2, 0.1), g.quat_mul(g.yaw_quat_deg(40.0), g.pitch_quat_rad(0.3)))
    b = g.Pose((0.05, 0.0, 0.02), g.yaw_quat_deg(-15.0))
    world = g.compose(a, b)
    back = g.relative(a, world)
    assert back.position == pytest.approx(b.position, abs=1e-15)
    assert canonical(back.orientation) == pytest.approx(b.orientation, abs=1e-15)
    # a point 1 m along a's x axis
    turned = g.Pose((1.0, 0.0, 0.0), g.yaw_quat_deg(90.0))
    assert g.compose(turned, g.Pose((1.0, 0.0, 0.0))).position == pytest.approx(
        (1.0, 1.0, 0.0), abs=1e-15
    )


def test_a_pose_is_a_tuple() -> None:
    pos, rot = g.Pose((1.0, 2.0, 3.0))
    assert pos == (1.0, 2.0, 3.0) and rot == g.IDENTITY
    assert g.Pose() == ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    assert g.yaw_pose_deg([1, 2, 3], 0.0) == g.Pose((1.0, 2.0, 3.0), g.yaw_quat_deg(0.0))
    assert all(isinstance(c, float) for c in g.yaw_pose_deg([1, 2, 3], 0.0).position)


def test_interpolate_pose_lerps_and_slerps() -> None:
    a = g.Pose((0.0, 0.0, 0.0), g.yaw_quat_deg(0.0))
    b = g.Pose((2.0, 4.0, 0.0), g.yaw_quat_deg(90.0))
    m = g.interpolate_pose(a, b, 0.25)
    assert m.position == pytest.approx((0.5, 1.0, 0.0))
    assert g.quat_yaw_deg(m.orientation) == pytest.approx(22.5)


def test_point_box_distance_outside_inside_and_turned() -> None:
    box = g.Pose((1.0, 0.0, 0.0))
    half = (0.1, 0.2, 0.3)
    assert g.point_box_distance((1.05, 0.1, -0.2), box, half) == 0.0
    assert g.point_box_distance((1.5, 0.0, 0.0), box, half) == pytest.approx(0.4)
    assert g.point_box_distance((1.4, 0.6, 0.0), box, half) == pytest.approx(0.5)  # 0.3, 0.4
    turned = g.Pose((1.0, 0.0, 0.0), g.yaw_quat_deg(90.0))  # its x half-extent now along y
    assert g.point_box_distance((1.0, 0.15, 0.0), turned, half) == pytest.approx(0.05)
    assert g.point_box_distance((1.15, 0.0, 0.0), turned, half) == 0.0


def test_distance_and_vectors() -> None:
    assert g.distance((0.0, 0.0, 0.0), (3.0, 4.0, 0.0)) == 5.0
    assert g.add((1.0, 2.0, 3.0), (1.0, 1.0, 1.0)) == (2.0, 3.0, 4.0)
    assert g.sub((1.0, 2.0, 3.0), (1.0, 1.0, 1.0)) == (0.0, 1.0, 2.0)
    assert g.scale((1.0, 2.0, 3.0), 2.0) == (2.0, 4.0, 6.0)
    assert g.lerp3((0.0, 0.0, 0.0), (1.0, 2.0, 4.0), 0.5) == (0.5, 1.0, 2.0)
    assert g.vec3(np.array([1, 2, 3])) == (1.0, 2.0, 3.0)


# ---------------------------------------------------------------- the wire and numpy


def test_wire_round_trips_are_exact() -> None:
    pose = g.Pose((0.1, -0.2, 0.3), g.normalized((0.1, 0.2, 0.3, 0.9)))
    assert g.pose_from_pb(g.pose_to_pb(pose)) == pose
    assert g.vec3_from_pb(g.vec3_to_pb((1.5, -2.5, 1e-9))) == (1.5, -2.5, 1e-9)
    assert g.quat_from_pb(g.quat_to_pb(pose.orientation)) == pose.orientation
    msg = g.pose_yaw_to_pb((0.2, 0.1, 0.0), 30.0)
    assert msg.yaw_deg == 30.0 and g.vec3_from_pb(msg.xyz) == (0.2, 0.1, 0.0)
    assert g.pose_yaw_from_pb(msg) == g.yaw_pose_deg((0.2, 0.1, 0.0), 30.0)


@pytest.mark.parametrize(
    "pose", [g.Pose((0.1, -0.2, 0.3), (0.0, 0.0, 0.38, 0.92)), g.Pose((0.0,) * 3, (0.0,) * 4)]
)
def test_pose_into_pb_writes_the_bytes_pose_to_pb_makes(pose: g.Pose) -> None:
    built = pb.HumanState(head=g.pose_to_pb(pose))
    filled = pb.HumanState()
    g.pose_into_pb(filled.head, pose)
    assert filled.SerializeToString() == built.SerializeToString()
    assert filled.HasField("head")  # present even when every value is 0


def test_an_unset_orientation_is_the_identity() -> None:
    msg = pb.Pose(position=pb.Vec3(x=1.0))
    assert g.pose_from_pb(msg) == g.Pose((1.0, 0.0, 0.0), g.IDENTITY)
    assert g.quat_from_pb(pb.Quat()) == g.IDENTITY


def test_pose_from_pb_unit_scales_the_orientation() -> None:
    msg = g.pose_to_pb(g.Pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 2.0)))
    assert g.pose_from_pb(msg).orientation == (0.0, 0.0, 0.0, 2.0)
    assert g.pose_from_pb(msg, unit=True).orientation == (0.0, 0.0, 0.0, 1.0)
    tiny = g.pose_to_pb(g.Pose((0.0, 0.0, 0.0), (1e-14, 0.0, 0.0, 0.0)))
    assert g.pose_from_pb(tiny, unit=True).orientation == g.IDENTITY


def test_numpy_round_trip() -> None:
    a = g.to_array((0.1, 0.2, 0.3))
    assert a.dtype == np.float64 and a.shape == (3,)
    back = g.vec3_from_array(a)
    assert back == (0.1, 0.2, 0.3) and all(type(c) is float for c in back)
    assert g.to_array(g.IDENTITY).tolist() == [0.0, 0.0, 0.0, 1.0]


# ---------------------------------------------------------------- names carry units


def test_every_angle_name_says_its_unit() -> None:
    """A function that takes or gives an angle says its unit in its name (pose_yaw_* name the
    wire's PoseYaw, whose field is yaw_deg), and so does every angle parameter."""
    angle_words = ("yaw", "pitch", "angle", "rotate_z")
    checked = 0
    for name, obj in vars(g).items():
        if name.startswith("_") or not inspect.isfunction(obj) or obj.__module__ != g.__name__:
            continue
        if any(w in name for w in angle_words) and not name.startswith("pose_yaw_"):
            assert "_deg" in name or "_rad" in name, name
            checked += 1
        for param in inspect.signature(obj).parameters:
            if any(w in param for w in angle_words):
                assert param.endswith(("_deg", "_rad")), f"{name}({param})"
    assert checked >= 8
