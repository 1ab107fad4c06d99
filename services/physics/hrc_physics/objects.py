"""Parts and screws: dynamic boxes, kinematic while held, frozen once snapped."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import pybullet as p

from hrc.geometry import Pose, Quat, Vec3

DENSITY = 700.0  # kg/m^3: plastic-and-metal parts; only the ratio to gravity matters here
MIN_MASS = 0.005
FRICTION = 0.8
ROLLING_FRICTION = 0.001
# An object counts as still below these speeds; after REST_S seconds of stillness it has rested.
STILL_SPEED = 0.01  # m/s
STILL_SPIN = 0.2  # rad/s
REST_S = 0.1


@dataclass
class WorldObject:
    """One part's body and the state the world reports about it."""

    id: str
    kind: str
    owner: str
    size: Vec3
    mass: float
    body: int
    target: tuple[Vec3, float] | None  # (centre, yaw_deg) from the scenario, if it has one
    held_by: str = ""
    hold_offset: Pose = Pose()  # the object's pose in its holder's frame
    grabbable: bool = False
    placed: bool = False
    frozen: bool = False  # static (mass 0): held or snapped
    moving: bool = False  # free and in motion (falling, sliding, pushed)
    settling: bool = False  # released by a holder: RESTED is due when it comes to rest
    awake: bool = True  # free and watched until still; then put to sleep (not simulated)
    last_holder: str = ""
    still_ticks: int = 0
    dirty: bool = True  # state changed: publish it with the next world/objects
    pose: Pose = Pose()

    @property
    def half(self) -> Vec3:
        return (self.size[0] / 2, self.size[1] / 2, self.size[2] / 2)


def mass_of(size: Sequence[float]) -> float:
    return max(MIN_MASS, DENSITY * size[0] * size[1] * size[2])


def create_box(
    client: int,
    size: Sequence[float],
    pos: Vec3,
    rot: Quat,
    mass: float,
    rgba: Sequence[float] = (0.8, 0.8, 0.8, 1.0),
) -> int:
    half = [s / 2 for s in size]
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
    visual = p.createVisualShape(
        p.GEOM_BOX, halfExtents=half, rgbaColor=list(rgba), physicsClientId=client
    )
    body = p.createMultiBody(mass, shape, visual, list(pos), list(rot), physicsClientId=client)
    p.changeDynamics(
        body,
        -1,
        lateralFriction=FRICTION,
        rollingFriction=ROLLING_FRICTION,
        spinningFriction=ROLLING_FRICTION,
        restitution=0.0,
        activationState=p.ACTIVATION_STATE_ENABLE_SLEEPING,
        physicsClientId=client,
    )
    return body


def sleep(client: int, obj: WorldObject) -> None:
    """A part at rest costs the solver nothing while asleep; a moving body touching it wakes it."""
    p.changeDynamics(obj.body, -1, activationState=p.ACTIVATION_STATE_SLEEP, physicsClientId=client)
    obj.awake = False


def wake(client: int, obj: WorldObject) -> None:
    p.changeDynamics(
        obj.body, -1, activationState=p.ACTIVATION_STATE_WAKE_UP, physicsClientId=client
    )
    obj.awake = True
    obj.still_ticks = 0


def set_frozen(client: int, obj: WorldObject, frozen: bool) -> None:
    """Static (mass 0: moved only by us, unmoved by the solver) or dynamic again."""
    if obj.frozen == frozen:
        return
    p.changeDynamics(obj.body, -1, mass=0.0 if frozen else obj.mass, physicsClientId=client)
    p.resetBaseVelocity(obj.body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=client)
    obj.frozen = frozen
    if not frozen:
        wake(client, obj)


def place(client: int, obj: WorldObject, pos: Vec3, rot: Quat) -> None:
    p.resetBasePositionAndOrientation(obj.body, list(pos), list(rot), physicsClientId=client)
    obj.pose = Pose(pos, rot)
