"""Meshes every view can draw.

A maker's description ships its visual meshes in whatever its tools wrote: often Collada (.dae,
most ROS description packages). The participant's page reads Collada (three.js), pybullet
reads the collision meshes (STL, OBJ); rerun documents glTF/GLB, OBJ, STL and PLY for its
Asset3D. Its 0.41 viewer drew the Panda's Collada meshes here, but a Kinova Gen3's were dropped
without a word (issue 46): a mesh outside rerun's documented formats is converted once to GLB
(trimesh; pycollada reads Collada), its scene graph and colours kept, and cached by the source
file's content.
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

# What rerun documents for Asset3D (its URDF importer logs any other mesh as a blob as it is).
RERUN_DRAWS = frozenset({".glb", ".gltf", ".obj", ".stl", ".ply"})
# What the project converts from (trimesh reads them; Collada through pycollada).
CONVERTS = frozenset({".dae", ".off", ".3mf"})


class MeshError(ValueError):
    """A mesh that cannot be read or converted (the message names the file and why)."""


def cache_dir() -> Path:
    """Where converted meshes are kept: `$HRC_MESH_CACHE`, else the user's cache folder."""
    env = os.environ.get("HRC_MESH_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "hrc-cosim" / "meshes"


def drawable(path: Path, draws: frozenset[str] = RERUN_DRAWS, cache: Path | None = None) -> Path:
    """`path` if a view that `draws` these suffixes reads it; else its GLB conversion (made once,
    then taken from the cache). MeshError names a file that cannot be converted."""
    suffix = path.suffix.lower()
    if suffix in draws:
        return path
    if suffix not in CONVERTS:
        raise MeshError(
            f"{path}: a {suffix or 'suffix-less'} mesh: neither drawn nor converted (meshes in "
            f"{', '.join(sorted(draws | CONVERTS))} are)"
        )
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise MeshError(f"{path}: cannot read it ({exc.strerror or exc})") from exc
    folder = cache or cache_dir()
    out = folder / f"{path.stem}-{hashlib.sha256(data).hexdigest()[:16]}.glb"
    if out.is_file():
        return out
    import trimesh  # heavy: only where a mesh needs converting

    try:
        scene: Any = trimesh.load(path, force="scene")  # (a trimesh.Scene)
        glb = scene.export(file_type="glb")
    except Exception as exc:  # any reader error: named, with the file
        why = f"{type(exc).__name__}: {exc}"
        raise MeshError(f"{path}: cannot be converted to GLB ({why})") from exc
    if not scene.geometry:
        raise MeshError(f"{path}: holds no geometry")
    folder.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_bytes(glb)
    tmp.replace(out)  # atomic: trials started together may convert the same mesh
    log.info("converted %s to %s", path, out)
    return out
