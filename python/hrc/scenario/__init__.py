"""The scenario file (docs/scenario.md): typed models, full validation, conversion to the wire.

    from hrc.scenario import load, to_proto
    scenario = load("scenarios/thesis.toml")      # raises ScenarioError listing every problem
    msg = to_proto(scenario)                       # pb.Scenario, served on hrc/<s>/scenario

The format is documented in docs/scenario.md.
"""

from hrc.scenario.conventions import APPROACH_HEIGHT_M
from hrc.scenario.convert import (
    from_proto,
    scripted_params_from_proto,
    scripted_params_to_proto,
    scripted_wire_values,
    to_proto,
)
from hrc.scenario.enums import InputSource, ParticipantProfile, RobotRole, SafetyPolicy
from hrc.scenario.errors import Problem, ScenarioError
from hrc.scenario.loader import load, loads, validate
from hrc.scenario.models import (
    HUMAN,
    Box,
    Conditions,
    Part,
    Participant,
    Placement,
    PoseYaw,
    Robot,
    Scenario,
    ScenarioInfo,
    ScriptedParams,
    Ssm,
    Workspace,
)
from hrc.scenario.motion_check import PlannedMove, check_motion, planned_moves
from hrc.scenario.paths import find_project_root, resolve_path

__all__ = [
    "APPROACH_HEIGHT_M",
    "HUMAN",
    "Box",
    "Conditions",
    "InputSource",
    "Part",
    "Participant",
    "ParticipantProfile",
    "Placement",
    "PlannedMove",
    "PoseYaw",
    "Problem",
    "Robot",
    "RobotRole",
    "SafetyPolicy",
    "Scenario",
    "ScenarioError",
    "ScenarioInfo",
    "ScriptedParams",
    "Ssm",
    "Workspace",
    "check_motion",
    "find_project_root",
    "from_proto",
    "load",
    "loads",
    "planned_moves",
    "resolve_path",
    "scripted_params_from_proto",
    "scripted_params_to_proto",
    "scripted_wire_values",
    "to_proto",
    "validate",
]
