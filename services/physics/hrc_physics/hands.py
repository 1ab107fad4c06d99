"""The participant's hands: kinematic box colliders posed from `HumanState`.

Hand frame (the pose `HumanState` carries): origin at the palm centre, which is also the grasp
point; x across the palm (0.09 m), y along the fingers (0.18 m, wrist to finger tips), z the palm
normal (0.03 m). With the identity orientation the hand lies flat, fingers towards +y (towards the
robots, as the participant stands at -y).
"""

from __future__ import annotations

from dataclasses import dataclass

import pybullet as p

from hrc.geometry import IDENTITY, Quat, Vec3
from hrc.scenario.conventions import HAND_SIZE

PARKED: Vec3 = (0.0, 0.0, -10.0)  # where a hand waits before its first HumanState


@dataclass
class Hand:
    name: str
    body: int
    pos: Vec3 = PARKED
    rot: Quat = IDENTITY
    grip: float = 0.0
    active: bool = False  # a HumanState has placed it
    holding: str = ""  # object id


def create_hand(client: int, name: str) -> Hand:
    half = [s / 2 for s in HAND_SIZE]
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
    visual = p.createVisualShape(
        p.GEOM_BOX, halfExtents=half, rgbaColor=[0.95, 0.75, 0.6, 1.0], physicsClientId=client
    )
    body = p.createMultiBody(
        0.0, shape, visual, list(PARKED), list(IDENTITY), physicsClientId=client
    )
    # Queries only: the hand pushes nothing (a held part follows it kinematically instead).
    p.setCollisionFilterGroupMask(body, -1, 0, 0, physicsClientId=client)
    return Hand(name, body)


def pose_hand(client: int, hand: Hand, pos: Vec3, rot: Quat, grip: float) -> bool:
    """Puts the hand there; True if it moved (or became active)."""
    moved = (pos, rot) != (hand.pos, hand.rot)
    if moved:
        p.resetBasePositionAndOrientation(hand.body, list(pos), list(rot), physicsClientId=client)
    activated = not hand.active
    hand.pos, hand.rot, hand.grip, hand.active = pos, rot, grip, True
    return moved or activated
