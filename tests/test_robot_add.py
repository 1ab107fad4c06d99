"""`hrc robot add` (robots/README.md, "Bring your own robot"): the makers' descriptions beside the
project (../shared/robots: UR5e, xArm 6, Panda) and a description package with xacro and Collada
meshes (the UR5e's, as a maker's ROS package lays it out: a macro file with a prefix argument, a
top-level file that includes it through $(find ...), meshes named package://...) made into robot
folders: a scenario that names them validates, the report's figures hold, bad input is named."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hrc import scenario as sc
from hrc.scenario import urdf

from .conftest import HRC, ROOT

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

SHARED = ROOT.parent / "shared" / "robots"
MAKERS = {  # file, its chain as the report should guess it
    "ur5e": ("ur5e/ur5e.urdf", "base_link", "wrist_3_link"),
    "xarm6": ("xarm6/xarm6.urdf", "link_base", "link_eef"),
    "franka_panda": ("franka_panda/franka_panda.urdf", "base", "fer_link8"),
}


def robot_add(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [HRC, "robot", "add", *args], capture_output=True, text=True, timeout=600
    )  # fmt: skip


def scenario_for(robot: Path, base: str, tip: str, folder: Path) -> Path:
    text = (ROOT / "scenarios" / "minimal.toml").read_text()
    path = folder / "s.toml"
    path.write_text(
        text.replace(
            'urdf = "robots/arm5.urdf"',
            f'urdf = "{robot}"\nbase_link = "{base}"\ntip_link = "{tip}"',
            1,
        )
    )
    return path


@pytest.mark.parametrize("name", sorted(MAKERS))
def test_a_makers_description_becomes_a_robot_with_its_report(name: str, tmp_path: Path) -> None:
    file, base, tip = MAKERS[name]
    src = SHARED / file
    if not src.is_file():
        pytest.skip(f"{src} is not on this machine")
    out = tmp_path / "robot"
    proc = robot_add(str(src), "--out", str(out), "--tcp", "0,0,0.1")
    assert proc.returncode == 0, proc.stderr
    assert "pybullet build time" not in proc.stdout + proc.stderr  # (its C code kept quiet)
    report = (out / "report.md").read_text()
    assert report in proc.stdout
    assert f"- chain: `{base}` -> `{tip}`" in report, report
    reach = float(re.search(r"- reach: ([\d.]+) m", report).group(1))  # type: ignore[union-attr]
    assert 0.6 < reach < 1.5, report  # arms of 0.7-0.9 m (the Panda's base sits under link0)
    fk = float(re.search(r"agree within ([\d.]+) mm", report).group(1))  # type: ignore[union-attr]
    assert fk <= 0.5, report
    ik = float(re.search(r"\(the service's solver[^)]*\): ([\d.]+) % solved", report).group(1))  # type: ignore[union-attr]
    assert ik >= 95.0, report
    # the folder stands alone: its meshes beside it, every path relative, all of them there
    made = next(out.glob("*.urdf"))
    info = urdf.read_urdf(made)
    assert info.meshes and all(not Path(m).is_absolute() for m in info.meshes), info.meshes
    assert urdf.missing_meshes(info, []) == []
    # and a scenario naming it validates (its chain as the report gives it)
    s = sc.load(scenario_for(made, base, tip, tmp_path), motion_check=False)
    assert s.robots["r1"].tip_link == tip
    # the thesis board laid out for it: every move of the task planned by the motion check
    board = out / f"thesis-{made.stem}.toml"
    assert f"The thesis board laid out for it: `{board.name}` (it validates)" in report, report
    laid = sc.load(board)  # (with the motion check)
    assert {r.urdf for r in laid.robots.values()} == {made.name}  # beside it: the folder moves
    finishes(board, tmp_path / "trial")


def finishes(scenario: Path, out: Path) -> None:
    """The thesis task on `scenario` runs to its end: all 18 parts placed."""
    run = subprocess.run(
        [HRC, "run", str(scenario), "--out", str(out), "--max-ticks", "120000"],
        capture_output=True, text=True, timeout=900, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    assert m["task"]["finished"] and m["run"]["ok"], m["run"]
    assert len(m["parts"]) == 18 and all(p["placed_s"] is not None for p in m["parts"].values())


@pytest.fixture
def ur_package(tmp_path: Path) -> Path:
    """The UR5e as a maker's ROS description package: `ur_description/urdf/ur5e_macro.xacro`
    (a macro with a `prefix`, meshes package://ur_description/meshes/...), `ur5e.urdf.xacro`
    including it through $(find ur_description), the Collada and STL meshes in `meshes/`."""
    src = SHARED / "ur5e" / "ur5e.urdf"
    if not src.is_file():
        pytest.skip(f"{src} is not on this machine")
    pkg = tmp_path / "ws" / "ur_description"
    shutil.copytree(src.parent / "meshes", pkg / "meshes")
    root = ET.parse(src).getroot()
    names = {e.get("name") for e in root if e.tag in ("link", "joint")}
    body = []
    for e in root:
        if e.tag not in ("link", "joint"):
            continue
        e.set("name", "${prefix}" + str(e.get("name")))
        for ref in e.iter():
            if ref.tag in ("parent", "child") and ref.get("link") in names:
                ref.set("link", "${prefix}" + str(ref.get("link")))
            if ref.tag == "mesh":
                ref.set("filename", "package://ur_description/" + str(ref.get("filename")))
        body.append(ET.tostring(e, encoding="unicode"))
    xmlns = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'
    (pkg / "urdf").mkdir()
    (pkg / "urdf" / "ur5e_macro.xacro").write_text(
        f'<robot {xmlns}>\n<xacro:macro name="ur5e_robot" params="prefix">\n'
        + "\n".join(body)
        + "\n</xacro:macro>\n</robot>\n"
    )
    (pkg / "urdf" / "ur5e.urdf.xacro").write_text(
        f'<robot name="ur5e" {xmlns}>\n'
        '<xacro:arg name="prefix" default=""/>\n'
        '<xacro:include filename="$(find ur_description)/urdf/ur5e_macro.xacro"/>\n'
        '<xacro:ur5e_robot prefix="$(arg prefix)"/>\n</robot>\n'
    )
    return pkg


def test_a_description_package_with_xacro_and_collada_becomes_a_robot(
    ur_package: Path, tmp_path: Path
) -> None:
    out = tmp_path / "robot"
    proc = robot_add(
        str(ur_package), "--packages", str(ur_package.parent), "--arg", "prefix:=left_",
        "--out", str(out), "--tcp", "0,0,0.15",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    made = out / "ur5e.urdf"
    info = urdf.read_urdf(made)  # expanded: a URDF, no xacro left
    assert "left_base_link" in info.links and "left_wrist_3_link" in info.links, info.links
    assert "- chain: `left_base_link` -> `left_wrist_3_link`, 6 movable joints" in proc.stdout
    dae = [m for m in info.meshes if m.endswith(".dae")]
    assert len(dae) >= 6 and urdf.missing_meshes(info, []) == [], info.meshes
    assert all(m.startswith("meshes/ur_description/meshes/") for m in info.meshes), info.meshes
    s = sc.load(
        scenario_for(made, "left_base_link", "left_wrist_3_link", tmp_path), motion_check=False
    )
    assert s.robots["r1"].base_link == "left_base_link"
    # the thesis board laid out for it (a UR cannot point down near its own axis: the retreat
    # poses move outward), and the thesis task run to its end on it
    assert "retreat moved: [0.45, 0.45, 0.4] -> [0.55, 0.45, 0.4]" in proc.stdout, proc.stdout
    finishes(out / "thesis-ur5e.toml", tmp_path / "trial")
    # the raw xacro, given to a scenario: said to be xacro, with what to do
    raw = scenario_for(ur_package / "urdf" / "ur5e.urdf.xacro", "base_link", "tool0", tmp_path)
    v = subprocess.run([HRC, "validate", "--no-reach", str(raw)], capture_output=True, text=True)
    assert "a xacro file (macros not expanded), not a URDF: expand it first" in v.stderr, v.stderr


def test_bad_input_is_named_with_what_to_do(ur_package: Path, tmp_path: Path) -> None:
    # $(find ...) of a package nobody said where it is
    bare = tmp_path / "alone" / "ur5e.urdf.xacro"
    bare.parent.mkdir()
    shutil.copy(ur_package / "urdf" / "ur5e.urdf.xacro", bare)
    proc = robot_add(str(bare), "--out", str(tmp_path / "r"))
    assert proc.returncode == 2
    assert "$(find ur_description): no folder ur_description/ in the package folders" in proc.stderr
    assert "(--packages)" in proc.stderr
    # the package's meshes gone: every missing one named at once
    shutil.rmtree(ur_package / "meshes")
    proc = robot_add(
        str(ur_package), "--packages", str(ur_package.parent), "--out", str(tmp_path / "r")
    )
    assert proc.returncode == 2
    n = len(re.findall(r"package://ur_description/meshes/", proc.stderr.split(" (the first")[0]))
    assert "meshes not found: " in proc.stderr and n >= 12, proc.stderr
    # two top-level descriptions in a package: name one
    (ur_package / "urdf" / "ur5e_copy.urdf.xacro").write_text(
        (ur_package / "urdf" / "ur5e.urdf.xacro").read_text()
    )
    proc = robot_add(str(ur_package), "--out", str(tmp_path / "r"))
    assert proc.returncode == 2 and "2 descriptions in" in proc.stderr, proc.stderr
    assert "name one of ur5e.urdf.xacro, ur5e_copy.urdf.xacro" in proc.stderr
    proc = robot_add(str(tmp_path / "nowhere"))
    assert proc.returncode == 2 and "nowhere: no such file or folder" in proc.stderr
    proc = robot_add(str(ur_package), "--arg", "prefix=left_")
    assert proc.returncode == 2 and "expected NAME:=VALUE" in proc.stderr


def test_the_chain_guessed_stops_at_the_hand_where_the_fingers_part() -> None:
    """pybullet's Panda: the hand carries two finger joints; the arm ends at the hand."""
    from hrc.robot.add import guess_chain

    panda = urdf.resolve("package://pybullet_data/franka_panda/panda.urdf", None, [])
    assert panda is not None
    assert guess_chain(urdf.read_urdf(panda)) == ("panda_link0", "panda_hand")
