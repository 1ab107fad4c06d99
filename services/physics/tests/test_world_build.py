"""World building from the shipped scenarios and from the wire."""

from __future__ import annotations

import math

import pybullet as p
import pytest

from hrc import scenario as sc
from hrc.geometry import quat_yaw_deg, yaw_difference_deg
from hrc.paths import project_root
from hrc.scenario.layout import furniture

from hrc_physics.world import World


def _aabb(world: World, body: int):
    return p.getAABB(body, -1, physicsClientId=world.c)


def test_thesis_world_has_every_started_part_at_its_start(thesis: sc.Scenario) -> None:
    with World(thesis) as w:
        started = [part for part in thesis.parts if part.start is not None]
        assert list(w.objects) == [part.id for part in started]  # screws come from the feeder
        assert len(started) == 12
        for part in started:
            obj = w.objects[part.id]
            assert obj.size == tuple(part.size)
            assert obj.pose[0] == pytest.approx(tuple(part.start.xyz))
            assert yaw_difference_deg(quat_yaw_deg(obj.pose[1]), part.start.yaw) < 1e-6
            assert obj.target is not None and obj.target[0] == tuple(part.target.xyz)
        # Robots at their bases, from the URDF, zero pose (pointing up) before any state.
        assert set(w.robots) == {"r1", "r2"}
        r1 = w.robots["r1"]
        assert r1.joint_names == [
            "j1_base_yaw",
            "j2_shoulder",
            "j3_elbow",
            "j4_wrist_pitch",
            "j5_wrist_roll",
        ]
        assert set(r1.link_names.values()) >= {"base_link", "link3_forearm", "tool"}
        tool, _ = w.tool_pose("r1")
        assert tool == pytest.approx((0.45, 0.55, 1.12), abs=1e-6)
        # Furniture: board top at z = 0, picking table under r1's parts, r2's feeder and wall.
        for name in ("board", "table", "r1_picking_table", "r2_feeder", "r2_feeder_wall"):
            assert name in w.furniture
        lo, hi = _aabb(w, w.furniture["board"])
        assert hi[2] == pytest.approx(0.0, abs=1e-6)
        lo, hi = _aabb(w, w.furniture["r1_picking_table"])
        for part in thesis.parts_of("r1"):
            x, y, _ = part.start.xyz
            assert lo[0] < x < hi[0] and lo[1] < y < hi[1]
        assert hi[2] == pytest.approx(0.0, abs=1e-6)
        feeder = thesis.robots["r2"].feeder
        lo, hi = _aabb(w, w.furniture["r2_feeder"])
        assert hi[2] == pytest.approx(feeder[2] - 0.01, abs=1e-6)  # a 2 cm screw centred there
        _wall_lo, wall_hi = _aabb(w, w.furniture["r2_feeder_wall"])
        assert wall_hi[1] < feeder[1] and wall_hi[2] > hi[2]  # on the participant's side, higher
        assert w.button is not None and len(w.envelope) == 2


def test_target_markers_do_not_collide(thesis: sc.Scenario) -> None:
    boxes = {b.name: b for b in furniture(thesis)}
    for part in thesis.parts:
        marker = boxes[f"target:{part.id}"]
        assert not marker.collides
        assert marker.center == tuple(part.target.xyz)
    with World(thesis) as w:
        marker = w.furniture["target:H1"]
        assert p.getCollisionShapeData(marker, -1, physicsClientId=w.c) == ()


def test_parts_stay_put_and_fall_asleep(thesis: sc.Scenario) -> None:
    """Parts start resting on their tables: a second of simulation moves none of them."""
    with World(thesis) as w:
        first = w.object_states(full=True)
        assert len(first) == 12 and not any(s.moving for s in first)
        for _ in range(240):
            w.step()
            assert w.object_states() == []  # nothing moved, nothing changed
        assert w.take_events() == []
        for part in thesis.parts:
            if part.start is not None:
                obj = w.objects[part.id]
                pos, _ = p.getBasePositionAndOrientation(obj.body, physicsClientId=w.c)
                assert pos == pytest.approx(tuple(part.start.xyz), abs=1e-3), part.id
                assert not obj.awake


def test_minimal_world_and_wire_round_trip(minimal: sc.Scenario) -> None:
    wire = sc.from_proto(sc.to_proto(minimal))
    with World(minimal) as a, World(wire) as b:
        assert list(a.objects) == list(b.objects) == ["H1", "RA1"]
        assert a.furniture.keys() == b.furniture.keys()


def test_a_part_starting_in_the_air_falls_onto_the_table() -> None:
    text = (project_root() / "scenarios" / "minimal.toml").read_text()
    text = text.replace(
        "start = { xyz = [-0.20, -0.38, 0.02], yaw = 0 }",
        "start = { xyz = [-0.20, -0.38, 0.30], yaw = 0 }",
    )
    scen = sc.loads(text, project_root() / "scenarios", project_root())
    with World(scen) as w:
        moved = False
        for _ in range(480):
            w.step()
            moved |= any(s.id == "H1" and s.moving for s in w.object_states())
        assert moved
        assert w.objects["H1"].pose[0][2] == pytest.approx(0.02, abs=2e-3)
        assert not w.objects["H1"].moving
        assert w.take_events() == []  # nobody released it: no RESTED


def test_same_inputs_same_outputs(minimal: sc.Scenario, helpers) -> None:
    """Two worlds fed the same inputs end bit-identical (fixed step, fixed iterations)."""

    def trial() -> list[tuple]:
        with World(minimal) as w:
            w.step([helpers.grabbable("H1")])
            helpers.run(w, 5, helpers.human(left=(-0.20, -0.38, 0.02), left_grip=1.0))
            helpers.run(w, 5, helpers.human(left=(-0.05, 0.02, 0.15), left_grip=1.0))
            helpers.run(w, 300, helpers.human(left=(-0.05, 0.02, 0.15), left_grip=0.0))
            return [tuple(o.pose[0]) + tuple(o.pose[1]) for o in w.objects.values()]

    a, b = trial(), trial()
    assert a == b
    assert not math.isclose(a[0][0], -0.20)  # the part did move
