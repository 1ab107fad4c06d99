"""Typed models of the scenario file (every key is documented in docs/scenario.md).

The models check what a single table can check on its own: key names (extra keys are errors),
types (strict: no silent string-to-number coercion), ranges and finiteness. Everything that
relates tables to each other (ids, owners, sequences, dependencies, files, reachability) is
checked in `hrc.scenario.checks`, so one run reports every problem of a file.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, field_validator, model_validator

from hrc.scenario.colors import NAMED_RGB
from hrc.scenario.enums import InputSource, ParticipantProfile, RobotRole, SafetyPolicy
from hrc.scenario.paths import resolve_dir, resolve_path, resolve_urdf
from hrc.scenario.profiles import profile_defaults
from hrc.scenario.urdf import GENERIC_GRIPPER, GENERIC_GRIPPER_TCP_M, with_gripper

# ---------------------------------------------------------------- constants and conventions

HUMAN = "human"

DEFAULT_TICK_HZ = 240.0
# Lockstep exchanges of at most this many ticks (docs/ARCHITECTURE.md, "Exchange step"): 32 at
# 240 Hz = 7.5 exchanges per simulated second where nothing is near; 1 = an exchange every tick.
DEFAULT_MAX_EXCHANGE_TICKS = 32
MAX_EXCHANGE_TICKS = 64
MAX_TICK_HZ = 2000.0
MAX_TCP_SPEED = 1.5  # m/s, upper bound allowed for any robot
DEFAULT_NEAR_MARGIN = 0.05  # m, inflated-volume margin for robot-robot near collisions
DEFAULT_BASE_LINK = "base_link"  # the chain of the project's own URDFs (robots/README.md)
DEFAULT_TIP_LINK = "tool"
# m/s^2: the arms' acceleration limit (the IK service's MotionLimits::max_tcp_accel), so the
# hardest an arm brakes: an ssm deceleration above it would assume braking the arm cannot do.
ARM_MAX_TCP_ACCEL = 2.0
DEFAULT_SCREW_TIME_S = 1.0
DEFAULT_TOLERANCE_M = 0.02
DEFAULT_TOLERANCE_DEG = 20.0
DEFAULT_ROLE_COLORS = {RobotRole.TRANSPORT: "yellow", RobotRole.SCREWING: "green"}

# Names the view and the VR clients know; anything else must be written as #rrggbb.
COLOR_NAMES = frozenset(NAMED_RGB)
_HEX_COLOR = re.compile(r"^#[0-9a-fA-F]{6}$")
# Ids end up in bus keys (robot/<id>/command), cue ids ("target:RA1") and folder names.
ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_-]*$"
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"


class _Strict(BaseModel):
    """Base of every table: unknown keys are errors, no type coercion, no NaN/inf."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=False)


Num = Annotated[float, Field(allow_inf_nan=False)]
Vec3 = Annotated[list[Num], Field(min_length=3, max_length=3)]
Id = Annotated[str, Field(pattern=ID_PATTERN)]
Name = Annotated[str, Field(pattern=NAME_PATTERN)]
# The file writes an enum's string; strict mode alone would take only the member itself.
InputChoice = Annotated[InputSource, Field(strict=False)]
PolicyChoice = Annotated[SafetyPolicy, Field(strict=False)]
RoleChoice = Annotated[RobotRole, Field(strict=False)]
ProfileChoice = Annotated[ParticipantProfile, Field(strict=False)]


def check_color(value: str) -> str:
    if value.lower() in COLOR_NAMES or _HEX_COLOR.match(value):
        return value
    raise ValueError(
        f"unknown color {value!r}: use #rrggbb or one of {', '.join(sorted(COLOR_NAMES))}"
    )


# ---------------------------------------------------------------- tables


class PoseYaw(_Strict):
    """A position (metres, world frame) and a yaw about world z (degrees)."""

    xyz: Vec3
    yaw: Annotated[float, Field(ge=-360.0, le=360.0, allow_inf_nan=False)] = 0.0


class ScenarioInfo(_Strict):
    name: Name
    tick_hz: Annotated[float, Field(gt=0.0, le=MAX_TICK_HZ, allow_inf_nan=False)] = DEFAULT_TICK_HZ
    seed: Annotated[int, Field(ge=0, lt=2**64)] = 1
    # The watchdog: no progress for this long (simulated s) ends the trial; 0: never.
    stall_timeout_s: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 60.0
    # Up to this many ticks per lockstep exchange where no hand can reach an arm meanwhile; 1
    # gives every reaction one tick, as before exchanges (slower).
    max_exchange_ticks: Annotated[int, Field(ge=1, le=MAX_EXCHANGE_TICKS)] = (
        DEFAULT_MAX_EXCHANGE_TICKS
    )


class ScriptedParams(_Strict):
    """The scripted participant's parameters: defaults and ranges (the one place they are
    defined; meanings in docs/scenario.md). The defaults are the `baseline` profile's; another
    `profile` fills the keys left unset from `hrc.scenario.profiles`. They travel as
    `pb.ScriptedParams`."""

    profile: ProfileChoice = ParticipantProfile.BASELINE
    reaction_time_s: Annotated[float, Field(ge=0.0, le=10.0, allow_inf_nan=False)] = 0.4
    peak_hand_speed: Annotated[float, Field(gt=0.0, le=5.0, allow_inf_nan=False)] = 1.0
    caution: Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)] = 0.5
    fitts_a_s: Annotated[float, Field(ge=0.0, le=5.0, allow_inf_nan=False)] = 0.1
    fitts_b_s: Annotated[float, Field(ge=0.0, le=5.0, allow_inf_nan=False)] = 0.15
    fitts_c_s_per_m: Annotated[float, Field(ge=0.0, le=10.0, allow_inf_nan=False)] = 0.0
    pick_dwell_s: Annotated[float, Field(ge=0.0, le=10.0, allow_inf_nan=False)] = 0.3
    place_dwell_s: Annotated[float, Field(ge=0.0, le=10.0, allow_inf_nan=False)] = 0.3
    place_error_m: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = 0.005
    grip_close_s: Annotated[float, Field(ge=0.01, le=2.0, allow_inf_nan=False)] = 0.15
    grip_open_s: Annotated[float, Field(ge=0.01, le=2.0, allow_inf_nan=False)] = 0.10
    max_hold_back_s: Annotated[float, Field(ge=0.0, le=600.0, allow_inf_nan=False)] = 10.0
    left_handed: bool = False
    stop_above: bool = True
    # None: half of reaction_time_s
    collision_reaction_s: Annotated[float, Field(ge=0.0, le=10.0, allow_inf_nan=False)] | None = (
        None
    )

    @model_validator(mode="before")
    @classmethod
    def _profile_defaults(cls, data: Any) -> Any:
        """Keys left unset take the profile's values (an unknown profile is left to the field's
        own check, which names the choices)."""
        if not isinstance(data, dict) or "profile" not in data:
            return data
        profile = ParticipantProfile.parse(data["profile"])
        if profile is None:
            return data
        return {**profile_defaults(profile), **data}

    @property
    def collision_reaction(self) -> float:
        """Seconds from a collision to the hand's pull-back."""
        if self.collision_reaction_s is not None:
            return self.collision_reaction_s
        return 0.5 * self.reaction_time_s


class Participant(ScriptedParams):
    """Who drives the human side, and (inherited, same table) the scripted participant's
    parameters, which the replay and vr sources ignore."""

    name: Name
    input: InputChoice = InputSource.SCRIPTED
    replay_file: str | None = None
    # false | true | probability in [0, 1] | list of task times in seconds; normalised to a
    # probability (float) or a non-empty list of times (see docs/scenario.md).
    provoke_collisions: float | list[float] = 0.0

    @field_validator("provoke_collisions", mode="before")
    @classmethod
    def _provoke_shape(cls, value: Any) -> float | list[float]:
        if isinstance(value, bool):
            return 1.0 if value else 0.0
        if isinstance(value, (int, float)):
            if not math.isfinite(value) or not 0.0 <= value <= 1.0:
                raise ValueError(f"a probability must be in [0, 1], got {value}")
            return float(value)
        if isinstance(value, list):
            times: list[float] = []
            for item in value:
                if isinstance(item, bool) or not isinstance(item, (int, float)):
                    raise ValueError(f"times must be numbers of seconds, got {item!r}")
                if not math.isfinite(item) or item < 0.0:
                    raise ValueError(f"times must be finite and >= 0 s, got {item}")
                times.append(float(item))
            return sorted(times) if times else 0.0
        raise ValueError(
            "expected true/false, a probability in [0, 1] or a list of task times in seconds, "
            f"got {type(value).__name__}"
        )

    @property
    def provoke_times_s(self) -> list[float]:
        return list(self.provoke_collisions) if isinstance(self.provoke_collisions, list) else []

    @property
    def provoke_probability(self) -> float:
        return 0.0 if isinstance(self.provoke_collisions, list) else float(self.provoke_collisions)

    def scripted_params(self) -> ScriptedParams:
        return ScriptedParams(**{name: getattr(self, name) for name in ScriptedParams.model_fields})


class Ssm(_Strict):
    """Speed and separation monitoring parameters (safety_policy = "ssm"): the defaults of
    [conditions.ssm], overridden key by key per robot in [robots.<id>.ssm]. Meaning, default and
    source of each: docs/safety-ssm.md. They travel as `pb.SsmParams`."""

    human_speed: Annotated[float, Field(gt=0.0, le=5.0, allow_inf_nan=False)] = 1.6
    # > 0: no real system reacts in no time (a 0 would shrink S_p below what any robot can keep)
    reaction_time_s: Annotated[float, Field(gt=0.0, le=2.0, allow_inf_nan=False)] = 0.1
    deceleration: Annotated[float, Field(gt=0.0, le=ARM_MAX_TCP_ACCEL, allow_inf_nan=False)] = (
        ARM_MAX_TCP_ACCEL
    )
    intrusion_distance_m: Annotated[float, Field(ge=0.0, le=1.5, allow_inf_nan=False)] = 0.048
    sensing_uncertainty_m: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = 0.02
    position_uncertainty_m: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = 0.01
    min_speed: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = 0.01
    resume_margin_m: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = 0.05
    sensing_range_m: Annotated[float, Field(gt=0.0, le=10.0, allow_inf_nan=False)] = 2.0
    # a safety laser scanner's scan cycle (30-40 ms); at least one tick (hrc.ssm.scan_ticks)
    scan_period_s: Annotated[float, Field(gt=0.0, le=1.0, allow_inf_nan=False)] = 0.03

    def merged(self, override: Ssm | None) -> Ssm:
        """These values with the keys `override`'s table sets (a robot's own [ssm] table)."""
        if override is None:
            return self.model_copy()
        return self.model_copy(
            update={name: getattr(override, name) for name in override.model_fields_set}
        )


class Conditions(_Strict):
    anticipation: bool = True
    safety_policy: PolicyChoice = SafetyPolicy.RETREAT
    ssm: Ssm = Field(default_factory=Ssm)


class Tcp(_Strict):
    """The tool centre point in the tip link's frame: a translation (metres) and a rotation
    (roll, pitch, yaw about the tip link's fixed x, y, z axes, degrees; URDF's order)."""

    xyz: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    rpy_deg: Annotated[
        list[Annotated[float, Field(ge=-360.0, le=360.0)]], Field(min_length=3, max_length=3)
    ] = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class Gripper(_Strict):
    """The description's own fingers: joints set to `open` while the arm holds nothing and to
    `closed` while it holds a part (robots/README.md)."""

    # none: no fingers (what a study's condition writes for an arm without them)
    joints: list[Annotated[str, Field(min_length=1)]]
    open: Num = 0.0
    closed: Num = 0.0


class Robot(_Strict):
    """One arm. Its id is the key under [robots] (available as `.id` once loaded)."""

    @model_validator(mode="before")
    @classmethod
    def _generic_gripper_tcp(cls, data: Any) -> Any:
        """With the generic gripper attached and no tcp given: its finger tips."""
        generic = isinstance(data, dict) and data.get("gripper_urdf") == GENERIC_GRIPPER
        if generic and "tcp" not in data:
            return {**data, "tcp": {"xyz": [0.0, 0.0, GENERIC_GRIPPER_TCP_M]}}
        return data

    role: RoleChoice
    urdf: Annotated[str, Field(min_length=1)]
    # The chain, as MoveIt and KDL name one (robots/README.md): base_link -> tip_link, then tcp.
    base_link: Annotated[str, Field(min_length=1)] = DEFAULT_BASE_LINK
    tip_link: Annotated[str, Field(min_length=1)] = DEFAULT_TIP_LINK
    tcp: Tcp = Field(default_factory=Tcp)
    # Folders where package://NAME/... is looked up (relative: like urdf)
    packages: list[Annotated[str, Field(min_length=1)]] = Field(default_factory=list)
    tint: bool = True  # the page and the view show it in its colour (false: the URDF's own)
    gripper: Gripper | None = None
    # A gripper attached at tip_link (robots/README.md): "generic" (robots/gripper.urdf; the
    # tcp then defaults to its finger tips) or a gripper's own URDF (path, package://...)
    gripper_urdf: Annotated[str, Field(min_length=1)] | None = None
    base: PoseYaw
    max_tcp_speed: Annotated[float, Field(gt=0.0, le=MAX_TCP_SPEED, allow_inf_nan=False)]
    home: Vec3
    intermediate: Vec3
    retreat: Vec3
    color: str | None = None  # default by role: transport yellow, screwing green
    feeder: Vec3 | None = None  # screwing robots only (required there)
    screw_time_s: Annotated[float, Field(ge=0.0, le=60.0, allow_inf_nan=False)] | None = None
    near_margin: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = DEFAULT_NEAR_MARGIN
    ssm: Ssm | None = None  # overrides of [conditions.ssm] for this robot (only the keys set)

    _id: str = PrivateAttr(default="")

    @field_validator("color")
    @classmethod
    def _color(cls, value: str | None) -> str | None:
        return None if value is None else check_color(value)

    @property
    def id(self) -> str:
        return self._id

    @property
    def color_or_default(self) -> str:
        return self.color if self.color is not None else DEFAULT_ROLE_COLORS[self.role]

    @property
    def screw_time_or_default(self) -> float:
        if self.screw_time_s is not None:
            return self.screw_time_s
        return DEFAULT_SCREW_TIME_S if self.role == RobotRole.SCREWING else 0.0


class Part(_Strict):
    id: Id
    owner: Annotated[str, Field(min_length=1)]  # "human" or a robot id
    kind: str = "part"  # free text, shown in the view
    size: Annotated[
        list[Annotated[float, Field(gt=0.0, le=2.0, allow_inf_nan=False)]],
        Field(min_length=3, max_length=3),
    ]
    start: PoseYaw | None = None  # required unless the owner is a screwing robot
    target: PoseYaw
    after: list[str] = Field(default_factory=list)


class Box(_Strict):
    min: Vec3
    max: Vec3


class Workspace(_Strict):
    envelope: Annotated[list[Box], Field(min_length=1)]
    continue_button: Vec3 | None = None  # required for safety_policy = "retreat_button"


class Placement(_Strict):
    tolerance_m: Annotated[float, Field(gt=0.0, le=0.5, allow_inf_nan=False)] = DEFAULT_TOLERANCE_M
    tolerance_deg: Annotated[float, Field(gt=0.0, le=180.0, allow_inf_nan=False)] = (
        DEFAULT_TOLERANCE_DEG
    )


class Scenario(_Strict):
    """A whole scenario file. Build it with `hrc.scenario.load` (which also checks it)."""

    scenario: ScenarioInfo
    participant: Participant
    conditions: Conditions = Field(default_factory=Conditions)
    robots: dict[Id, Robot]
    parts: list[Part] = Field(default_factory=list)
    # agent ("human" or a robot id) -> part ids in the order that agent handles them
    sequence: dict[str, list[str]] = Field(default_factory=dict)
    workspace: Workspace
    placement: Placement = Field(default_factory=Placement)

    _source_path: Path | None = PrivateAttr(default=None)
    _source_text: str = PrivateAttr(default="")
    _project_root: Path | None = PrivateAttr(default=None)

    def model_post_init(self, _context: Any) -> None:
        for robot_id, robot in self.robots.items():
            robot._id = robot_id

    # -------------------------------------------------- where it came from

    @property
    def source_path(self) -> Path | None:
        return self._source_path

    @property
    def source_text(self) -> str:
        return self._source_text

    @property
    def project_root(self) -> Path | None:
        return self._project_root

    def resolve(self, relative: str) -> Path | None:
        """A path written in the file, resolved as docs/scenario.md says (None: nowhere)."""
        folder = self._source_path.parent if self._source_path else None
        return resolve_path(relative, folder, self._project_root)

    def package_dirs(self, robot_id: str) -> list[Path]:
        """The robot's `packages` folders that exist (relative ones like `resolve`)."""
        folder = self._source_path.parent if self._source_path else None
        found = (resolve_dir(d, folder, self._project_root) for d in self.robots[robot_id].packages)
        return [d for d in found if d is not None]

    def urdf_path(self, robot_id: str) -> Path | None:
        """The robot's description as every service reads it: its URDF, or, with a gripper
        attached (`gripper_urdf`), one URDF of both (hrc.scenario.urdf.with_gripper)."""
        robot = self.robots[robot_id]
        arm = self.arm_urdf_path(robot_id)
        if arm is None or robot.gripper_urdf is None:
            return arm
        gripper = self.gripper_path(robot_id)
        if gripper is None:
            return None
        return with_gripper(arm, robot.tip_link, gripper, self.package_dirs(robot_id))

    def arm_urdf_path(self, robot_id: str) -> Path | None:
        """The robot's own URDF, as `urdf` names it (without an attached gripper)."""
        folder = self._source_path.parent if self._source_path else None
        written = self.robots[robot_id].urdf
        return resolve_urdf(written, folder, self._project_root, self.package_dirs(robot_id))

    def gripper_path(self, robot_id: str) -> Path | None:
        """The attached gripper's own URDF (None: none attached, or not found)."""
        written = self.robots[robot_id].gripper_urdf
        if written is None:
            return None
        if written == GENERIC_GRIPPER:
            written = "robots/gripper.urdf"
        folder = self._source_path.parent if self._source_path else None
        return resolve_urdf(written, folder, self._project_root, self.package_dirs(robot_id))

    # -------------------------------------------------- accessors the task logic uses

    @property
    def agents(self) -> list[str]:
        """ "human" then the robot ids, in file order."""
        return [HUMAN, *self.robots]

    def part(self, part_id: str) -> Part:
        for part in self.parts:
            if part.id == part_id:
                return part
        raise KeyError(f"no part {part_id!r} in scenario {self.scenario.name!r}")

    @property
    def parts_by_id(self) -> dict[str, Part]:
        return {part.id: part for part in self.parts}

    def ssm_of(self, robot_id: str) -> Ssm:
        """The robot's effective SSM parameters: [conditions.ssm] with its own overrides."""
        return self.conditions.ssm.merged(self.robot(robot_id).ssm)

    def robot(self, robot_id: str) -> Robot:
        try:
            return self.robots[robot_id]
        except KeyError:
            raise KeyError(f"no robot {robot_id!r} in scenario {self.scenario.name!r}") from None

    def sequence_of(self, agent: str) -> list[str]:
        """Part ids the agent handles, in order (empty if it has none)."""
        if agent != HUMAN and agent not in self.robots:
            raise KeyError(f"no agent {agent!r} in scenario {self.scenario.name!r}")
        return list(self.sequence.get(agent, []))

    def parts_in_sequence(self, agent: str) -> list[Part]:
        by_id = self.parts_by_id
        return [by_id[pid] for pid in self.sequence_of(agent)]

    def parts_of(self, owner: str) -> list[Part]:
        """Parts owned by an agent, in file order."""
        return [part for part in self.parts if part.owner == owner]

    def robots_by_role(self, role: RobotRole | str) -> dict[str, Robot]:
        role = RobotRole(role)  # ValueError for a string that is not a role
        return {rid: robot for rid, robot in self.robots.items() if robot.role == role}

    def dependents(self, part_id: str) -> list[str]:
        """Ids of the parts whose `after` names part_id."""
        return [part.id for part in self.parts if part_id in part.after]
