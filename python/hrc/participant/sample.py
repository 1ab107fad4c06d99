"""One participant sample: head, both hands, both grips. The shape every source produces.

The JSON form (docs/replay-format.md) is shared by the replay file and the VR bridge:

    {"t": 1.25,
     "head":  {"position": [x, y, z], "orientation": [x, y, z, w]},
     "left":  {"position": [...], "orientation": [...]},
     "right": {"position": [...], "orientation": [...]},
     "left_grip": 0.0, "right_grip": 1.0}
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hrc.geometry import Pose, interpolate_pose, lerp, normalized, pose_from_pb, pose_into_pb
from hrc.scenario import InputSource
from hrc.scenario.conventions import GRIP_CLOSED
from hrc.wire import pb

POSE_NAMES = ("head", "left", "right")
GRIP_NAMES = ("left_grip", "right_grip")
SAMPLE_KEYS = frozenset({"t", *POSE_NAMES, *GRIP_NAMES})
POSE_KEYS = frozenset({"position", "orientation"})
# Anything farther than this from the board origin is certainly a unit or frame mistake.
MAX_ABS_COORD_M = 10.0
_SOURCE_NUMBERS: dict[InputSource, pb.InputSource.ValueType] = {}


def pose_json(pose: Pose) -> dict[str, list[float]]:
    return {"position": list(pose.position), "orientation": list(pose.orientation)}


@dataclass(frozen=True)
class Sample:
    """The participant at one instant. ``t`` is simulation time in seconds."""

    t: float = 0.0
    head: Pose = field(default_factory=Pose)
    left: Pose = field(default_factory=Pose)
    right: Pose = field(default_factory=Pose)
    left_grip: float = 0.0
    right_grip: float = 0.0

    def hand(self, name: str) -> Pose:
        return self.left if name == "left" else self.right

    def same_as(self, other: Sample) -> bool:
        """Same poses and grips (the time aside)."""
        return (
            self.left == other.left
            and self.right == other.right
            and self.head == other.head
            and self.left_grip == other.left_grip
            and self.right_grip == other.right_grip
        )

    def closed(self) -> tuple[bool, bool]:
        """Which hands hold (left, right): grips at or above GRIP_CLOSED."""
        return (self.left_grip >= GRIP_CLOSED, self.right_grip >= GRIP_CLOSED)

    def grip(self, name: str) -> float:
        return self.left_grip if name == "left" else self.right_grip

    def at(self, t: float) -> Sample:
        """The same sample stamped with another time."""
        return Sample(t, self.head, self.left, self.right, self.left_grip, self.right_grip)

    def released(self) -> Sample:
        """The same poses with both grips open."""
        return Sample(self.t, self.head, self.left, self.right, 0.0, 0.0)

    def to_proto(self, source: InputSource) -> pb.HumanState:
        msg = pb.HumanState()
        self.into_proto(msg, source)
        return msg

    def into_proto(self, msg: pb.HumanState, source: InputSource) -> None:
        """Writes every field but the header and hand_speed_bound into ``msg`` (once per tick:
        one message filled again and again, the source's wire number looked up once)."""
        number = _SOURCE_NUMBERS.get(source)
        if number is None:
            number = _SOURCE_NUMBERS[source] = source.to_proto()
        msg.left_grip, msg.right_grip, msg.source = self.left_grip, self.right_grip, number
        pose_into_pb(msg.head, self.head)
        pose_into_pb(msg.left_hand, self.left)
        pose_into_pb(msg.right_hand, self.right)

    @staticmethod
    def from_proto(msg: pb.HumanState) -> Sample:
        return Sample(
            msg.header.sim_time,
            pose_from_pb(msg.head),
            pose_from_pb(msg.left_hand),
            pose_from_pb(msg.right_hand),
            msg.left_grip,
            msg.right_grip,
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "t": self.t,
            "head": pose_json(self.head),
            "left": pose_json(self.left),
            "right": pose_json(self.right),
            "left_grip": self.left_grip,
            "right_grip": self.right_grip,
        }


def interpolate(a: Sample, b: Sample, t: float) -> Sample:
    """Sample at time t between a and b: positions and grips linear, orientations slerp."""
    if b.t <= a.t:
        return b.at(t)
    u = min(1.0, max(0.0, (t - a.t) / (b.t - a.t)))
    return Sample(
        t,
        interpolate_pose(a.head, b.head, u),
        interpolate_pose(a.left, b.left, u),
        interpolate_pose(a.right, b.right, u),
        lerp(a.left_grip, b.left_grip, u),
        lerp(a.right_grip, b.right_grip, u),
    )


# ------------------------------------------------------------ JSON parsing with every problem named


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _vector(obj: Any, n: int, where: str, problems: list[str]) -> tuple[float, ...] | None:
    if not isinstance(obj, list) or len(obj) != n:
        problems.append(f"{where} must be a list of {n} numbers, got {_show(obj)}")
        return None
    bad = [i for i, v in enumerate(obj) if not _number(v)]
    if bad:
        problems.append(f"{where}[{bad[0]}] must be a finite number, got {_show(obj[bad[0]])}")
        return None
    return tuple(float(v) for v in obj)


def _pose(obj: Any, name: str, problems: list[str]) -> Pose | None:
    if not isinstance(obj, dict):
        problems.append(f"{name} must be an object with position and orientation, got {_show(obj)}")
        return None
    n0 = len(problems)
    for key in sorted(set(obj) - POSE_KEYS):
        problems.append(f"{name}: unknown key {key!r} (expected position, orientation)")
    for key in ("position", "orientation"):
        if key not in obj:
            problems.append(f"{name}.{key} is missing")
    pos = _vector(obj["position"], 3, f"{name}.position", problems) if "position" in obj else None
    quat = (
        _vector(obj["orientation"], 4, f"{name}.orientation", problems)
        if "orientation" in obj
        else None
    )
    if pos is not None and any(abs(c) > MAX_ABS_COORD_M for c in pos):
        problems.append(
            f"{name}.position {list(pos)} is more than {MAX_ABS_COORD_M:g} m from "
            "the origin (metres, world frame expected)"
        )
    if quat is not None:
        try:
            quat = normalized(quat)
        except ValueError:
            problems.append(f"{name}.orientation has zero length")
    if len(problems) > n0 or pos is None or quat is None:
        return None
    return Pose(pos, quat)  # type: ignore[arg-type]


def parse_sample(obj: Any, *, require_t: bool) -> tuple[Sample | None, list[str]]:
    """A sample from its JSON object, or None and every problem found."""
    problems: list[str] = []
    if not isinstance(obj, dict):
        return None, [f"a sample must be a JSON object, got {_show(obj)}"]
    for key in sorted(set(obj) - SAMPLE_KEYS):
        problems.append(f"unknown key {key!r} (expected {', '.join(sorted(SAMPLE_KEYS))})")
    t = 0.0
    if "t" in obj:
        if not _number(obj["t"]) or obj["t"] < 0:
            problems.append(f"t must be a finite number of seconds >= 0, got {_show(obj['t'])}")
        else:
            t = float(obj["t"])
    elif require_t:
        problems.append("t is missing")
    poses: dict[str, Pose] = {}
    for name in POSE_NAMES:
        if name not in obj:
            problems.append(f"{name} is missing")
            continue
        pose = _pose(obj[name], name, problems)
        if pose is not None:
            poses[name] = pose
    grips: dict[str, float] = {}
    for name in GRIP_NAMES:
        if name not in obj:
            problems.append(f"{name} is missing")
        elif not _number(obj[name]) or not 0.0 <= obj[name] <= 1.0:
            problems.append(f"{name} must be a number in [0, 1], got {_show(obj[name])}")
        else:
            grips[name] = float(obj[name])
    if problems:
        return None, problems
    return Sample(
        t, poses["head"], poses["left"], poses["right"], grips["left_grip"], grips["right_grip"]
    ), []


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
