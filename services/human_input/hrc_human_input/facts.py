"""What the participant knows of the scenario, read tolerantly from the wire `pb.Scenario`.

Read straight from the message (not through the strict scenario model) so a parameter this
service does not know yet, or a newer one, never stops the participant: unknown names are logged
and ignored, missing ones take the documented defaults.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

from hrc.geometry import Vec3, vec3_from_pb
from hrc.scenario.models import DEFAULT_TICK_HZ, DEFAULT_TOLERANCE_M, HUMAN
from hrc.wire import pb

log = logging.getLogger(__name__)

# Scripted-participant parameters this service reads from ParticipantConfig.params, with the
# defaults used when a value is absent (the scenario model fills them in normally) and the range
# a value is clamped to.
PARAM_DEFAULTS: dict[str, float] = {
    "reaction_time_s": 0.4,
    "peak_hand_speed": 1.0,
    "caution": 0.5,
    "fitts_a_s": 0.1,
    "fitts_b_s": 0.15,
    "pick_dwell_s": 0.3,
    "place_dwell_s": 0.3,
    "place_error_m": 0.005,
    # Proposed additions to [participant] (read if present): see the service README.
    "grip_close_s": 0.15,
    "grip_open_s": 0.10,
    "max_hold_back_s": 10.0,
    "left_handed": 0.0,
}
PARAM_RANGES: dict[str, tuple[float, float]] = {
    "reaction_time_s": (0.0, 10.0),
    "peak_hand_speed": (0.05, 5.0),
    "caution": (0.0, 1.0),
    "fitts_a_s": (0.0, 5.0),
    "fitts_b_s": (0.0, 5.0),
    "pick_dwell_s": (0.0, 10.0),
    "place_dwell_s": (0.0, 10.0),
    "place_error_m": (0.0, 0.5),
    "grip_close_s": (0.01, 2.0),
    "grip_open_s": (0.01, 2.0),
    "max_hold_back_s": (0.0, 600.0),
    "left_handed": (0.0, 1.0),
}


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
    input: str = "scripted"
    replay_file: str = ""
    anticipation: bool = True
    safety_policy: str = "retreat"
    parts: dict[str, PartFacts] = field(default_factory=dict)
    robots: dict[str, RobotFacts] = field(default_factory=dict)
    human_sequence: list[str] = field(default_factory=list)
    continue_button: Vec3 | None = None
    place_tolerance_m: float = DEFAULT_TOLERANCE_M
    params: dict[str, float] = field(default_factory=lambda: dict(PARAM_DEFAULTS))
    provoke_times_s: list[float] = field(default_factory=list)
    provoke_probability: float = 0.0

    def param(self, name: str) -> float:
        return self.params.get(name, PARAM_DEFAULTS[name])


def read_params(raw: dict[str, float]) -> dict[str, float]:
    params = dict(PARAM_DEFAULTS)
    for name, value in sorted(raw.items()):
        if name not in PARAM_DEFAULTS:
            log.warning("participant parameter %r is not used by the scripted participant", name)
            continue
        lo, hi = PARAM_RANGES[name]
        if not math.isfinite(value):
            log.warning("participant parameter %s = %r is not finite; using %g", name, value,
                        PARAM_DEFAULTS[name])
            continue
        if not lo <= value <= hi:
            log.warning("participant parameter %s = %g is outside [%g, %g]; clamped", name,
                        value, lo, hi)
            value = min(hi, max(lo, value))
        params[name] = float(value)
    return params


def from_proto(msg: pb.Scenario) -> ScenarioFacts:
    pc = msg.participant
    facts = ScenarioFacts(
        name=msg.info.name, seed=int(msg.info.seed), tick_hz=msg.info.tick_hz or DEFAULT_TICK_HZ,
        participant=pc.name, input=pc.input or "scripted", replay_file=pc.replay_file,
        anticipation=msg.conditions.anticipation,
        safety_policy=msg.conditions.safety_policy or "retreat",
        place_tolerance_m=msg.place_tolerance_m or DEFAULT_TOLERANCE_M,
        params=read_params(dict(pc.params)),
        provoke_times_s=sorted(t for t in pc.provoke_times_s if math.isfinite(t) and t >= 0),
        provoke_probability=min(1.0, max(0.0, pc.provoke_probability))
        if math.isfinite(pc.provoke_probability) else 0.0,
    )
    for p in msg.parts:
        facts.parts[p.id] = PartFacts(
            id=p.id, owner=p.owner, size=vec3_from_pb(p.size),
            start=vec3_from_pb(p.start.xyz) if p.start_given else None,
            start_yaw_deg=p.start.yaw_deg, target=vec3_from_pb(p.target.xyz),
            target_yaw_deg=p.target.yaw_deg, after=tuple(p.after))
    for r in msg.robots:
        facts.robots[r.id] = RobotFacts(id=r.id, color=r.color, retreat=vec3_from_pb(r.retreat))
    for s in msg.sequences:
        if s.agent == HUMAN:
            facts.human_sequence = list(s.parts)
    if msg.workspace.HasField("continue_button"):
        facts.continue_button = vec3_from_pb(msg.workspace.continue_button)
    return facts
