"""Task conventions that more than one service relies on, defined once (docs/task-semantics.md
describes the behaviour they belong to).

The scenario's own defaults and bounds (tick rate, placement tolerance, ...) live with the
models in :mod:`hrc.scenario.models`; the participant's hands, the grasp rule, the robots'
vertical approach and the cue ids live here.
"""

from __future__ import annotations

# ---------------------------------------------------------------- the participant's hands

HANDS = ("left", "right")  # hand names on the wire (HumanState fields, contacts, events)
GRIP_CLOSED = 0.5  # a grip >= this holds a part; below it lets go
# A state in which a grip crosses GRIP_CLOSED is used for a tick of its own even when a later
# one has arrived (a release then the hand away: the part is let go where it was released);
# at most this many wait, a flood of them drops the oldest.
MAX_HELD_GRIP_CHANGES = 8
GRASP_DISTANCE_M = 0.03  # a closed hand grasps a grabbable part this close to it
HAND_SIZE = (0.09, 0.18, 0.03)  # m, the hand's box collider (x, y, z in the hand's frame)
# m: its farthest point from its centre (a turn at w rad/s moves no point faster than w * this)
HAND_RADIUS_M = 0.5 * (HAND_SIZE[0] ** 2 + HAND_SIZE[1] ** 2 + HAND_SIZE[2] ** 2) ** 0.5

# ---------------------------------------------------------------- the robots

# Picks and places are approached and left vertically from this far above (the orchestrator's
# commands, and the motion check of the scenario validation).
APPROACH_HEIGHT_M = 0.05


def grasp_point(
    centre: tuple[float, float, float], size: list[float]
) -> tuple[float, float, float]:
    """The TCP for a part whose box centre is `centre`: the centre of its top face."""
    return (centre[0], centre[1], centre[2] + size[2] / 2.0)


# ---------------------------------------------------------------- cues (task/indicators)

WAITING_TEXT = "Waiting.."  # the label of a robot that waits for a part (the thesis's text)
WAITING_HEIGHT_M = 0.6  # where that label floats, above the robot's base
CONTINUE_BUTTON_CUE = "continue_button"
TARGET_CUE_PREFIX = "target:"


def outline_cue_id(part: str) -> str:
    """The outline of the part the participant may grab next."""
    return f"outline:{part}"


def target_cue_id(part: str) -> str:
    """The target of a part that is being carried (or that a robot heads to, with anticipation)."""
    return f"{TARGET_CUE_PREFIX}{part}"


def waiting_cue_id(robot: str) -> str:
    """A robot's "Waiting.." label."""
    return f"waiting:{robot}"
