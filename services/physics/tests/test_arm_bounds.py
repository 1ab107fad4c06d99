"""The contact checks and the exchange-step planner skip an arm that cannot have come near since
its AABB was last measured (KinematicRobot.bounds): the bound holds for the arms of the
project's scenarios (the thesis arm, the UR5e, the Panda), and the contacts and spans are those
of a world that measures every arm at every tick."""

from __future__ import annotations

import math
import random
from collections.abc import Callable

import pybullet as p
import pytest

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.wire import pb

from .conftest import human
from hrc_physics.closest import Box
from hrc_physics.exchange import SpanPlanner, arm_levers, arm_speed_terms
from hrc_physics.robots import KinematicRobot
from hrc_physics.world import World

ROOT = project_root()
SCENARIOS = ["thesis", "thesis-ur5e", "thesis-panda"]  # 5-DOF arms, UR5e, Panda (fingers slide)


def _walk(rng: random.Random, robot: KinematicRobot, q: list[float], step: float) -> list[float]:
    """A random step of every joint (up to ``step`` rad or m), kept inside its limits."""
    out = []
    for j, v in zip(robot.movable, q, strict=True):
        lo, hi = p.getJointInfo(robot.body, j, physicsClientId=robot._c)[8:10]
        v += rng.uniform(-step, step)
        out.append(min(max(v, lo), hi) if hi > lo else v)
    return out


def _true_box(robot: KinematicRobot) -> tuple[list[float], list[float]]:
    """The arm's AABB now, measured without touching what the arm keeps."""
    boxes = [p.getAABB(robot.body, link, physicsClientId=robot._c) for link in robot._links]
    lo = [min(b[0][i] for b in boxes) for i in range(3)]
    return lo, [max(b[1][i] for b in boxes) for i in range(3)]


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_colliders_stay_inside_the_last_box_grown_by_the_joints_travel(name: str) -> None:
    rng = random.Random(7)
    with World(sc.load(ROOT / "scenarios" / f"{name}.toml")) as world:
        for robot in world.robots.values():
            q = list(robot.positions)
            grown = []
            for tick in range(400):
                if tick % 50 == 0:
                    robot.aabb()  # measured: the bound starts again from here
                q = _walk(rng, robot, q, 0.03)
                robot.set_state(robot.joint_names, q)
                robot.apply()
                p.stepSimulation(physicsClientId=world.c)
                robot.stepped()
                bound = robot.bounds()
                assert bound is not None
                (lo, hi), d = bound
                grown.append(d)
                true_lo, true_hi = _true_box(robot)
                for i in range(3):
                    assert lo[i] - d <= true_lo[i] and true_hi[i] <= hi[i] + d, (
                        f"{name} {robot.id} tick {tick}: axis {i} [{true_lo[i]}, {true_hi[i]}] "
                        f"outside [{lo[i]}, {hi[i]}] grown by {d}"
                    )
            # the bound grows with the travel, and is of use: a few cm for one step of the joints
            assert min(grown) > 0.0 and grown[0] < 0.1, (name, robot.id, grown[:3])


def _hands(rng: random.Random, world: World, near: bool) -> object:
    """Both hands by an arm: within 10 cm of its box (often touching it), or 5 to 40 cm out
    from one of its faces (clear of it, at gaps that bound the next exchange's span)."""
    boxes = [_true_box(r) for r in world.robots.values()]

    def around() -> tuple[float, ...]:
        lo, hi = rng.choice(boxes)
        if near:
            return tuple(rng.uniform(a - 0.1, b + 0.1) for a, b in zip(lo, hi, strict=True))
        at = [rng.uniform(a, b) for a, b in zip(lo, hi, strict=True)]
        axis, out = rng.randrange(3), rng.uniform(0.05, 0.4)
        at[axis] = hi[axis] + out if rng.random() < 0.5 else lo[axis] - out
        return tuple(at)

    return human(left=around(), right=around())


def planner(world: World) -> SpanPlanner:
    """The exchange-step planner as the service makes it, for a slow hand (0.3 m/s: long
    spans at a few centimetres from an arm)."""
    return SpanPlanner(
        dt=world.settings.dt,
        hand_bound=2.0,
        arm_terms={rid: arm_speed_terms(r) for rid, r in world.robots.items()},
        arm_levers={rid: arm_levers(r) for rid, r in world.robots.items()},
        arm_pairs=[
            (a, b, world.robots[a].near_margin + world.robots[b].near_margin)
            for a, b in world.robot_pairs
        ],
    )


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_contacts_and_spans_are_those_found_by_checking_every_arm_at_every_tick(
    name: str,
) -> None:
    """Two worlds, the same inputs: the arms swing about (their first two joints lean them out
    and sweep them into each other), the hands now at an arm, now a little out; one world
    checks every arm at every tick. Every tick's contact events (every other 240 ticks: in
    between the planner alone measures the arms) and each exchange's span of 8 ticks are the
    same, and the other world measured fewer AABBs."""
    scenario = sc.load(ROOT / "scenarios" / f"{name}.toml")
    rng = random.Random(11)
    with World(scenario) as lazy, World(scenario) as every:
        for robot in every.robots.values():
            robot.bounds = lambda: None  # type: ignore[method-assign]  # no bound: always measure
        measured = {"lazy": 0, "every": 0}
        for label, world in (("lazy", lazy), ("every", every)):
            for robot in world.robots.values():

                def counted(
                    aabb: Callable[[], Box] = robot.aabb,
                    label: str = label,
                    robot: KinematicRobot = robot,
                ) -> Box:
                    if robot._aabb is None:
                        measured[label] += 1
                    return aabb()

                robot.aabb = counted  # type: ignore[method-assign]
        planners = {world: planner(world) for world in (lazy, every)}
        spans: set[int] = set()
        q = {rid: list(r.positions) for rid, r in lazy.robots.items()}
        seen: set[tuple[int, bool]] = set()
        hands = None
        for tick in range(1200):
            if tick % 60 == 0:
                hands = _hands(rng, every, near=tick % 120 == 0)  # then they stay for 60 ticks
            for k, rid in enumerate(q):
                q[rid] = _walk(rng, lazy.robots[rid], q[rid], 0.02)
                # the first two joints swing: the arms lean out and sweep into each other
                q[rid][0] = (-1) ** k * 0.6 * math.sin(tick / 150)
                q[rid][1] = 1.9 * math.sin(tick / 40)
            contacts, span = [], []
            for world in (lazy, every):
                for rid, robot in world.robots.items():
                    world.set_robot_state(rid, robot.joint_names, q[rid])
                    planners[world].declare(rid, robot.joint_names, [0.02] * len(q[rid]))
                world.set_human(hands)  # type: ignore[arg-type]
                world.step()
                if (tick // 240) % 2 == 0:  # else the planner alone: its bounds grow longer
                    contacts.append(
                        [(c.kind, c.begin, c.a, c.b, c.link) for c in world.contact_events()]
                    )
                if tick % 8 == 0:  # an exchange of 8 ticks
                    span.append(
                        planners[world].span(world.c, list(world.hands.values()), world.robots)
                    )
            assert contacts[:1] == contacts[1:], f"{name} tick {tick}: the contacts"
            assert span[:1] == span[1:], f"{name} tick {tick}: the next exchange's span"
            seen |= {(c[0], c[1]) for c in (contacts or [[]])[0]}
            spans.update(span)
        for kind in (pb.CONTACT_KIND_HAND_ROBOT, pb.CONTACT_KIND_ROBOT_ROBOT):
            assert (kind, True) in seen and (kind, False) in seen, (name, kind, seen)
        assert len(spans) > 3, spans  # spans of all sizes were compared
        assert measured["lazy"] < measured["every"], measured  # some arms were skipped
