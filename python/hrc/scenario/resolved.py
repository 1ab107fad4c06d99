"""The scenario exactly as a trial runs it: the file's settings with the run's overrides applied
(`hrc run --seed`, `--replay`), written out in full as TOML (`scenario.toml` in the trial folder),
and the short hash that tells trials apart (docs/task-semantics.md#outputs).

    run = resolve(scenario, seed=7)      # a Resolved: the scenario, the overrides, a hash
    text = run.toml()                    # every key written, file paths absolute

The text loads back (`hrc.scenario.loads`) into the same settings: `hrc run` starts the services
on it, so what the trial folder holds is what ran.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hrc.scenario.enums import InputSource, SafetyPolicy
from hrc.scenario.models import Robot, Scenario, ScenarioInfo, Tcp
from hrc.tomlw import dumps


@dataclass
class Resolved:
    scenario: Scenario
    overrides: list[str] = field(default_factory=list)  # "scenario.seed = 7 (--seed)", ...

    def settings(self) -> dict[str, Any]:
        """Every setting (defaults filled in), file paths as written. The robot keys added for
        real arms (base_link ... tint) appear only when they differ from their defaults, so a
        scenario that does not use them keeps its hash, and its trials their folder names."""
        data = self.scenario.model_dump(mode="json", exclude_none=True)
        for robot in data.get("robots", {}).values():
            for key, default in CHAIN_DEFAULTS.items():
                if robot.get(key) == default:
                    del robot[key]
        return data

    @property
    def hash(self) -> str:
        """8 hex digits of the SHA-256 of the settings: equal for equal settings on any machine."""
        canonical = json.dumps(self.settings(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canonical.encode("utf-8")).hexdigest()[:8]

    def folder_name(self) -> str:
        """``<scenario>_<Anticipation|Normal>[_<policy>][_<input>][_seed<N>]_<hash>``: the
        conditions that differ from the defaults, then the hash of everything."""
        s = self.scenario
        parts = [slug(s.scenario.name), "Anticipation" if s.conditions.anticipation else "Normal"]
        if s.conditions.safety_policy != SafetyPolicy.RETREAT:
            parts.append(str(s.conditions.safety_policy))
        if s.participant.input != InputSource.SCRIPTED:
            parts.append(str(s.participant.input))
        if s.scenario.seed != ScenarioInfo.model_fields["seed"].default:
            parts.append(f"seed{s.scenario.seed}")
        parts.append(self.hash)
        return "_".join(parts)

    def toml(self) -> str:
        """The scenario file of the trial: a header naming the source and the overrides, then
        every key, with URDF and replay paths made absolute (the copy runs from any folder)."""
        data = self.settings()
        for rid, robot in data.get("robots", {}).items():
            # the arm's own file and the gripper's (not the two joined: that file is made again
            # from them when the copy is loaded, under the same name)
            urdf = self.scenario.arm_urdf_path(rid)
            if urdf is not None:
                robot["urdf"] = str(urdf)
            gripper = self.scenario.gripper_path(rid)
            if gripper is not None:
                robot["gripper_urdf"] = str(gripper)
            if robot.get("packages"):
                robot["packages"] = [str(d) for d in self.scenario.package_dirs(rid)]
        participant = data.get("participant", {})
        if "replay_file" in participant:
            replay = self.scenario.resolve(participant["replay_file"])
            if replay is not None:
                participant["replay_file"] = str(replay)
        source = self.scenario.source_path
        header = [
            "# The scenario exactly as this trial ran it (written by `hrc run`): every key,",
            "# defaults filled in, file paths absolute. Run it again: `hrc run <this file>`.",
            f"# source: {source if source is not None else '(text)'}",
        ]
        header += [f"# override: {o}" for o in self.overrides] or ["# overrides: none"]
        return "\n".join(header) + "\n\n" + dumps(data)


CHAIN_DEFAULTS: dict[str, Any] = {
    key: Robot.model_fields[key].get_default(call_default_factory=True)
    for key in ("base_link", "tip_link", "packages", "tint")
} | {"tcp": Tcp().model_dump(mode="json")}


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_\-]+", "-", text).strip("-") or "x"


def resolve(
    scenario: Scenario,
    *,
    seed: int | None = None,
    replay: Path | None = None,
    source: str | None = None,
    participant: str | None = None,
) -> Resolved:
    """`scenario` with the run's overrides applied (a copy; the given scenario is unchanged):
    `hrc run --seed`, `--input` (`source`), `--replay` (which wins over `--input`) and
    `--participant`."""
    s = scenario.model_copy(deep=True)
    overrides: list[str] = []
    if participant is not None and participant != s.participant.name:
        s.participant.name = participant
        overrides.append(f'participant.name = "{participant}" (--participant)')
    if seed is not None:
        s.scenario.seed = seed
        overrides.append(f"scenario.seed = {seed} (--seed)")
    if source is not None and replay is None and source != s.participant.input:
        s.participant.input = InputSource(source)
        overrides.append(f'participant.input = "{source}" (--input)')
    if replay is not None:
        s.participant.input = InputSource.REPLAY
        s.participant.replay_file = str(replay.resolve())
        overrides.append(
            f'participant.input = "replay", participant.replay_file = "{replay.resolve()}" '
            "(--replay)"
        )
    return Resolved(s, overrides)
