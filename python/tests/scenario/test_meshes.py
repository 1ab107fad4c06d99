"""Meshes every view can draw (hrc.scenario.meshes): a Collada mesh converted to GLB once, the
same size, then taken from the cache; a mesh that cannot be converted named with why."""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh

from hrc.scenario.meshes import RERUN_DRAWS, MeshError, drawable


def collada_box(path: Path) -> Path:
    path.write_bytes(trimesh.creation.box(extents=[0.1, 0.2, 0.3]).export(file_type="dae"))
    return path


def test_a_collada_mesh_is_converted_once_to_glb_of_the_same_size(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    src = collada_box(tmp_path / "link.dae")
    glb = drawable(src, cache=cache)
    assert glb.suffix == ".glb" and glb.parent == cache
    back = trimesh.load(glb, force="scene")
    assert back.extents == pytest.approx([0.1, 0.2, 0.3], abs=1e-6)
    made = glb.stat().st_mtime_ns
    assert drawable(src, cache=cache) == glb and glb.stat().st_mtime_ns == made  # the cache
    # another content, another file (the name carries the content's hash)
    src.write_bytes(trimesh.creation.box(extents=[0.1, 0.1, 0.1]).export(file_type="dae"))
    assert drawable(src, cache=cache) != glb


def test_what_rerun_draws_is_left_as_it_is(tmp_path: Path) -> None:
    for suffix in sorted(RERUN_DRAWS):
        path = tmp_path / f"m{suffix}"
        assert drawable(path, cache=tmp_path / "cache") == path  # (not even read)
    assert not (tmp_path / "cache").exists()


def test_a_mesh_that_cannot_be_converted_is_named_with_why(tmp_path: Path) -> None:
    broken = tmp_path / "broken.dae"
    broken.write_text("<COLLADA>not a mesh")
    with pytest.raises(MeshError, match=r"broken\.dae: cannot be converted to GLB"):
        drawable(broken, cache=tmp_path / "cache")
    with pytest.raises(MeshError, match=r"missing\.dae: cannot read it"):
        drawable(tmp_path / "missing.dae", cache=tmp_path / "cache")
    with pytest.raises(MeshError, match=r"m\.xyz: a \.xyz mesh: neither drawn nor converted"):
        drawable(tmp_path / "m.xyz", cache=tmp_path / "cache")
