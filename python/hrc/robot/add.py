"""`hrc robot add SOURCE`: a description package, a URDF or a xacro file made into a robot folder
the project uses in every view, with a report (robots/README.md, "Bring your own robot").

The folder holds `<name>.urdf` (xacro expanded, every mesh path relative), `meshes/` (the meshes
it names, copied: the folder moves as a whole) and `report.md`: the chain (base and tip links,
guessed unless given), its joints and limits, the reach, the forward kinematics of the project
(`hrc.urdf_fk`, which the views use) checked against pybullet's on random postures, and the IK
service's solver on the chain (`hrc-ik-bench --only`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hrc.robot.expand import ExpandError, expand
from hrc.scenario import urdf
from hrc.scenario.urdf import UrdfJoint
from hrc.urdf_fk import UrdfModel

REACH_SAMPLES = 2000  # random postures for the reach
FK_CHECKS = 5  # random postures on which the project's FK is compared with pybullet's
FK_TOLERANCE_MM = 0.5
IK_TARGETS = 300  # IK figures: targets on the chain (the bench's service solver)
XACRO = (".xacro", ".urdf.xacro")


class RobotError(ValueError):
    """A description that cannot be made a robot: the message says what and what to do."""


@dataclass
class Report:
    name: str
    urdf: Path
    base: str
    tip: str
    joints: list[UrdfJoint]
    reach_m: float = 0.0
    zero_tip_m: list[float] = field(default_factory=list)
    fk_error_mm: float | None = None
    ik: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    tcp: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    board: Path | None = None  # the board's scenario laid out for the arm (board.py)
    board_changes: list[str] = field(default_factory=list)
    board_error: str = ""

    def markdown(self) -> str:
        dof = sum(j.kind in urdf.MOVABLE for j in self.joints)
        rows = [
            f"| {j.name} | {j.kind} | {_limit(j.lower)} | {_limit(j.upper)} |"
            for j in self.joints
            if j.kind in urdf.MOVABLE
        ]
        ik = self.ik.get("service", {})
        lines = [
            f"# Robot {self.name}",
            "",
            f"- description: `{self.urdf.name}`",
            f"- chain: `{self.base}` -> `{self.tip}`, {dof} movable joints",
            f"- reach: {self.reach_m:.3f} m (the tip's farthest distance from the base link's "
            f"origin over {REACH_SAMPLES} random postures within the limits)",
            "- tip at all joints 0: "
            + ", ".join(f"{v:.4f}" for v in self.zero_tip_m)
            + " m (in the base link's frame)",
        ]
        if self.fk_error_mm is not None:
            lines.append(
                f"- forward kinematics: the project's and pybullet's agree within "
                f"{self.fk_error_mm:.4f} mm on {FK_CHECKS} random postures"
            )
        if ik:
            lines.append(
                f"- IK (the service's solver, {ik.get('n')} random reachable targets): "
                f"{100 * ik.get('success', 0):.1f} % solved, mean {ik.get('mean_us', 0):.0f} us, "
                f"p99 {ik.get('p99_us', 0):.0f} us"
            )
        lines += ["", "| joint | type | lower | upper |", "|---|---|---|---|", *rows]
        lines += [f"\nNote: {n}" for n in self.notes]
        if self.board is not None:
            lines += ["", f"The thesis board laid out for it: `{self.board.name}` (it validates)"]
            lines += [f"- {c}" for c in self.board_changes] or ["- as the template has it"]
        if self.board_error:
            lines += ["", f"The board could not be laid out for it: {self.board_error}"]
        tcp = ", ".join(f"{v:g}" for v in self.tcp)
        lines += [
            "",
            "In a scenario:",
            "",
            "```toml",
            "[robots.r1]",
            f'urdf = "{self.urdf}"',
            f'base_link = "{self.base}"',
            f'tip_link = "{self.tip}"',
            f"tcp = {{ xyz = [{tcp}] }}   # the tool centre point in the tip link's frame",
            "```",
        ]
        return "\n".join(lines) + "\n"


def _limit(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}"


def find_description(source: Path) -> Path:
    """The URDF or xacro file `source` names: itself, or the one top-level description of a
    package folder (its `urdf/` folder first)."""
    if source.is_file():
        return source
    if not source.is_dir():
        raise RobotError(f"{source}: no such file or folder")
    for folder in (source / "urdf", source):
        found = sorted(
            p for p in folder.glob("*") if p.is_file() and p.name.endswith((".urdf", *XACRO))
        )
        # a package's macro files are included by its top-level ones: those name a <robot>
        # that instantiates something (not only <xacro:macro> definitions)
        top = [p for p in found if _top_level(p)]
        if len(top) == 1:
            return top[0]
        if len(top) > 1:
            raise RobotError(
                f"{source}: {len(top)} descriptions in {folder}: name one of "
                + ", ".join(p.name for p in top)
            )
    raise RobotError(f"{source}: no URDF or xacro file in it (nor in its urdf/ folder)")


def _top_level(path: Path) -> bool:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return False
    if root.tag != "robot":
        return False
    return any(not c.tag.endswith("macro") and not c.tag.endswith("property") for c in root)


def guess_chain(info: urdf.UrdfInfo) -> tuple[str, str]:
    """(base, tip): the root link (past a fixed `world`, prefixed or not), and the end of the
    arm: down the only branch that holds movable joints, through fixed links, to a leaf or to
    the link where two movable branches part (a hand and its fingers)."""
    children = {j.child for j in info.joints}
    roots = [link for link in info.links if link not in children]
    if len(roots) != 1:
        raise RobotError(f"{info.path.name}: not one tree (its roots: {', '.join(roots)})")
    below: dict[str, list[urdf.UrdfJoint]] = defaultdict(list)
    for j in info.joints:
        below[j.parent].append(j)
    base = roots[0]
    if base.endswith("world") and len(below[base]) == 1 and below[base][0].kind == "fixed":
        base = below[base][0].child

    def movable(link: str) -> int:
        return sum((j.kind in urdf.MOVABLE) + movable(j.child) for j in below[link])

    tip = base
    while below[tip]:
        moving = [j for j in below[tip] if j.kind in urdf.MOVABLE or movable(j.child)]
        if len(moving) > 1:
            break  # the hand: its fingers part here
        nxt = moving or below[tip]
        if len(nxt) > 1:
            break  # fixed links only, several: frames on the tool; stop at the branch
        tip = nxt[0].child
    return base, tip


def _copy_meshes(root: ET.Element, src: Path, packages: Sequence[Path], out: Path) -> None:
    """Every mesh the description names copied into `out/meshes/`, its path made relative; all
    missing ones named at once."""
    meshes = list(root.iter("mesh"))
    found_at = {m: urdf.resolve(m.get("filename", ""), src.parent, packages) for m in meshes}
    lost = [m.get("filename", "") for m, found in found_at.items() if found is None]
    if lost:
        first = ", ".join(str(c) for c in urdf.candidates(lost[0], src.parent, packages))
        raise RobotError(
            f"{src.name}: {len(lost)} of its {len(meshes)} meshes not found: "
            + ", ".join(dict.fromkeys(lost))
            + f" (the first looked for at {first or 'nowhere'}); give the folder that holds "
            "their package (--packages)"
        )
    for m, found in found_at.items():
        written = m.get("filename", "")
        assert found is not None
        if written.startswith(urdf.PACKAGE):
            rel = Path(written[len(urdf.PACKAGE) :])
        else:
            rel = Path(found.parent.name) / found.name
        target = out / "meshes" / rel
        if target.exists() and target.read_bytes() != found.read_bytes():
            digest = hashlib.sha256(str(found).encode()).hexdigest()[:8]
            target = target.with_name(f"{target.stem}-{digest}{target.suffix}")
        target.parent.mkdir(parents=True, exist_ok=True)
        if not target.exists():
            shutil.copyfile(found, target)
        m.set("filename", str(target.relative_to(out)))


def _reach(
    model: UrdfModel, chain: Sequence[UrdfJoint], base: str, tip: str
) -> tuple[float, list[float]]:
    rng = np.random.default_rng(0)
    far = 0.0
    zero: list[float] = []
    for k in range(REACH_SAMPLES + 1):
        q = {} if k == 0 else _random_q(chain, rng)
        poses = model.link_poses(q)
        rel = np.linalg.solve(poses[base], poses[tip])[:3, 3]
        if k == 0:
            zero = [float(v) for v in rel]
        far = max(far, float(np.linalg.norm(rel)))
    return far, zero


def _random_q(chain: Sequence[urdf.UrdfJoint], rng: np.random.Generator) -> dict[str, float]:
    q = {}
    for j in chain:
        if j.kind not in urdf.MOVABLE:
            continue
        lo = j.lower if j.lower is not None and j.kind != "continuous" else -math.pi
        hi = j.upper if j.upper is not None and j.kind != "continuous" else math.pi
        q[j.name] = float(rng.uniform(lo, hi))
    return q


def _fk_against_pybullet(
    path: Path, model: UrdfModel, chain: Sequence[UrdfJoint], base: str, tip: str
) -> float:
    """The largest distance (mm) between the tip's position in the base link's frame by the
    project's FK and by pybullet's, over FK_CHECKS random postures."""
    rng = np.random.default_rng(1)
    with _quiet():  # pybullet's C code prints (its build time, no inertia, ...) on the terminal
        import pybullet as p

        cid = p.connect(p.DIRECT)
        try:
            body = p.loadURDF(str(path), useFixedBase=True, physicsClientId=cid)
        except p.error as exc:
            p.disconnect(physicsClientId=cid)
            raise RobotError(f"{path.name}: pybullet cannot load it ({exc})") from exc
    try:
        index = {
            p.getJointInfo(body, i, physicsClientId=cid)[12].decode(): i
            for i in range(p.getNumJoints(body, physicsClientId=cid))
        }
        joint_index = {
            p.getJointInfo(body, i, physicsClientId=cid)[1].decode(): i
            for i in range(p.getNumJoints(body, physicsClientId=cid))
        }
        worst = 0.0
        for _ in range(FK_CHECKS):
            q = _random_q(chain, rng)
            for name, v in q.items():
                p.resetJointState(body, joint_index[name], v, physicsClientId=cid)
            mine = model.link_poses(q)
            ours = np.linalg.solve(mine[base], mine[tip])[:3, 3]
            theirs = _pb_pose(p, cid, body, index, base, tip)
            worst = max(worst, 1000.0 * float(np.linalg.norm(ours - theirs)))
        return worst
    finally:
        p.disconnect(physicsClientId=cid)


@contextmanager
def _quiet() -> Iterator[None]:
    """File descriptors 1 and 2 to /dev/null for the block (C code's prints included)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (null, *saved):
            os.close(fd)


def _pb_pose(p: Any, cid: int, body: int, index: Mapping[str, int], base: str, tip: str) -> Any:
    def world(link: str) -> Any:
        if link not in index:  # the root link: the body's base frame
            pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=cid)
            # (pybullet's base frame is the root's inertial frame: undo it)
            inertial = p.getDynamicsInfo(body, -1, physicsClientId=cid)[3:5]
            inv = p.invertTransform(*inertial)
            pos, orn = p.multiplyTransforms(pos, orn, *inv)
        else:
            s = p.getLinkState(
                body, index[link], computeForwardKinematics=True, physicsClientId=cid
            )
            pos, orn = s[4], s[5]  # the link's URDF frame
        m = np.eye(4)
        m[:3, :3] = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
        m[:3, 3] = pos
        return m

    return np.linalg.solve(world(base), world(tip))[:3, 3]


def _ik_figures(path: Path, base: str, tip: str) -> dict[str, Any]:
    from hrc.paths import ik_bench_binary

    binary = ik_bench_binary()
    if not binary.exists():
        return {}
    argv = [str(binary), "--only", "--chain", f"robot={path}:{base}:{tip}"]
    argv += ["--n", str(IK_TARGETS), "--gd-n", "0", "--json"]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=600, check=False)
    if proc.returncode != 0:
        raise RobotError(f"the IK service's chain {base} -> {tip}: {proc.stderr.strip()}")
    chains: dict[str, Any] = json.loads(proc.stdout)["chains"]
    figures: dict[str, Any] = chains["robot"]
    return figures


def add(
    source: Path,
    out: Path | None = None,
    name: str | None = None,
    packages: Sequence[Path] = (),
    args: Mapping[str, str] | None = None,
    base: str | None = None,
    tip: str | None = None,
    tcp: Sequence[float] = (0.0, 0.0, 0.0),
    board: Path | None = None,
) -> Report:
    """Makes the robot folder `out` (default `robots/<name>` in the working folder) from
    `source` and returns its report (also in the folder: `report.md`)."""
    src = find_description(source.expanduser().resolve())
    packages = [Path(p).expanduser().resolve() for p in packages]
    for p in packages:
        if not p.is_dir():
            raise RobotError(f"--packages {p}: no such folder")
    if src.name.endswith(XACRO) or _has_xacro(src):
        try:
            text = expand(src, packages, args)
        except ExpandError as exc:
            raise RobotError(str(exc)) from exc
    else:
        text = src.read_text(encoding="utf-8")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotError(f"{src}: not valid XML after expansion ({exc})") from exc
    name = name or root.get("name") or src.name.split(".")[0]
    out = (out or Path("robots") / name).resolve()
    out.mkdir(parents=True, exist_ok=True)
    _copy_meshes(root, src, packages, out)
    path = out / f"{name}.urdf"
    text = ET.tostring(root, encoding="unicode")
    path.write_text(text + "\n", encoding="utf-8")
    try:
        info = urdf.read_urdf(path)
    except urdf.UrdfError as exc:
        raise RobotError(str(exc)) from exc
    g_base, g_tip = guess_chain(info)
    base, tip = base or g_base, tip or g_tip
    for flag, link in (("--base", base), ("--tip", tip)):
        if link not in info.links:
            raise RobotError(
                f"{flag}: {path.name} has no link {link!r}; its links: {', '.join(info.links)}"
            )
    joints = info.chain(base, tip)
    if joints is None:
        raise RobotError(f"--tip: {tip!r} is not below {base!r} in {path.name}")
    report = Report(name, path, base, tip, joints)
    model = UrdfModel.from_string(text, path.name)  # the FK the views use
    report.reach_m, report.zero_tip_m = _reach(model, joints, base, tip)
    report.fk_error_mm = _fk_against_pybullet(path, model, joints, base, tip)
    if report.fk_error_mm > FK_TOLERANCE_MM:
        report.notes.append(
            f"the forward kinematics differ by {report.fk_error_mm:.3f} mm from pybullet's: "
            "look at the joints' origins and axes"
        )
    report.ik = _ik_figures(path, base, tip)
    if not report.ik:
        report.notes.append("no IK figures: build services/ik_cpp (scripts/setup.sh)")
    odd = [
        j.name for j in joints if j.kind in urdf.LIMITED and (j.lower is None or j.upper is None)
    ]
    if odd:
        report.notes.append(f"joints without position limits: {', '.join(odd)}")
    report.tcp = [float(v) for v in tcp]
    if board is not None:
        _lay_out(report, board, out, name)
    (out / "report.md").write_text(report.markdown(), encoding="utf-8")
    return report


def _lay_out(report: Report, template: Path, out: Path, name: str) -> None:
    """`<out>/<template>-<name>.toml`: the template's board laid out for the arm (board.py)."""
    from hrc.paths import project_root
    from hrc.robot.board import BoardError, layout

    keys = {
        "urdf": str(report.urdf),
        "base_link": report.base,
        "tip_link": report.tip,
        "tcp": {"xyz": report.tcp},
    }
    stem = f"{template.stem}-{name}"
    try:
        # (the scenario names the URDF beside it: the folder moves as a whole)
        laid = layout(template, keys, out, project_root(), stem, report.urdf.name)
    except (BoardError, OSError, ValueError) as exc:
        report.board_error = str(exc)
        return
    report.board = out / f"{stem}.toml"
    report.board.write_text(
        f"# {template.name} laid out for {name} by hrc robot add (robots/README.md)\n" + laid.text,
        encoding="utf-8",
    )
    report.board_changes = laid.changes


def _has_xacro(path: Path) -> bool:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise RobotError(f"{path}: cannot read it ({exc.strerror or exc})") from exc
    return "http://www.ros.org/wiki/xacro" in text
