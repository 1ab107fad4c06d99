"""The scripted participant's plans for one part: the reach that grasps it and the carry that
places it, as steps of the hand (hrc.participant.hand). MTM's elements time the same plans."""

from __future__ import annotations

from hrc.geometry import Vec3
from hrc.participant.hand import Dwell, Grip, Move, Step
from hrc.participant.motor import MotorParams

APPROACH_CLEARANCE = 0.08  # approach and leave a part vertically from this far above
CARRY_CLEARANCE = 0.10  # carry a held part this far above the higher of start and goal
PICK_WIDTH = 0.06  # Fitts width: a grasp succeeds within 3 cm
GROSS_WIDTH = 0.10  # Fitts width of lifts, withdrawals and pull-backs


def reach_plan(
    above: Vec3,
    goal: Vec3,
    yaw_rad: float,
    motor: MotorParams,
    stop_above: bool,
    pick_dwell_s: float,
) -> list[Step]:
    """Open the hand, reach the grasp point from above (stopping there first, or passing
    through in one motion), close the grip and dwell: the reach for a part."""
    if stop_above:
        moves = [
            Move(above, yaw_rad, PICK_WIDTH, "reach"),
            Move(goal, yaw_rad, PICK_WIDTH, "descend"),
        ]
    else:
        moves = [Move(goal, yaw_rad, PICK_WIDTH, "reach", via=(above,))]
    return [
        Grip(0.0),
        *moves,
        Grip(1.0, "grip"),
        Dwell(max(0.0, pick_dwell_s - motor.grip_close_s), "pick dwell"),
    ]


def place_plan(
    start: Vec3,
    carry_z: float,
    release: Vec3,
    yaw_rad: float,
    place_width: float,
    stop_above: bool,
    place_dwell_s: float,
) -> list[Step]:
    """Carry a held part from ``start`` at height ``carry_z`` to above its release point, lower
    it, dwell, let go, dwell: lift, carry and lower as three moves, or as one motion."""
    lift = (start[0], start[1], carry_z)
    hover = (release[0], release[1], carry_z)
    lifts = carry_z - start[2] > 0.01
    if stop_above:
        moves = [Move(lift, None, GROSS_WIDTH, "lift")] if lifts else []
        moves += [
            Move(hover, yaw_rad, PICK_WIDTH, "carry"),
            Move(release, yaw_rad, place_width, "lower"),
        ]
    else:
        via = (lift, hover) if lifts else (hover,)
        moves = [Move(release, yaw_rad, place_width, "carry", via=via)]
    return [
        *moves,
        Dwell(place_dwell_s / 2.0, "place dwell"),
        Grip(0.0, "release"),
        Dwell(place_dwell_s / 2.0, "after release"),
    ]
