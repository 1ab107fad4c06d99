"""A robot's description: where its files are found, what the checks say about its chain, its
meshes and its fingers (robots/README.md, "Bring your own robot")."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hrc import scenario as sc
from hrc.scenario import urdf
from hrc.scenario.errors import ScenarioError
from hrc.scenario.paths import installed_root

ROBOT = """<robot name="toy">
  <link name="stand"/>
  <link name="base"><visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
  <link name="arm"/>
  <link name="finger"/>
  <joint name="bolt" type="fixed"><parent link="stand"/><child link="base"/></joint>
  <joint name="turn" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="arm"/><child link="finger"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.04" velocity="0.1" effort="1"/></joint>
</robot>
"""


def make_robot(folder: Path, mesh: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "toy.urdf"
    path.write_text(ROBOT.format(mesh=mesh))
    return path


def test_package_paths_are_found_in_packages_around_the_urdf_and_installed(
    tmp_path: Path,
) -> None:
    ws = tmp_path / "ws"
    (ws / "toy_description" / "meshes").mkdir(parents=True)
    (ws / "toy_description" / "meshes" / "base.stl").write_text("solid x\nendsolid x\n")
    path = make_robot(ws / "toy_description" / "urdf", "package://toy_description/meshes/base.stl")
    want = ws / "toy_description" / "meshes" / "base.stl"
    # a ROS package: the folder named like the package, above the URDF
    assert urdf.resolve("package://toy_description/meshes/base.stl", path.parent, []) == want
    # a packages folder (ROS_PACKAGE_PATH style), without the URDF's folder
    assert urdf.resolve("package://toy_description/meshes/base.stl", None, [ws]) == want
    # an installed Python package: pybullet's data folder ships a Panda
    found = urdf.resolve("package://pybullet_data/franka_panda/panda.urdf", None, [])
    assert found is not None and found.name == "panda.urdf"
    assert urdf.resolve("package://no_such_pkg/x.stl", path.parent, [ws]) is None
    assert urdf.missing_meshes(urdf.read_urdf(path), []) == []


def test_a_copy_for_physics_has_absolute_mesh_paths_and_the_tint(tmp_path: Path) -> None:
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    mesh = tmp_path / "pkg" / "meshes" / "base.obj"
    mesh.write_text("v 0 0 0\n")
    plain = make_robot(tmp_path / "plain", str(mesh))
    assert urdf.localized_urdf(plain, []) == plain  # nothing to rewrite: the file itself
    path = make_robot(tmp_path / "pkg" / "urdf", "package://pkg/meshes/base.obj")
    copy = urdf.localized_urdf(path, [], tmp_path / "out", tint_rgb=(1.0, 0.5, 0.0))
    root = ET.parse(copy).getroot()
    assert [m.get("filename") for m in root.iter("mesh")] == [str(mesh)]
    colors = [c.get("rgba") for c in root.iter("color")]
    assert colors == ["1 0.5 0 1"]
    assert urdf.localized_urdf(path, [], tmp_path / "out", tint_rgb=(1.0, 0.5, 0.0)) == copy


def scenario_with(tmp_path: Path, robot_keys: str) -> Path:
    text = (installed_root() / "scenarios" / "minimal.toml").read_text()
    text = text.replace('urdf = "robots/arm5.urdf"', robot_keys, 1)
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def problems(path: Path) -> list[str]:
    with pytest.raises(ScenarioError) as err:
        sc.load(path, motion_check=False)
    return [str(p) for p in err.value.problems]


def test_the_checks_name_the_key_and_what_the_file_has(tmp_path: Path) -> None:
    robot = make_robot(tmp_path / "d", "meshes/base.stl")
    got = problems(scenario_with(tmp_path, f'urdf = "{robot}"'))
    assert any(
        "robots.r1.base_link: toy.urdf has no link named 'base_link' (the default base_link); "
        "its links: stand, base, arm, finger" in p
        for p in got
    ), got
    got = problems(
        scenario_with(tmp_path, f'urdf = "{robot}"\nbase_link = "arm"\ntip_link = "base"')
    )
    assert any("robots.r1.tip_link: 'base' is not below 'arm' in toy.urdf" in p for p in got), got
    got = problems(
        scenario_with(tmp_path, f'urdf = "{robot}"\nbase_link = "base"\ntip_link = "arm"')
    )
    assert any(
        "robots.r1.urdf: toy.urdf: mesh meshes/base.stl not found (tried " in p for p in got
    ), got
    pkg = make_robot(tmp_path / "p", "package://toy_description/meshes/base.stl")
    got = problems(
        scenario_with(
            tmp_path,
            f'urdf = "{pkg}"\nbase_link = "base"\ntip_link = "arm"\npackages = ["nowhere"]\n'
            'gripper = { joints = ["turn", "nail"], open = 0.05, closed = 0.0 }',
        )
    )
    assert any("robots.r1.packages[0]: no such folder: nowhere" in p for p in got), got
    assert any("add the folder that holds toy_description/ to packages" in p for p in got), got
    assert any("robots.r1.gripper.joints: 'turn' is a joint of the arm's chain" in p for p in got)
    assert any(
        "robots.r1.gripper.joints: toy.urdf has no revolute or prismatic joint named 'nail'; "
        "its movable joints: turn, slide" in p
        for p in got
    ), got
    got = problems(
        scenario_with(
            tmp_path,
            f'urdf = "{pkg}"\nbase_link = "base"\ntip_link = "arm"\npackages = ["{tmp_path}"]\n'
            'gripper = { joints = ["slide"], open = 0.05, closed = 0.0 }',
        )
    )
    assert any(
        "robots.r1.gripper.open: 0.05 is outside slide's limits [0.0, 0.04]" in p for p in got
    )


def test_the_shipped_real_arm_scenarios_load_with_their_chains() -> None:
    root = installed_root() / "scenarios"
    panda = sc.load(root / "thesis-panda.toml", motion_check=False)
    r1 = panda.robots["r1"]
    assert (r1.base_link, r1.tip_link, r1.tcp.xyz) == ("panda_link0", "panda_hand", [0, 0, 0.1034])
    assert r1.gripper is not None and r1.gripper.joints == [
        "panda_finger_joint1",
        "panda_finger_joint2",
    ]
    path = panda.urdf_path("r1")
    assert path is not None and path.parent.name == "franka_panda"
    wire = sc.to_proto(panda).robots[0]
    assert (wire.base_link, wire.tip_link) == ("panda_link0", "panda_hand")
    assert wire.tcp.position.z == pytest.approx(0.1034) and list(wire.gripper.joints)
    back = sc.from_proto(sc.to_proto(panda))
    assert back.robots["r1"].tcp == r1.tcp and back.robots["r1"].gripper == r1.gripper
    ur5e = sc.load(root / "thesis-ur5e.toml", motion_check=False)
    assert ur5e.robots["r2"].tip_link == "tool" and ur5e.robots["r2"].gripper is None


def test_every_missing_mesh_is_named_at_once_with_a_hint_that_fits(tmp_path: Path) -> None:
    """A description with many meshes a check cannot find names them all in one run (it named
    the first, so a lab fixed them one run at a time); the hint fits what `packages` holds."""
    ws = tmp_path / "ws"
    (ws / "toy_description" / "meshes").mkdir(parents=True)
    text = ROBOT.format(mesh="package://toy_description/meshes/base.stl").replace(
        '<link name="arm"/>',
        '<link name="arm"><visual><geometry><mesh filename="file:///home/maker/arm.dae"/>'
        "</geometry></visual><collision><geometry>"
        '<mesh filename="package://toy_description/meshes/arm.stl"/></geometry></collision></link>',
    )
    robot = tmp_path / "d" / "toy.urdf"
    robot.parent.mkdir()
    robot.write_text(text)
    keys = f'urdf = "{robot}"\nbase_link = "base"\ntip_link = "arm"\n'
    # the package's folder is in packages, the files are not in it: no "add ... to packages"
    got = [
        p
        for p in problems(scenario_with(tmp_path, keys + f'packages = ["{ws}"]'))
        if p.startswith("robots.r1.urdf")
    ]
    assert len(got) == 1, got
    (msg,) = got
    assert "toy.urdf: mesh package://toy_description/meshes/base.stl not found (tried " in msg
    assert f"; {ws / 'toy_description'} is in packages but has no meshes/base.stl" in msg
    assert "add the folder" not in msg
    assert (
        "; 2 more of its 3 meshes not found: file:///home/maker/arm.dae, "
        "package://toy_description/meshes/arm.stl" in msg
    ), msg
    # without packages: the hint to give them; an absolute path first: made on another machine
    (msg,) = [p for p in problems(scenario_with(tmp_path, keys)) if p.startswith("robots.r1.urdf")]
    assert "add the folder that holds toy_description/ to packages" in msg, msg
    bare = urdf.read_urdf(robot)
    assert urdf.missing_meshes(bare, [])[1] == "file:///home/maker/arm.dae"


def test_a_xacro_file_given_as_the_urdf_is_said_to_be_xacro(tmp_path: Path) -> None:
    """It said "has no link named 'base_link'; its links: world" (the macros unexpanded)."""
    for name, text in (
        (
            "arm.urdf.xacro",
            '<robot name="a" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="world"/>'
            '<xacro:include filename="$(find arm_description)/urdf/arm.xacro"/></robot>',
        ),
        (  # named .urdf, but macros in it
            "arm.urdf",
            '<robot name="a" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="world"/>'
            '<xacro:arm prefix=""/></robot>',
        ),
    ):
        path = tmp_path / name
        path.write_text(text)
        got = problems(scenario_with(tmp_path, f'urdf = "{path}"'))
        assert any(
            f"robots.r1.urdf: {path}: a xacro file (macros not expanded), not a URDF: expand it "
            f"first (hrc robot add {name}" in p
            for p in got
        ), got
        assert not any("has no link named" in p for p in got), got


def test_a_gripper_is_attached_at_the_tip_from_the_scenario(tmp_path: Path) -> None:
    """`gripper_urdf = "generic"`: the project's two-finger gripper joined to the arm at its tip
    link in one URDF (what every service reads), the TCP at its finger tips unless given; a
    gripper's own description likewise; clashing names and missing files named."""
    arm = make_robot(tmp_path / "d", "meshes/base.stl")
    (tmp_path / "d" / "meshes").mkdir()
    (tmp_path / "d" / "meshes" / "base.stl").write_text("solid x\nendsolid x\n")
    keys = f'urdf = "{arm}"\nbase_link = "base"\ntip_link = "arm"\ngripper_urdf = "generic"'
    s = sc.load(scenario_with(tmp_path, keys), motion_check=False)
    assert s.robots["r1"].tcp.xyz == [0.0, 0.0, urdf.GENERIC_GRIPPER_TCP_M]
    joined = s.urdf_path("r1")
    assert joined is not None and joined != arm
    info = urdf.read_urdf(joined)
    assert {"gripper_palm", "gripper_tcp", "stand", "arm"} <= set(info.links), info.links
    mount = next(j for j in info.joints if j.name == "gripper_palm_mount")
    assert (mount.parent, mount.child, mount.kind) == ("arm", "gripper_palm", "fixed")
    assert urdf.missing_meshes(info, []) == []  # the arm's relative mesh, made absolute
    assert s.arm_urdf_path("r1") == arm.resolve()
    # the trial's copy of the scenario names both files; it loads to the same joined URDF
    from hrc.scenario.resolved import resolve

    again = sc.loads(resolve(s).toml(), tmp_path, motion_check=False)
    assert again.urdf_path("r1") == joined
    # a tcp given stays as given
    s = sc.load(scenario_with(tmp_path, keys + "\ntcp = { xyz = [0, 0, 0.2] }"), motion_check=False)
    assert s.robots["r1"].tcp.xyz == [0, 0, 0.2]
    # a gripper whose names clash with the arm's; one that is not there
    clash = tmp_path / "clash.urdf"
    clash.write_text('<robot name="g"><link name="arm"/></robot>')
    got = problems(scenario_with(tmp_path, keys.replace('"generic"', f'"{clash}"')))
    assert any(
        "robots.r1.gripper_urdf: clash.urdf: names that toy.urdf has too: arm" in p for p in got
    ), got
    got = problems(scenario_with(tmp_path, keys.replace('"generic"', '"nowhere.urdf"')))
    assert any(p.startswith("robots.r1.gripper_urdf: ") and "nowhere.urdf" in p for p in got), got
