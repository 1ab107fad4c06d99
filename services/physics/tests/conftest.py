"""Shared fixtures of the physics unit tests: scenarios and small input builders."""

from __future__ import annotations

import pytest

from hrc import scenario as sc
from hrc.geometry import IDENTITY, Pose, pose_to_pb
from hrc.paths import project_root
from hrc.wire import pb

from hrc_physics.world import World

ROOT = project_root()


@pytest.fixture(scope="session")
def thesis() -> sc.Scenario:
    return sc.load(ROOT / "scenarios" / "thesis.toml")


@pytest.fixture(scope="session")
def minimal() -> sc.Scenario:
    return sc.load(ROOT / "scenarios" / "minimal.toml")


@pytest.fixture
def world(minimal: sc.Scenario):
    with World(minimal) as w:
        yield w


def human(
    left=(0.0, -0.6, 0.3),
    right=(0.3, -0.6, 0.3),
    left_grip=0.0,
    right_grip=0.0,
    rot=(0.0, 0.0, 0.0, 1.0),
) -> pb.HumanState:
    """A HumanState with both hands at the given positions (flat hands, fingers to +y)."""
    return pb.HumanState(
        left_hand=pose_to_pb(Pose(left, rot)),
        right_hand=pose_to_pb(Pose(right, rot)),
        left_grip=left_grip,
        right_grip=right_grip,
        head=pose_to_pb(Pose((0.0, -0.7, 0.5))),
    )


def grabbable(obj: str, on: bool = True) -> pb.WorldCommand:
    return pb.WorldCommand(set_grabbable=pb.SetGrabbable(object=obj, grabbable=on))


def snap(obj: str, pos, rot=IDENTITY) -> pb.WorldCommand:
    return pb.WorldCommand(
        release=pb.Release(object=obj, snap=True, pose=pose_to_pb(Pose(pos, rot)))
    )


def attach(obj: str, holder: str) -> pb.WorldCommand:
    return pb.WorldCommand(attach=pb.Attach(object=obj, holder=holder))


def spawn(obj: str, pos, size, owner="r2") -> pb.WorldCommand:
    return pb.WorldCommand(
        spawn=pb.Spawn(
            object=obj,
            pose=pose_to_pb(Pose(pos)),
            size=pb.Vec3(x=size[0], y=size[1], z=size[2]),
            kind="screw",
            owner=owner,
        )
    )


def run(world: World, ticks: int, msg: pb.HumanState | None = None) -> list[pb.ObjectEvent]:
    """Steps ``ticks`` times (with the same human input) and returns the object events."""
    events: list[pb.ObjectEvent] = []
    for _ in range(ticks):
        if msg is not None:
            world.set_human(msg)
        world.step()
        events += world.take_events()
    return events


@pytest.fixture
def helpers():
    """The builders above, for test modules (importlib mode cannot import conftest)."""

    class H:
        pass

    h = H()
    for f in (human, grabbable, snap, attach, spawn, run):
        setattr(h, f.__name__, staticmethod(f))
    return h
