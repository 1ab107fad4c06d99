"""Scenario <-> wire `pb.Scenario` (served by the orchestrator on `hrc/<s>/scenario`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from pydantic import ValidationError

from hrc.geometry import (
    pose_yaw_to_pb,
    quat_from_pb,
    quat_rpy_deg,
    quat_to_pb,
    rpy_quat_deg,
    vec3_from_pb,
    vec3_to_pb,
)
from hrc.scenario.enums import (
    InputSource,
    ParticipantProfile,
    RobotRole,
    SafetyPolicy,
    WireEnum,
)
from hrc.scenario.errors import Problem, ScenarioError
from hrc.scenario.models import (
    DEFAULT_BASE_LINK,
    DEFAULT_MAX_EXCHANGE_TICKS,
    DEFAULT_TIP_LINK,
    Box,
    Conditions,
    Gripper,
    Part,
    Participant,
    Placement,
    PoseYaw,
    Robot,
    Scenario,
    ScenarioInfo,
    ScriptedParams,
    Ssm,
    Tcp,
    Workspace,
)
from hrc.wire import pb

T = TypeVar("T")
E = TypeVar("E", bound=WireEnum)


def to_proto(scenario: Scenario) -> pb.Scenario:
    """Every field filled: defaults applied, URDF and replay paths absolute where the file exists
    (as written otherwise), `source_toml` = the file's text. The header is left to the sender."""
    msg = pb.Scenario()
    info = scenario.scenario
    msg.info.CopyFrom(
        pb.ScenarioInfo(
            name=info.name,
            tick_hz=info.tick_hz,
            seed=info.seed,
            max_exchange_ticks=info.max_exchange_ticks,
        )
    )

    part = scenario.participant
    pc = msg.participant
    pc.name = part.name
    pc.input = part.input.to_proto()
    if part.replay_file is not None:
        resolved = scenario.resolve(part.replay_file)
        pc.replay_file = str(resolved) if resolved else part.replay_file
    pc.scripted.CopyFrom(scripted_params_to_proto(part.scripted_params()))
    pc.provoke_times_s.extend(part.provoke_times_s)
    pc.provoke_probability = part.provoke_probability

    msg.conditions.CopyFrom(
        pb.Conditions(
            anticipation=scenario.conditions.anticipation,
            safety_policy=scenario.conditions.safety_policy.to_proto(),
        )
    )
    if scenario.conditions.safety_policy == SafetyPolicy.SSM:
        # Only under ssm: the other policies' conditions (and metrics.json) stay as they were.
        msg.conditions.ssm.CopyFrom(ssm_to_proto(scenario.conditions.ssm))

    for rid, robot in scenario.robots.items():
        rc = msg.robots.add()
        rc.id = rid
        rc.role = robot.role.to_proto()
        urdf = scenario.urdf_path(rid)
        rc.urdf_path = str(urdf) if urdf else robot.urdf
        rc.base_link = robot.base_link
        rc.tip_link = robot.tip_link
        if robot.tcp != Tcp():  # unset on the wire: the tip link is the TCP
            rc.tcp.position.CopyFrom(vec3_to_pb(robot.tcp.xyz))
            rc.tcp.orientation.CopyFrom(quat_to_pb(rpy_quat_deg(robot.tcp.rpy_deg)))
        rc.package_dirs.extend(str(d) for d in scenario.package_dirs(rid))
        rc.own_colors = not robot.tint
        if robot.gripper is not None and robot.gripper.joints:
            rc.gripper.joints.extend(robot.gripper.joints)
            rc.gripper.open = robot.gripper.open
            rc.gripper.closed = robot.gripper.closed
        rc.base.CopyFrom(pose_yaw_to_pb(robot.base.xyz, robot.base.yaw))
        rc.max_tcp_speed = robot.max_tcp_speed
        rc.home.CopyFrom(vec3_to_pb(robot.home))
        rc.intermediate.CopyFrom(vec3_to_pb(robot.intermediate))
        rc.retreat.CopyFrom(vec3_to_pb(robot.retreat))
        rc.color = robot.color_or_default
        if robot.feeder is not None:  # presence tells from_proto the feeder exists
            rc.feeder.CopyFrom(vec3_to_pb(robot.feeder))
        rc.screw_time_s = robot.screw_time_or_default
        rc.near_margin = robot.near_margin
        rc.ssm.CopyFrom(ssm_to_proto(scenario.ssm_of(rid)))

    for p in scenario.parts:
        pcfg = msg.parts.add()
        pcfg.id = p.id
        pcfg.owner = p.owner
        pcfg.kind = p.kind
        pcfg.size.CopyFrom(vec3_to_pb(p.size))
        pcfg.start_given = p.start is not None
        if p.start is not None:
            pcfg.start.CopyFrom(pose_yaw_to_pb(p.start.xyz, p.start.yaw))
        pcfg.target.CopyFrom(pose_yaw_to_pb(p.target.xyz, p.target.yaw))
        pcfg.after.extend(p.after)

    # One sequence per agent, empty ones included, so services see every agent.
    for agent in scenario.agents:
        msg.sequences.add(agent=agent, parts=scenario.sequence_of(agent))

    for box in scenario.workspace.envelope:
        msg.workspace.envelope.add(min=vec3_to_pb(box.min), max=vec3_to_pb(box.max))
    if scenario.workspace.continue_button is not None:
        msg.workspace.continue_button.CopyFrom(vec3_to_pb(scenario.workspace.continue_button))
    msg.workspace.SetInParent()

    msg.place_tolerance_m = scenario.placement.tolerance_m
    msg.place_tolerance_deg = scenario.placement.tolerance_deg
    msg.source_path = str(scenario.source_path) if scenario.source_path else ""
    msg.source_toml = scenario.source_text
    return msg


def ssm_to_proto(params: Ssm) -> pb.SsmParams:
    return pb.SsmParams(**params.model_dump())


def scripted_params_to_proto(params: ScriptedParams) -> pb.ScriptedParams:
    """Every parameter set (the defaults applied; an unset collision_reaction_s stays unset)."""
    msg = pb.ScriptedParams()
    for name, value in scripted_wire_values(params).items():
        setattr(msg, name, value)
    return msg


def scripted_wire_values(params: ScriptedParams) -> dict[str, float | bool | int]:
    """The parameters as the wire's fields take them (the profile as its enum number); the
    unset optional ones left out."""
    values: dict[str, float | bool | int] = {}
    for name, value in params.model_dump().items():
        if value is None:
            continue
        values[name] = value.to_proto() if isinstance(value, ParticipantProfile) else value
    return values


def scripted_params_from_proto(
    msg: pb.ScriptedParams, source: str = "<wire scenario>"
) -> ScriptedParams:
    """The parameters a message sets, the model's defaults for the others; ScenarioError naming
    the key (participant.<name>) for a value out of its range."""
    return _validated(lambda: ScriptedParams.model_validate(_set_fields(msg)), source)


def from_proto(msg: pb.Scenario) -> Scenario:
    """The typed scenario back from the wire (paths are the absolute ones the sender resolved).
    Raises ScenarioError when a field is out of range (e.g. a message from a broken sender)."""
    source = msg.source_path or "<wire scenario>"
    return _validated(lambda: _from_proto(msg, source), source)


def _validated(build: Callable[[], T], source: str) -> T:
    try:
        return build()
    except ValidationError as exc:
        problems = [
            Problem(_wire_key(err["loc"]), err["msg"].removeprefix("Value error, "))
            for err in exc.errors(include_url=False)
        ]
        raise ScenarioError(problems, source) from exc


def _member(enum: type[E], number: int, key: str, source: str, default: E | None = None) -> E:
    try:
        return enum.from_proto(number, default)
    except ValueError as exc:  # unset, or a value this build does not know
        raise ScenarioError([Problem(key, str(exc))], source) from exc


def _wire_key(loc: tuple[int | str, ...]) -> str:
    key = ".".join(str(x) for x in loc) or "scenario"
    return f"participant.{key}" if loc and loc[0] in ScriptedParams.model_fields else key


def ssm_from_proto(msg: pb.SsmParams) -> Ssm:
    # Every field: a message carries all of them (0 is a valid value for some).
    return Ssm.model_validate({f.name: getattr(msg, f.name) for f in msg.DESCRIPTOR.fields})


def _robot_ssm(rc: pb.RobotConfig, defaults: Ssm) -> Ssm | None:
    """The robot's overrides: its effective values, or None where they are the defaults'."""
    if not rc.HasField("ssm"):
        return None
    own = ssm_from_proto(rc.ssm)
    return None if own == defaults else own


def _set_fields(msg: pb.ScriptedParams) -> dict[str, float | bool | ParticipantProfile]:
    out: dict[str, float | bool | ParticipantProfile] = {}
    for field, value in msg.ListFields():
        if field.name == "profile":
            out["profile"] = ParticipantProfile.from_proto(value, ParticipantProfile.BASELINE)
        else:
            out[field.name] = value
    return out


def _from_proto(msg: pb.Scenario, source: str) -> Scenario:
    pc = msg.participant
    provoke: float | list[float] = (
        list(pc.provoke_times_s) if pc.provoke_times_s else pc.provoke_probability
    )
    participant = Participant.model_validate(
        {
            "name": pc.name,
            "input": _member(InputSource, pc.input, "participant.input", source),
            "replay_file": pc.replay_file or None,
            "provoke_collisions": provoke,
            **_set_fields(pc.scripted),
        }
    )

    conditions_ssm = ssm_from_proto(msg.conditions.ssm) if msg.conditions.HasField("ssm") else Ssm()
    robots: dict[str, Robot] = {}
    for rc in msg.robots:
        role = _member(RobotRole, rc.role, f"robots.{rc.id}.role", source)
        robots[rc.id] = Robot(
            role=role,
            urdf=rc.urdf_path,
            base_link=rc.base_link or DEFAULT_BASE_LINK,
            tip_link=rc.tip_link or DEFAULT_TIP_LINK,
            tcp=_tcp_back(rc.tcp) if rc.HasField("tcp") else Tcp(),
            packages=list(rc.package_dirs),
            tint=not rc.own_colors,
            gripper=Gripper(
                joints=list(rc.gripper.joints), open=rc.gripper.open, closed=rc.gripper.closed
            )
            if rc.HasField("gripper")
            else None,
            base=_pose_back(rc.base),
            max_tcp_speed=rc.max_tcp_speed,
            home=_vec_back(rc.home),
            intermediate=_vec_back(rc.intermediate),
            retreat=_vec_back(rc.retreat),
            color=rc.color or None,
            feeder=_vec_back(rc.feeder) if rc.HasField("feeder") else None,
            screw_time_s=rc.screw_time_s if role == RobotRole.SCREWING else None,
            near_margin=rc.near_margin,
            ssm=_robot_ssm(rc, conditions_ssm),
        )

    parts = [
        Part(
            id=p.id,
            owner=p.owner,
            kind=p.kind,
            size=_vec_back(p.size),
            start=_pose_back(p.start) if p.start_given else None,
            target=_pose_back(p.target),
            after=list(p.after),
        )
        for p in msg.parts
    ]
    sequence = {s.agent: list(s.parts) for s in msg.sequences}

    ws = msg.workspace
    workspace = Workspace(
        envelope=[Box(min=_vec_back(b.min), max=_vec_back(b.max)) for b in ws.envelope],
        continue_button=_vec_back(ws.continue_button) if ws.HasField("continue_button") else None,
    )
    scenario = Scenario(
        scenario=ScenarioInfo(
            name=msg.info.name,
            tick_hz=msg.info.tick_hz,
            seed=msg.info.seed,
            max_exchange_ticks=msg.info.max_exchange_ticks or DEFAULT_MAX_EXCHANGE_TICKS,
        ),
        participant=participant,
        conditions=Conditions(
            anticipation=msg.conditions.anticipation,
            safety_policy=_member(
                SafetyPolicy,
                msg.conditions.safety_policy,
                "conditions.safety_policy",
                source,
                Conditions().safety_policy,
            ),
            ssm=conditions_ssm,
        ),
        robots=robots,
        parts=parts,
        sequence=sequence,
        workspace=workspace,
        placement=Placement(
            tolerance_m=msg.place_tolerance_m, tolerance_deg=msg.place_tolerance_deg
        ),
    )
    scenario._source_path = Path(msg.source_path) if msg.source_path else None
    scenario._source_text = msg.source_toml
    return scenario


def _vec_back(v: pb.Vec3) -> list[float]:
    return list(vec3_from_pb(v))  # the models hold lists


def _tcp_back(p: pb.Pose) -> Tcp:
    rpy = quat_rpy_deg(quat_from_pb(p.orientation))
    return Tcp(xyz=_vec_back(p.position), rpy_deg=[round(a, 9) + 0.0 for a in rpy])


def _pose_back(p: pb.PoseYaw) -> PoseYaw:
    return PoseYaw(xyz=_vec_back(p.xyz), yaw=p.yaw_deg)
