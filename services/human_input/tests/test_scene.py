"""The scene a participant client draws: the same furniture, colours and cue ids as physics and
the task, and only the scenario's robot files served."""

from __future__ import annotations

import json
from pathlib import Path

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.scenario.colors import hex_color
from hrc.scenario.layout import furniture

from hrc_human_input.scene import RobotFiles, build_scene

ROOT = project_root()


def thesis() -> sc.Scenario:
    return sc.load(ROOT / "scenarios" / "thesis.toml", motion_check=False)


def test_the_scene_is_the_scenario_with_physics_furniture_and_one_set_of_colours() -> None:
    s = thesis()
    scene = build_scene(sc.to_proto(s), RobotFiles())
    json.dumps(scene)  # plain JSON
    assert scene["protocol"] == 1 and scene["scenario"] == s.scenario.name
    assert len(scene["parts"]) == len(s.parts)
    boxes = {b.name: b for b in furniture(s) if b.collides}
    table = next(t for t in scene["tables"] if t["id"] == "human")
    assert table["center"] == [round(c, 4) for c in boxes["table"].center]
    assert table["size"] == [round(2 * h, 4) for h in boxes["table"].half]
    for robot in scene["robots"]:
        assert robot["color"] == hex_color(s.robots[robot["id"]].color_or_default)
        own = [p for p in scene["parts"] if p["owner"] == robot["id"]]
        assert own and all(p["color"] == robot["color"] for p in own)
        assert robot["joint_names"][0] == "j1_base_yaw" and len(robot["joint_names"]) == 5
    human = [p for p in scene["parts"] if p["owner"] == "human"]
    assert len({p["color"] for p in human}) == 1
    assert human[0]["color"] not in {r["color"] for r in scene["robots"]} | {scene["hand_color"]}
    cues = {c["id"]: c for c in scene["cues"]}
    for p in s.parts:
        assert f"target:{p.id}" in cues
    assert cues["waiting:r1"]["text"] == "Waiting.." and cues["waiting:r1"]["position"][2] > 0.5


def test_only_the_scenario_urdfs_and_meshes_beside_them_are_served(tmp_path: Path) -> None:
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    urdf = tmp_path / "pkg" / "arm.urdf"
    urdf.write_text("<robot name='a'/>")
    (tmp_path / "pkg" / "meshes" / "link.stl").write_bytes(b"solid")
    (tmp_path / "pkg" / "notes.txt").write_text("private")
    (tmp_path / "secret.stl").write_bytes(b"outside")
    files = RobotFiles()
    assert files.add("r1", urdf) == "/robots/arm.urdf"
    assert files.add("r2", urdf) == "/robots/arm.urdf"  # one file, one URL
    assert files.lookup("arm.urdf") == urdf
    assert files.lookup("meshes/link.stl") == tmp_path / "pkg" / "meshes" / "link.stl"
    assert files.lookup("pkg/meshes/link.stl") == tmp_path / "pkg" / "meshes" / "link.stl"
    for bad in ("notes.txt", "../secret.stl", "meshes/../../secret.stl", "..", "", "other.urdf"):
        assert files.lookup(bad) is None, bad
