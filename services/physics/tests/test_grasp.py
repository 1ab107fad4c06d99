"""Human grasp and release, robot attach / snap, spawn, and rejected commands."""

from __future__ import annotations

import math

import pybullet as p
import pytest

from hrc.geometry import Pose, pose_to_pb, rotate, yaw_quat_deg
from hrc.wire import pb

from hrc_physics.world import CommandRejected, World

K = pb.ObjectEvent
H1_START = (-0.20, -0.38, 0.02)  # minimal.toml, size 0.10 x 0.04 x 0.04
H1_TARGET = (-0.18, -0.02, 0.02)


def _kinds(events: list[pb.ObjectEvent]) -> list[tuple[int, str, str]]:
    return [(e.kind, e.object, e.holder) for e in events]


def _grab_h1(w: World, h) -> None:
    w.step([h.grabbable("H1")])
    events = h.run(w, 1, h.human(left=H1_START, left_grip=1.0))
    assert _kinds(events) == [(K.KIND_GRABBED, "H1", "left")]


def test_grab_needs_grabbable_grip_and_distance(world: World, helpers) -> None:
    h = helpers
    # Closed hand on the part, but the orchestrator has not made it grabbable.
    assert h.run(world, 3, h.human(left=H1_START, left_grip=1.0)) == []
    world.set_human(h.human(left=(0.0, -0.6, 0.3)))  # away, open
    world.step([h.grabbable("H1")])
    assert world.take_events() == []
    # Grabbable, but the grip is open (below 0.5).
    assert h.run(world, 2, h.human(left=H1_START, left_grip=0.49)) == []
    # Closed, 4 cm above the top face (top at z = 0.04): too far (3 cm limit, to the surface).
    assert h.run(world, 2, h.human(left=(-0.20, -0.38, 0.08), left_grip=0.9)) == []
    # Closed, 2.5 cm above the top face: grabs.
    events = h.run(world, 1, h.human(left=(-0.20, -0.38, 0.065), left_grip=0.5))
    assert _kinds(events) == [(K.KIND_GRABBED, "H1", "left")]
    state = {s.id: s for s in world.object_states()}["H1"]
    assert state.held_by == "left" and state.moving


def test_held_part_follows_the_hand_and_reports_release(world: World, helpers) -> None:
    h = helpers
    _grab_h1(world, h)
    # Carry it to 1 cm beside its target (x + 0.01) and let go there.
    release_at = (H1_TARGET[0] + 0.01, H1_TARGET[1], H1_TARGET[2])
    h.run(world, 3, h.human(left=release_at, left_grip=1.0))
    assert world.objects["H1"].pose[0] == pytest.approx(release_at, abs=1e-9)
    events = h.run(world, 1, h.human(left=release_at, left_grip=0.2))
    assert _kinds(events) == [(K.KIND_RELEASED, "H1", "left")]
    rel = events[0]
    assert rel.target_distance_m == pytest.approx(0.01, abs=1e-6)
    assert rel.target_angle_deg == pytest.approx(0.0, abs=1e-6)
    assert (rel.pose.position.x, rel.pose.position.y) == pytest.approx(release_at[:2])
    # It was released right at its resting height: it comes to rest where it is.
    events = h.run(world, 120, h.human(left=(0.0, -0.6, 0.3)))
    assert _kinds(events) == [(K.KIND_RESTED, "H1", "left")]
    assert events[0].pose.position.z == pytest.approx(0.02, abs=1e-3)
    assert world.objects["H1"].held_by == ""


def test_a_release_arriving_with_the_hand_already_away_lets_go_where_it_was_released(
    world: World, helpers
) -> None:
    """Realtime: the release and the next state (the hand at rest) can arrive before one step;
    the release is still applied in a step of its own, where it was sent."""
    h = helpers
    _grab_h1(world, h)
    release_at = (H1_TARGET[0] + 0.01, H1_TARGET[1], H1_TARGET[2])
    h.run(world, 2, h.human(left=release_at, left_grip=1.0))
    world.set_human(h.human(left=release_at, left_grip=0.0))
    world.set_human(h.human(left=(0.0, -0.6, 0.3), left_grip=0.0))
    events = h.run(world, 1)
    assert _kinds(events) == [(K.KIND_RELEASED, "H1", "left")]
    assert (events[0].pose.position.x, events[0].pose.position.y) == pytest.approx(release_at[:2])
    h.run(world, 1)  # then the latest: the hand away, the part where it was let go
    assert world.hands["left"].pos == pytest.approx((0.0, -0.6, 0.3))
    assert world.objects["H1"].pose[0][:2] == pytest.approx(release_at[:2], abs=1e-3)


def test_released_far_from_target_falls_and_rests_on_the_table(world: World, helpers) -> None:
    h = helpers
    _grab_h1(world, h)
    turned = yaw_quat_deg(30.0)
    above = (H1_TARGET[0] + 0.10, H1_TARGET[1], 0.15)  # 10 cm off, 13 cm above the board
    h.run(world, 2, h.human(left=above, left_grip=1.0, rot=turned))
    events = h.run(world, 1, h.human(left=above, left_grip=0.0, rot=turned))
    assert _kinds(events) == [(K.KIND_RELEASED, "H1", "left")]
    assert events[0].target_distance_m == pytest.approx(math.hypot(0.10, 0.13), abs=1e-6)
    assert events[0].target_angle_deg == pytest.approx(30.0, abs=1e-6)
    moving_seen = False
    rested = []
    last: list[pb.ObjectState] = []
    for _ in range(480):
        world.step()
        rested += [e for e in world.take_events() if e.kind == K.KIND_RESTED]
        last = [s for s in world.object_states() if s.id == "H1"]
        moving_seen |= any(s.moving for s in last)
        if rested:
            break
    assert moving_seen and len(rested) == 1
    assert len(last) == 1 and not last[0].moving  # the state that says it stopped
    pos = rested[0].pose.position
    assert pos.z == pytest.approx(0.02, abs=2e-3)  # size z / 2: lying on the board
    assert (pos.x, pos.y) == pytest.approx(above[:2], abs=0.01)
    assert world.object_states() == []  # at rest: nothing more to publish


def test_snap_places_exactly_and_freezes(world: World, helpers) -> None:
    h = helpers
    _grab_h1(world, h)
    h.run(world, 1, h.human(left=(-0.16, -0.03, 0.05), left_grip=0.0))
    world.take_events()
    target_rot = yaw_quat_deg(0.0)
    world.step([h.snap("H1", H1_TARGET, target_rot)])
    events = world.take_events()
    assert _kinds(events) == [(K.KIND_SNAPPED, "H1", "left")]
    assert events[0].target_distance_m == pytest.approx(0.0, abs=1e-12)
    h.run(world, 240)
    obj = world.objects["H1"]
    pos, _ = p.getBasePositionAndOrientation(obj.body, physicsClientId=world.c)
    assert pos == pytest.approx(H1_TARGET, abs=1e-12)
    assert obj.placed and obj.frozen
    assert {s.id: s for s in world.object_states(full=True)}["H1"].placed
    # A placed part is done: a closed hand on it does not take it, even if marked grabbable.
    assert h.run(world, 3, h.human(left=H1_TARGET, left_grip=1.0)) == []


def _tool_down(world: World, robot: str, q2: float, q3: float) -> None:
    world.set_robot_state(robot, [], [0.0, q2, q3, math.pi - q2 - q3, 0.0])


def test_robot_attach_hangs_the_part_below_the_tool_and_snaps_it(world: World, helpers) -> None:
    h = helpers
    _tool_down(world, "r1", 0.6, 1.6)
    world.step([h.attach("RA1", "r1")])
    events = world.take_events()
    assert _kinds(events) == [(K.KIND_GRABBED, "RA1", "r1")]
    tool, rot = world.tool_pose("r1")
    assert rotate(rot, (0.0, 0.0, 1.0))[2] == pytest.approx(-1.0, abs=1e-6)  # pointing down
    size_z = world.objects["RA1"].size[2]
    centre = world.objects["RA1"].pose[0]
    assert centre == pytest.approx((tool[0], tool[1], tool[2] - size_z / 2), abs=1e-6)
    # The part follows the tool while the arm moves.
    _tool_down(world, "r1", 0.4, 1.9)
    world.step()
    tool, _ = world.tool_pose("r1")
    assert world.objects["RA1"].pose[0] == pytest.approx(
        (tool[0], tool[1], tool[2] - size_z / 2), abs=1e-6
    )
    assert {s.id: s for s in world.object_states()}["RA1"].held_by == "r1"
    target = (0.04, 0.16, 0.03)
    world.step([h.snap("RA1", target)])
    events = world.take_events()
    assert _kinds(events) == [(K.KIND_SNAPPED, "RA1", "r1")]
    h.run(world, 60)
    assert world.objects["RA1"].pose[0] == target and world.objects["RA1"].held_by == ""


def test_spawned_screw_rests_on_the_feeder(world: World, helpers) -> None:
    h = helpers
    feeder = (-0.60, 0.35, 0.05)
    with pytest.raises(CommandRejected, match=r"S1.*not been spawned"):
        world.apply(h.attach("S1", "r2"))
    world.step([h.spawn("S1", feeder, (0.012, 0.012, 0.02))])
    events = world.take_events()
    assert _kinds(events) == [(K.KIND_SPAWNED, "S1", "r2")]
    assert "S1" in {s.id for s in world.object_states()}
    h.run(world, 240)
    assert world.objects["S1"].pose[0] == pytest.approx(feeder, abs=2e-3)
    assert not world.objects["S1"].moving
    problems = world.step([h.spawn("S1", feeder, (0.012, 0.012, 0.02))])
    assert problems == ["spawn: object 'S1' already exists"]


def test_bad_commands_are_rejected_naming_the_object(world: World, helpers) -> None:
    h = helpers
    nan_pose = pose_to_pb(Pose((math.nan, 0.0, 0.0)))
    problems = world.step(
        [
            h.attach("X9", "r1"),
            h.attach("H1", "left"),
            pb.WorldCommand(release=pb.Release(object="H1", snap=True, pose=nan_pose)),
            pb.WorldCommand(release=pb.Release(object="H1", snap=False)),
            h.grabbable("nope"),
            h.spawn("S9", (0.0, 0.0, math.inf), (0.01, 0.01, 0.01)),
            h.spawn("S8", (0.0, 0.0, 0.1), (0.0, 0.01, 0.01)),
            pb.WorldCommand(),
            h.grabbable("H1"),  # a good one after the bad ones still applies
        ]
    )
    assert len(problems) == 8
    assert "unknown object 'X9'" in problems[0]
    assert "holder 'left' is not a robot" in problems[1]
    assert "'H1'" in problems[2] and "NaN" in problems[2]
    assert "'H1': it is not held" in problems[3]
    assert "unknown object 'nope'" in problems[4]
    assert "'S9'" in problems[5] and "S8" in problems[6]
    assert world.rejected["X9"] == 1 and world.rejected["H1"] == 3
    assert world.objects["H1"].grabbable
    with pytest.raises(CommandRejected, match="unknown robot 'r7'"):
        world.set_robot_state("r7", [], [0.0] * 5)
    with pytest.raises(CommandRejected, match="no joint named elbow"):
        world.set_robot_state("r1", ["elbow"], [0.0])
    with pytest.raises(CommandRejected, match="NaN"):
        world.set_robot_state("r1", [], [0.0, math.nan, 0.0, 0.0, 0.0])
    with pytest.raises(CommandRejected, match="3 joint positions for 5 joints"):
        world.set_robot_state("r1", [], [0.0] * 3)
    world.step()  # the world carries on


def test_joint_states_by_name_in_any_order(world: World) -> None:
    world.set_robot_state("r1", ["j3_elbow", "j2_shoulder"], [1.0, 0.5])
    world.step()
    r1 = world.robots["r1"]
    states = p.getJointStates(r1.body, r1.movable, physicsClientId=world.c)
    assert [s[0] for s in states] == pytest.approx([0.0, 0.5, 1.0, 0.0, 0.0], abs=1e-12)
    for _ in range(240):  # kinematic: gravity never makes the arm sag between states
        world.step()
    states = p.getJointStates(r1.body, r1.movable, physicsClientId=world.c)
    assert [s[0] for s in states] == pytest.approx([0.0, 0.5, 1.0, 0.0, 0.0], abs=1e-12)
