"""What the participant knows of the scenario, read from the wire `pb.Scenario`.

Read straight from the message (not through the strict scenario model, which would also demand
what this service never uses), except the scripted participant's parameters: their defaults and
ranges live in the scenario model (`hrc.scenario.ScriptedParams`), which reads them here too. A
parameter the message leaves unset takes its default; one out of range is a ScenarioError.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from hrc import scenario as sc
from hrc.geometry import Vec3, vec3_from_pb
from hrc.scenario.models import DEFAULT_TICK_HZ, DEFAULT_TOLERANCE_M, HUMAN
from hrc.wire import pb


@dataclass(frozen=True)
class PartFacts:
    id: str
    owner: str
    size: Vec3
    start: Vec3 | None
    start_yaw_deg: float
    target: Vec3
    target_yaw_deg: float
    after: tuple[str, ...] = ()


@dataclass(frozen=True)
class RobotFacts:
    id: str
    color: str
    retreat: Vec3


@dataclass
class ScenarioFacts:
    name: str = ""
    seed: int = 1
    tick_hz: float = DEFAULT_TICK_HZ
    participant: str = ""
    input: sc.InputSource = sc.InputSource.SCRIPTED
    replay_file: str = ""
    anticipation: bool = True
    safety_policy: sc.SafetyPolicy = sc.SafetyPolicy.RETREAT
    parts: dict[str, PartFacts] = field(default_factory=dict)
    robots: dict[str, RobotFacts] = field(default_factory=dict)
    human_sequence: list[str] = field(default_factory=list)
    continue_button: Vec3 | None = None
    place_tolerance_m: float = DEFAULT_TOLERANCE_M
    params: sc.ScriptedParams = field(default_factory=sc.ScriptedParams)
    provoke_times_s: list[float] = field(default_factory=list)
    provoke_probability: float = 0.0


def from_proto(msg: pb.Scenario) -> ScenarioFacts:
    """ScenarioError when the scripted parameters are out of range."""
    pc = msg.participant
    defaults = ScenarioFacts()
    facts = ScenarioFacts(
        name=msg.info.name,
        seed=int(msg.info.seed),
        tick_hz=msg.info.tick_hz or DEFAULT_TICK_HZ,
        participant=pc.name,
        input=sc.InputSource.from_proto(pc.input, defaults.input),
        replay_file=pc.replay_file,
        anticipation=msg.conditions.anticipation,
        safety_policy=sc.SafetyPolicy.from_proto(
            msg.conditions.safety_policy, defaults.safety_policy
        ),
        place_tolerance_m=msg.place_tolerance_m or DEFAULT_TOLERANCE_M,
        params=sc.scripted_params_from_proto(pc.scripted, msg.source_path or "<wire scenario>"),
        provoke_times_s=sorted(t for t in pc.provoke_times_s if math.isfinite(t) and t >= 0),
        provoke_probability=min(1.0, max(0.0, pc.provoke_probability))
        if math.isfinite(pc.provoke_probability)
        else 0.0,
    )
    for p in msg.parts:
        facts.parts[p.id] = PartFacts(
            id=p.id,
            owner=p.owner,
            size=vec3_from_pb(p.size),
            start=vec3_from_pb(p.start.xyz) if p.start_given else None,
            start_yaw_deg=p.start.yaw_deg,
            target=vec3_from_pb(p.target.xyz),
            target_yaw_deg=p.target.yaw_deg,
            after=tuple(p.after),
        )
    for r in msg.robots:
        facts.robots[r.id] = RobotFacts(id=r.id, color=r.color, retreat=vec3_from_pb(r.retreat))
    for s in msg.sequences:
        if s.agent == HUMAN:
            facts.human_sequence = list(s.parts)
    if msg.workspace.HasField("continue_button"):
        facts.continue_button = vec3_from_pb(msg.workspace.continue_button)
    return facts
