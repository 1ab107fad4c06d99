"""What the project needs to know of a robot's URDF before any service loads it: its links and
joints, the chain between two links, and where the files it names are.

A URDF names a mesh (or, in a scenario, the URDF itself) three ways (robots/README.md):

- ``package://NAME/rest``: looked up as ``NAME/rest`` in each folder of the robot's ``packages``,
  then in the folders around the URDF (a folder called NAME at or above it, as a ROS package
  holds its ``urdf/``; or NAME beside it, as pybullet's data folder writes ``package://meshes/``),
  then in an installed Python package called NAME (``package://pybullet_data/franka_panda/...``);
- ``file:///absolute/path``, or an absolute path;
- a relative path: against the URDF's folder.

Physics loads a copy of the URDF with every mesh path made absolute (`localized_urdf`), so
pybullet never guesses; the participant page asks the bridge for them under ``/robots/``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

PACKAGE = "package://"
FILE = "file://"
MOVABLE = ("revolute", "continuous", "prismatic")
LIMITED = ("revolute", "prismatic")  # movable with position limits: what a finger may be


class UrdfError(ValueError):
    """The file is not a URDF this project can use; the message names the file and why."""


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    kind: str  # revolute | continuous | prismatic | fixed | ...
    parent: str
    child: str
    lower: float | None = None  # the limit's lower and upper (None: not given)
    upper: float | None = None


@dataclass(frozen=True)
class UrdfInfo:
    path: Path
    name: str
    links: list[str]
    joints: list[UrdfJoint]
    meshes: list[str]  # mesh file names as written, each once, collision and visual

    def chain(self, base: str, tip: str) -> list[UrdfJoint] | None:
        """The joints from `base` down to `tip` (None when `tip` is not below `base`)."""
        by_child = {j.child: j for j in self.joints}
        out: list[UrdfJoint] = []
        link = tip
        while link != base:
            joint = by_child.get(link)
            if joint is None:
                return None
            out.append(joint)
            link = joint.parent
        return out[::-1]

    def below(self, link: str) -> list[str]:
        """The links whose chain from the root passes through `link` (itself excluded)."""
        out: list[str] = []
        frontier = [link]
        while frontier:
            parent = frontier.pop()
            for j in self.joints:
                if j.parent == parent:
                    out.append(j.child)
                    frontier.append(j.child)
        return out


def _float(value: str | None) -> float | None:
    try:
        return float(value) if value is not None else None
    except ValueError:
        return None


def read_urdf(path: Path) -> UrdfInfo:
    try:
        root = ET.parse(path).getroot()
    except OSError as exc:
        raise UrdfError(f"URDF {path}: cannot read it ({exc.strerror or exc})") from exc
    except ET.ParseError as exc:
        raise UrdfError(f"URDF {path}: not valid XML ({exc})") from exc
    if _is_xacro(path, root):
        raise UrdfError(
            f"{path}: a xacro file (macros not expanded), not a URDF: expand it first "
            f"(hrc robot add {path.name}, or xacro {path.name} -o {path.stem}.urdf)"
        )
    if root.tag != "robot":
        raise UrdfError(f"URDF {path}: the top element is <{root.tag}>, not <robot>")
    links = [e.get("name", "") for e in root.findall("link")]
    if not links or not all(links):
        raise UrdfError(f"URDF {path}: no <link>, or a <link> without a name")
    joints = []
    for e in root.findall("joint"):
        parent, child, limit = e.find("parent"), e.find("child"), e.find("limit")
        joints.append(
            UrdfJoint(
                name=e.get("name", ""),
                kind=e.get("type", ""),
                parent=parent.get("link", "") if parent is not None else "",
                child=child.get("link", "") if child is not None else "",
                lower=_float(limit.get("lower")) if limit is not None else None,
                upper=_float(limit.get("upper")) if limit is not None else None,
            )
        )
    meshes = [
        m.get("filename", "")
        for link in root.findall("link")
        for m in link.iter("mesh")
        if m.get("filename")
    ]
    return UrdfInfo(path, root.get("name", ""), links, joints, list(dict.fromkeys(meshes)))


XACRO_NS = "{http://www.ros.org/wiki/xacro}"


def _is_xacro(path: Path, root: ET.Element) -> bool:
    """A xacro file: named so, or any element of xacro's namespace (xacro:macro, :include, ...)
    left in it (a URDF read as is would lack every link the macros make)."""
    if path.name.endswith((".xacro", ".urdf.xacro")):
        return True
    return any(e.tag.startswith(XACRO_NS) for e in root.iter())


def _installed_package(name: str) -> Path | None:
    """The folder of an installed Python package called `name` (not imported)."""
    if not name.isidentifier():
        return None
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


def candidates(written: str, folder: Path | None, packages: Sequence[Path]) -> list[Path]:
    """Where `written` may be, in the order they are tried (see the module's docstring)."""
    if written.startswith(FILE):
        return [Path(written[len(FILE) :])]
    if not written.startswith(PACKAGE):
        path = Path(written).expanduser()
        if path.is_absolute() or folder is None:
            return [path]
        return [folder / path]
    name, _, rest = written[len(PACKAGE) :].partition("/")
    out = [Path(d) / name / rest for d in packages]
    if folder is not None:
        for up in (folder, *folder.parents):
            if up.name == name:
                out.append(up / rest)
            out.append(up / name / rest)
    installed = _installed_package(name)
    if installed is not None:
        out.append(installed / rest)
    return out


def resolve(written: str, folder: Path | None, packages: Sequence[Path]) -> Path | None:
    """The existing file `written` names, or None."""
    for cand in candidates(written, folder, packages):
        if cand.is_file():
            return cand.resolve()
    return None


def _suffix(written: str) -> str:
    return Path(written.partition("?")[0]).suffix.lower()


def missing_meshes(info: UrdfInfo, packages: Sequence[Path]) -> list[str]:
    return [m for m in info.meshes if resolve(m, info.path.parent, packages) is None]


def localized_urdf(
    path: Path,
    packages: Sequence[Path],
    out_dir: Path | None = None,
    tint_rgb: Sequence[float] | None = None,
    draws: frozenset[str] | None = None,
) -> Path:
    """`path` itself when every mesh it names is a plain relative or absolute path, no tint is
    asked for and every visual mesh is of a kind in `draws` (suffixes; None: any); otherwise a
    copy (in `out_dir`, by default a per-user temporary folder, named by its content) whose mesh
    paths are absolute, whose visual meshes of other kinds are converted (hrc.scenario.meshes),
    and whose visuals all have the colour `tint_rgb` (0..1) if given. A mesh that is found
    nowhere is left as written: the scenario check has named it already, and pybullet then
    says what it could not load; one that cannot be converted raises MeshError."""
    tree = ET.parse(path)
    meshes = list(tree.getroot().iter("mesh"))
    shown = [m for v in tree.getroot().iter("visual") for m in v.iter("mesh")]
    foreign = [
        m for m in shown if draws is not None and _suffix(m.get("filename", "")) not in draws
    ]
    if (
        tint_rgb is None
        and not foreign
        and not any(m.get("filename", "").startswith((PACKAGE, FILE)) for m in meshes)
    ):
        return path
    # all of them: the copy lives elsewhere, relative paths would break
    _absolute_meshes(tree.getroot(), path.parent, packages)
    if foreign:
        from hrc.scenario.meshes import drawable

        assert draws is not None
        for mesh in foreign:
            found = Path(mesh.get("filename", ""))
            if found.is_file():
                mesh.set("filename", str(drawable(found, draws)))
    if tint_rgb is not None:
        rgba = " ".join(f"{c:.4g}" for c in (*tint_rgb[:3], 1.0))
        for visual in tree.getroot().iter("visual"):
            for old in visual.findall("material"):
                visual.remove(old)
            material = ET.SubElement(visual, "material", name=f"hrc_tint_{rgba.replace(' ', '_')}")
            ET.SubElement(material, "color", rgba=rgba)
    text = ET.tostring(tree.getroot(), encoding="unicode")
    return _written_once(text, path.stem, out_dir, salt=str(path.resolve()))


def _absolute_meshes(root: ET.Element, folder: Path, packages: Sequence[Path]) -> None:
    """Every mesh path under `root` made absolute where the file is found (else as written)."""
    for mesh in root.iter("mesh"):
        found = resolve(mesh.get("filename", ""), folder, packages)
        if found is not None:
            mesh.set("filename", str(found))


def _written_once(text: str, stem: str, out_dir: Path | None, salt: str = "") -> Path:
    """`text` as `<stem>-<hash>.urdf` in `out_dir` (default: a per-user temporary folder),
    written only if not there yet: the name is the content's."""
    digest = hashlib.sha256(f"{salt}\n{text}".encode()).hexdigest()[:16]
    folder = out_dir or Path(tempfile.gettempdir()) / f"hrc-urdf-{os.getuid()}"
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / f"{stem}-{digest}.urdf"
    if not out.is_file():
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(out)  # atomic: trials (services) started together may write the same file
    return out


GENERIC_GRIPPER = "generic"  # the project's two-finger gripper: robots/gripper.urdf
GENERIC_GRIPPER_TCP_M = 0.05  # its tool centre point from the mounting face (gripper_tcp)


def with_gripper(
    arm: Path, tip: str, gripper: Path, packages: Sequence[Path], out_dir: Path | None = None
) -> Path:
    """The arm's description with `gripper`'s attached at link `tip` by a fixed joint (the
    gripper's root link on the tip's frame): one URDF every view and physics read, written once
    (named by its content) in `out_dir` (default: a per-user temporary folder). Both files'
    mesh paths are made absolute; a gripper link or joint named like one of the arm's is
    refused (UrdfError)."""
    root, groot = ET.parse(arm).getroot(), ET.parse(gripper).getroot()
    for tree_root, path in ((root, arm), (groot, gripper)):  # the joined file lives elsewhere
        _absolute_meshes(tree_root, path.parent, packages)
    names = {e.get("name") for e in root if e.tag in ("link", "joint")}
    clash = sorted(
        str(e.get("name")) for e in groot if e.tag in ("link", "joint") and e.get("name") in names
    )
    if clash:
        raise UrdfError(f"{gripper.name}: names that {arm.name} has too: {', '.join(clash)}")
    children = {c.get("link") for j in groot.findall("joint") for c in j.findall("child")}
    groots = [str(e.get("name")) for e in groot.findall("link") if e.get("name") not in children]
    if len(groots) != 1:
        raise UrdfError(f"{gripper.name}: not one tree (its roots: {', '.join(groots)})")
    for e in list(groot):  # materials first-come: the arm's win a name both have
        if e.tag == "material" and root.find(f"material[@name='{e.get('name')}']") is not None:
            continue
        root.append(e)
    mount = ET.SubElement(root, "joint", name=f"{groots[0]}_mount", type="fixed")
    ET.SubElement(mount, "parent", link=tip)
    ET.SubElement(mount, "child", link=groots[0])
    ET.SubElement(mount, "origin", xyz="0 0 0", rpy="0 0 0")
    text = ET.tostring(root, encoding="unicode")
    return _written_once(text, f"{arm.stem}-{gripper.stem}", out_dir)
