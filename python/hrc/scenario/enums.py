"""The scenario file's named choices and their wire enums: the one mapping between the two.

Each is a `StrEnum` whose values are the strings the scenario file uses (and metrics.json shows);
`to_proto` / `from_proto` convert to and from the `pb` enum of the same name. The texts follow
the wire's JSON rule (`hrc.wire.jsonmap.enum_text`: `SAFETY_POLICY_RETREAT_BUTTON` <->
"retreat_button"), so every place that writes an enum as text agrees with the scenario file.
Services compare these members (or the `pb` values), never the strings.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Self, cast

from google.protobuf.descriptor import EnumDescriptor

from hrc.wire import pb
from hrc.wire.jsonmap import enum_number, enum_text


class WireEnum(StrEnum):
    """Base of the scenario enums (no members of its own)."""

    def to_proto(self) -> int:
        """The wire value (the subclasses narrow the type to their `pb` enum)."""
        return enum_number(_DESCRIPTORS[type(self)], self.value)

    @classmethod
    def from_proto(cls, number: int, default: Self | None = None) -> Self:
        """The member for a wire value; `default` for the 0 value (not set) if given, else
        ValueError (as for a number the enum does not have)."""
        text = enum_text(_DESCRIPTORS[cls], number)
        if text is None:
            if default is not None:
                return default
            raise ValueError(f"{cls.__name__} is not set")
        return cls(text)

    @classmethod
    def parse(cls, text: object) -> Self | None:
        """The member whose string is `text`, or None."""
        for member in cls:
            if member.value == text:
                return member
        return None


class SafetyPolicy(WireEnum):
    """What the robots do when a hand touches one (docs/scenario.md, [conditions])."""

    RETREAT = "retreat"
    RETREAT_BUTTON = "retreat_button"
    STOP_COLLIDING = "stop_colliding"
    SSM = "ssm"  # speed and separation monitoring (docs/safety-ssm.md)

    def to_proto(self) -> pb.SafetyPolicy.ValueType:
        return cast("pb.SafetyPolicy.ValueType", super().to_proto())


class RobotRole(WireEnum):
    TRANSPORT = "transport"
    SCREWING = "screwing"

    def to_proto(self) -> pb.RobotRole.ValueType:
        return cast("pb.RobotRole.ValueType", super().to_proto())


class InputSource(WireEnum):
    """Who drives the human side."""

    SCRIPTED = "scripted"
    REPLAY = "replay"
    VR = "vr"

    def to_proto(self) -> pb.InputSource.ValueType:
        return cast("pb.InputSource.ValueType", super().to_proto())


class ParticipantProfile(WireEnum):
    """Whose defaults the scripted participant's unset parameters take
    (`hrc.scenario.profiles`, docs/participant-model.md)."""

    BASELINE = "baseline"
    REAL = "real"
    VR = "vr"

    def to_proto(self) -> pb.ParticipantProfile.ValueType:
        return cast("pb.ParticipantProfile.ValueType", super().to_proto())


_DESCRIPTORS: dict[type[WireEnum], EnumDescriptor] = {
    SafetyPolicy: pb.SafetyPolicy.DESCRIPTOR,
    RobotRole: pb.RobotRole.DESCRIPTOR,
    InputSource: pb.InputSource.DESCRIPTOR,
    ParticipantProfile: pb.ParticipantProfile.DESCRIPTOR,
}
