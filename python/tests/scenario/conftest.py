"""Fixtures for the scenario tests: a stand-in arm URDF, the minimal scenario as data, and a
small TOML writer so each test can break one thing and load the result."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hrc.scenario import Problem, ScenarioError, load

REPO = Path(__file__).resolve().parents[3]
SCENARIOS = REPO / "scenarios"

# ------------------------------------------------------------- a 5-joint arm like robots/arm5.urdf

_LINK = """  <link name="{name}">
    <visual><origin xyz="0 0 {half}"/>
      <geometry><cylinder radius="0.04" length="{length}"/></geometry></visual>
    <inertial><origin xyz="0 0 {half}"/><mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
"""
_JOINT = """  <joint name="{name}" type="revolute">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="0 0 {z}"/><axis xyz="{axis}"/>
    <limit lower="{lo}" upper="{hi}" effort="100" velocity="2"/>
  </joint>
"""


def arm_urdf(upper: float = 0.40, fore: float = 0.35) -> str:
    """base yaw (z), shoulder (y), elbow (y), wrist pitch (y), wrist roll (z), then a fixed tool."""
    links = [
        ("base_link", 0.15),
        ("link1", 0.10),
        ("link2", upper),
        ("link3", fore),
        ("link4", 0.05),
        ("link5", 0.03),
    ]
    joints = [
        ("joint1", "0 0 1", -3.1416, 3.1416),
        ("joint2", "0 1 0", -2.0, 2.0),
        ("joint3", "0 1 0", -2.6, 2.6),
        ("joint4", "0 1 0", -2.2, 2.2),
        ("joint5", "0 0 1", -3.1416, 3.1416),
    ]
    out = ['<?xml version="1.0"?>\n<robot name="arm5_test">\n']
    for name, length in links:
        out.append(_LINK.format(name=name, length=length, half=length / 2))
    for i, (name, axis, lo, hi) in enumerate(joints):
        out.append(
            _JOINT.format(
                name=name,
                parent=links[i][0],
                child=links[i + 1][0],
                z=links[i][1],
                axis=axis,
                lo=lo,
                hi=hi,
            )
        )
    # the tool frame sits 5 cm beyond the last link; its inertial origin is deliberately offset
    # so a check that used the centre of mass instead of the link frame would be caught
    out.append(
        '  <link name="tool"><inertial><origin xyz="0.02 0 0.01"/><mass value="0.1"/>'
        '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>'
        "</inertial></link>\n"
    )
    out.append(
        '  <joint name="tool_joint" type="fixed"><parent link="link5"/><child link="tool"/>'
        '<origin xyz="0 0 0.08"/></joint>\n'
    )
    out.append("</robot>\n")
    return "".join(out)


def write_arm(folder: Path, name: str = "arm5.urdf") -> Path:
    path = folder / name
    path.write_text(arm_urdf(), encoding="utf-8")
    return path


# ------------------------------------------------------------- a TOML writer (enough for scenarios)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        if isinstance(v, float) and math.isnan(v):
            return "nan"
        if isinstance(v, float) and math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _value(k)


def to_toml(data: dict[str, Any]) -> str:
    lines: list[str] = []
    for name, value in data.items():
        if name == "parts" and isinstance(value, list) and all(isinstance(p, dict) for p in value):
            for part in value:
                lines.append("[[parts]]")
                lines.extend(f"{_key(k)} = {_value(v)}" for k, v in part.items())
                lines.append("")
        elif (
            name == "robots"
            and isinstance(value, dict)
            and all(isinstance(r, dict) for r in value.values())
        ):
            for rid, robot in value.items():
                lines.append(f"[robots.{_key(rid)}]")
                lines.extend(f"{_key(k)} = {_value(v)}" for k, v in robot.items())
                lines.append("")
        elif isinstance(value, dict):
            lines.append(f"[{_key(name)}]")
            lines.extend(f"{_key(k)} = {_value(v)}" for k, v in value.items())
            lines.append("")
        else:
            lines.append(f"{_key(name)} = {_value(value)}")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="session")
def arm_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A project root holding robots/arm5.urdf (the stand-in arm) and an empty scenarios/."""
    root = tmp_path_factory.mktemp("root")
    (root / "robots").mkdir()
    (root / "scenarios").mkdir()
    write_arm(root / "robots")
    return root


@pytest.fixture(name="to_toml")
def to_toml_fixture() -> Callable[[dict[str, Any]], str]:
    return to_toml


@pytest.fixture
def minimal_raw() -> dict[str, Any]:
    """scenarios/minimal.toml as plain data, for a test to change."""
    return tomllib.loads((SCENARIOS / "minimal.toml").read_text(encoding="utf-8"))


@pytest.fixture
def write_scenario(tmp_path: Path) -> Callable[[dict[str, Any]], Path]:
    def write(data: dict[str, Any], name: str = "case.toml") -> Path:
        path = tmp_path / name
        path.write_text(to_toml(data), encoding="utf-8")
        return path

    return write


@pytest.fixture
def problems_of(
    write_scenario: Callable[[dict[str, Any]], Path], arm_root: Path
) -> Callable[..., list[Problem]]:
    """Load data (no motion check unless asked) and return its problems ([] when it loads)."""

    def run(data: dict[str, Any], **kwargs: Any) -> list[Problem]:
        kwargs.setdefault("motion_check", False)
        try:
            load(write_scenario(data), project_root=arm_root, **kwargs)
        except ScenarioError as err:
            assert err.problems, "a ScenarioError always lists its problems"
            return err.problems
        return []

    return run
