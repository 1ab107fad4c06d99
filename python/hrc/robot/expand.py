"""Xacro expanded, as ROS's `xacro` command does, without ROS: `$(find PKG)` resolves to a folder
called PKG in the given package folders, else at or above the file (a ROS package), else beside
a folder above it (a workspace's `src/`)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path


class ExpandError(ValueError):
    """A xacro file that cannot be expanded (the message names the file and why)."""


def find_package(name: str, near: Path, packages: Sequence[Path]) -> Path | None:
    """The folder of ROS package `name`, for a file at `near`."""
    for d in packages:
        if (d / name).is_dir():
            return d / name
    for up in (near, *near.parents):
        if up.name == name:
            return up
        if (up / name).is_dir():
            return up / name
    return None


@contextmanager
def _finding(near: Path, packages: Sequence[Path]) -> Iterator[None]:
    # xacro resolves $(find) through ROS 2's ament index, which a lab's machine without ROS has
    # not: its resolver is swapped for ours while we expand (and put back after).
    from xacro import substitution_args

    def find(name: str) -> str:
        found = find_package(name, near, packages)
        if found is None:
            where = ", ".join(str(p) for p in packages) or "none given"
            raise ExpandError(
                f"$(find {name}): no folder {name}/ in the package folders ({where}) nor at or "
                f"above {near}: give the folder that holds {name}/ (--packages)"
            )
        return str(found)

    before = substitution_args._eval_find
    substitution_args._eval_find = find
    try:
        yield
    finally:
        substitution_args._eval_find = before


def expand(path: Path, packages: Sequence[Path] = (), args: Mapping[str, str] | None = None) -> str:
    """The URDF text of xacro file `path` with `args` (xacro's `name:=value` arguments)."""
    import xacro

    with _finding(path.parent, packages):
        try:
            doc = xacro.process_file(str(path), mappings=dict(args or {}))
        except ExpandError:
            raise
        except Exception as exc:  # xacro's own errors (XacroException, NameError, ...)
            raise ExpandError(f"{path}: xacro: {type(exc).__name__}: {exc}") from exc
    text: str = doc.toprettyxml(indent="  ")
    return text
