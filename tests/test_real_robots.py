"""Real robots (robots/README.md): the shipped real-arm scenarios finish under every policy with
provoked collisions and the thesis's task semantics, deterministically; a lab's own description,
referenced from outside the project with only its chain given, runs the minimal scenario; the
rerun recording holds the meshes in the robot's colour, and the Panda's fingers open and close.
"""

from __future__ import annotations

import itertools
import math
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest
import rerun as rr

from hrc.scenario import colors, urdf

from .conftest import HRC, ROOT, strip_fields
from .goldens import normalised
from .warm_cli import hrc

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

PANDA = ROOT / "scenarios" / "thesis-panda.toml"
UR5E = ROOT / "scenarios" / "thesis-ur5e.toml"
THESIS_PARTS = 18
POLICIES = ("retreat", "retreat_button", "stop_colliding", "ssm")
# A lab's own arm, as its maker publishes it: the project's tests use it from there, never a copy
# (it is beside the project on the development machines, not beside every clone); and the xArm 6
# of pybullet's data folder (its meshes named package://...), which every setup installs.
XARM6 = ROOT.parent / "shared" / "robots" / "xarm6" / "xarm6.urdf"
# the maker's Panda (FR3 family) description: Collada visual meshes, STL collision meshes
SHARED_PANDA = ROOT.parent / "shared" / "robots" / "franka_panda" / "franka_panda.urdf"
PYBULLET_XARM6 = urdf.resolve("package://pybullet_data/xarm/xarm6_robot.urdf", None, [])
WALL = {"wall_time", "wall_s", "realtime_factor", "end_reason"}


def variant(src: Path, folder: Path, policy: str, provoke: bool = True) -> Path:
    """`src` under `policy`, the participant provoking collisions."""
    text = src.read_text()
    for old, new in (
        ('safety_policy = "retreat"', f'safety_policy = "{policy}"'),
        ("provoke_collisions = false", f"provoke_collisions = {str(provoke).lower()}"),
    ):
        assert text.count(old) == 1, f"{src.name}: expected one '{old}'"
        text = text.replace(old, new)
    out = folder / f"{src.stem}-{policy}.toml"
    out.write_text(text)
    return out


def run(scenario: Path, out: Path, *extra: str, view: bool = False) -> dict[str, Any]:
    """The trial's normalised outputs; ``view``: it also keeps its 3D recording."""
    argv = ["run", str(scenario), "--out", str(out), "--max-ticks", "120000", *extra]
    proc = hrc(*(argv if view else [*argv, "--no-view"]), timeout=1200)
    assert proc.returncode == 0, f"{scenario.name}: exit {proc.returncode}\n{proc.stderr[-3000:]}"
    return normalised(out)


@pytest.mark.parametrize("policy", POLICIES)
@pytest.mark.parametrize("scenario", [PANDA, UR5E], ids=["panda", "ur5e"])
def test_a_real_arm_scenario_finishes_under_every_policy(
    scenario: Path, policy: str, tmp_path: Path, ik_bin: Path
) -> None:
    out = run(variant(scenario, tmp_path, policy), tmp_path / "trial")
    m = out["metrics.json"]
    assert m["run"]["ok"], m["run"]
    assert m["task"]["finished"], m["task"]
    assert m["conditions"]["safety_policy"] == policy
    placed = {pid for pid, p in m["parts"].items() if p.get("placed_s") is not None}
    assert len(placed) == THESIS_PARTS, f"placed {sorted(placed)}"
    # the thesis's order and waits hold with real arms: a part never before what it waits for
    for after, before in (("H2", "RA2"), ("H5", "RA3"), ("RA4", "H3"), ("RA6", "H5")):
        assert m["parts"][after]["placed_s"] >= m["parts"][before]["placed_s"], (after, before)
    assert m["collisions"]["human_robot_count"] > 0, "the provoked collisions met no arm"


def test_a_real_arm_trial_is_deterministic(tmp_path: Path, ik_bin: Path) -> None:
    scenario = variant(PANDA, tmp_path, "retreat")
    a = run(scenario, tmp_path / "a", "--seed", "3")
    b = run(scenario, tmp_path / "b", "--seed", "3")
    assert strip_fields(a, WALL) == strip_fields(b, WALL)


def _transforms(rrd: Path, entity: str) -> list[tuple[int, list[float], list[float]]]:
    """(tick, translation, quaternion xyzw) of every temporal row of `entity`."""
    rows = []
    for chunk in rr.chunk.RrdReader(rrd).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        tcol = next(n for n in batch.schema.names if n.endswith(":translation"))
        qcol = next(n for n in batch.schema.names if n.endswith(":quaternion"))
        for tick, t, q in zip(
            batch.column("tick").to_pylist(),
            batch.column(tcol).to_pylist(),
            batch.column(qcol).to_pylist(),
            strict=True,
        ):
            if t is not None and q is not None:
                rows.append((int(tick), list(t[0]), list(q[0])))
    return sorted(rows)


def _media_types(rrd: Path, robot: str) -> dict[str, str]:
    """Visual mesh entity of each link -> the media type of its Asset3D (what the viewer gets)."""
    out: dict[str, str] = {}
    for chunk in rr.chunk.RrdReader(rrd).stream():
        path = chunk.entity_path
        if not path.startswith(f"/robot_{robot}/") or "/visual_geometries/" not in path:
            continue
        batch = chunk.to_record_batch()
        if "Asset3D:media_type" in batch.schema.names:
            kind = next(v for v in batch.column("Asset3D:media_type").to_pylist() if v)[0]
            out[path.split("/visual_geometries/")[1].split("/")[0]] = kind
    return out


def _visual_links(rrd: Path) -> dict[str, set[str]]:
    """Robot -> the links with visual geometry in the recording (meshes and shapes alike)."""
    out: dict[str, set[str]] = {"r1": set(), "r2": set()}
    for chunk in rr.chunk.RrdReader(rrd).stream():
        path = chunk.entity_path
        if path.startswith("/robot_") and "/visual_geometries/" in path:
            robot = path.split("/")[1].removeprefix("robot_")
            out.setdefault(robot, set()).add(path.split("/visual_geometries/")[1].split("/")[0])
    return out


def _visual_meshes(rrd: Path, robot: str) -> dict[str, list[float] | None]:
    """Visual mesh entity of each link -> its albedo factor (rgba 0..1)."""
    out: dict[str, list[float] | None] = {}
    for chunk in rr.chunk.RrdReader(rrd).stream():
        path = chunk.entity_path
        if not path.startswith(f"/robot_{robot}/") or "/visual_geometries/" not in path:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        blob = next((n for n in names if n == "Asset3D:blob"), None)
        if blob is None or not any(v for v in batch.column(blob).to_pylist()):
            continue
        albedo = next((n for n in names if n == "Asset3D:albedo_factor"), None)
        value = None
        if albedo is not None:
            packed = next(v for v in batch.column(albedo).to_pylist() if v)[0]
            value = [((packed >> s) & 0xFF) / 255 for s in (24, 16, 8, 0)]
        out[path.split("/visual_geometries/")[1].split("/")[0]] = value
    return out


def test_the_recording_holds_the_meshes_and_the_fingers_move(tmp_path: Path, ik_bin: Path) -> None:
    out = tmp_path / "trial"
    run(PANDA, out, view=True)
    rrd = out / "recording.rrd"
    for robot, color in (("r1", "yellow"), ("r2", "green")):
        meshes = _visual_meshes(rrd, robot)
        links = {f"panda_link{i}" for i in range(7)} | {"panda_hand", "panda_leftfinger"}
        assert links <= meshes.keys(), f"{robot}: meshes for {sorted(meshes)}"
        want = [c / 255 for c in colors.rgb(color)]
        for link, rgba in meshes.items():
            assert rgba is not None and all(
                math.isclose(a, b, abs_tol=1.5 / 255) for a, b in zip(rgba, want, strict=False)
            ), f"{robot} {link}: albedo {rgba}, not {color} {want}"
    # The fingers open while the arm carries nothing and close on every part it carries.
    fingers = [t[1][1] for t in _transforms(rrd, "/robot_r1/joints/panda_finger_joint1")]
    assert fingers, "no finger transforms in the recording"
    opened = sum(1 for a, b in itertools.pairwise(fingers) if a < 0.02 <= b)
    assert max(fingers) == pytest.approx(0.04, abs=1e-6) and min(fingers) < 0.011
    assert opened >= 6, f"the fingers opened {opened} times for r1's 6 parts"


@pytest.mark.parametrize("description", [PYBULLET_XARM6, XARM6], ids=["pybullet", "maker"])
def test_a_description_from_outside_the_project_runs_the_minimal_scenario(
    description: Path | None, tmp_path: Path, ik_bin: Path
) -> None:
    if description is None or not description.is_file():
        pytest.skip(f"{description or 'pybullet_data/xarm'} is not on this machine")
    text = (ROOT / "scenarios" / "minimal.toml").read_text()
    own = text.replace(
        'urdf = "robots/arm5.urdf"',
        f'urdf = "{description}"\nbase_link = "link_base"\ntip_link = "link6"\n'
        "tcp = { xyz = [0.0, 0.0, 0.172] }",
    )
    if description == XARM6:  # r1 with the project's generic gripper attached at its flange
        own = own.replace(
            "tcp = { xyz = [0.0, 0.0, 0.172] }", 'gripper_urdf = "generic"', 1
        )  # fmt: skip
    scenario = tmp_path / "xarm6.toml"
    scenario.write_text(own)
    m = run(scenario, tmp_path / "trial", view=True)["metrics.json"]
    assert m["task"]["finished"] and all(p["placed_s"] is not None for p in m["parts"].values())
    if description == XARM6:  # the gripper drawn in the recording, beside the arm's links
        drawn = _visual_links(tmp_path / "trial" / "recording.rrd")
        assert {"gripper_palm", "link6", "link_base"} <= drawn["r1"], drawn
        assert "gripper_palm" not in drawn["r2"], drawn
    # Without the chain, the check names what is missing and what the file has.
    bare = tmp_path / "bare.toml"
    bare.write_text(text.replace('urdf = "robots/arm5.urdf"', f'urdf = "{description}"'))
    proc = subprocess.run([HRC, "validate", str(bare)], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    assert (
        f"robots.r1.tip_link: {description.name} has no link named 'tool' (the default tip_link)"
        in proc.stdout + proc.stderr
    )
    assert "its links: world, link_base, link1" in proc.stdout + proc.stderr


def test_a_description_with_collada_visuals_is_drawn_in_the_recording(
    tmp_path: Path, ik_bin: Path
) -> None:
    """The maker's Panda draws its links with Collada meshes, outside the formats rerun
    documents (a Kinova's were dropped from the view without a word): the logger converts them
    to GLB, once (a cache), so the recording holds every link in a documented format, in the
    robot's colour."""
    if not SHARED_PANDA.is_file():
        pytest.skip(f"{SHARED_PANDA} is not on this machine")
    text = (ROOT / "scenarios" / "minimal.toml").read_text()
    scenario = tmp_path / "panda.toml"
    scenario.write_text(
        text.replace(
            'urdf = "robots/arm5.urdf"',
            f'urdf = "{SHARED_PANDA}"\nbase_link = "fer_link0"\ntip_link = "fer_link8"\n'
            "tcp = { xyz = [0.0, 0.0, 0.2] }",
            1,
        )
    )
    cache = tmp_path / "meshes"  # a cold cache: the trial converts
    out = tmp_path / "trial"
    proc = subprocess.run(
        [HRC, "run", str(scenario), "--out", str(out), "--ticks", "60"],
        capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL,
        env={**os.environ, "HRC_MESH_CACHE": str(cache)},
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    kinds = _media_types(out / "recording.rrd", "r1")
    links = {f"fer_link{i}" for i in range(8)}
    assert links <= kinds.keys(), f"visual meshes for {sorted(kinds)}"
    assert {kinds[k] for k in links} == {"model/gltf-binary"}, kinds
    assert len(list(cache.glob("link*.glb"))) == 8, sorted(cache.iterdir())
    want = [c / 255 for c in colors.rgb("yellow")]  # tinted like any other arm
    for link, rgba in _visual_meshes(out / "recording.rrd", "r1").items():
        assert rgba is not None and all(
            math.isclose(a, b, abs_tol=1.5 / 255) for a, b in zip(rgba, want, strict=False)
        ), (link, rgba)
