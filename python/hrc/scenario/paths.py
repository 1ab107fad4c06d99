"""Where relative paths in a scenario file point (docs/scenario.md)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from hrc.scenario import urdf

ROOT_ENV = "HRC_ROOT"
ROOT_MARKER = "scenarios"


def find_project_root(start: Path) -> Path | None:
    """The project root for a scenario file: $HRC_ROOT if set, else the nearest folder at or above
    `start` that holds a `scenarios/` folder, else the root of the installed project (so a
    scenario kept elsewhere can still name robots/arm5.urdf), else None."""
    env = os.environ.get(ROOT_ENV)
    if env:
        return Path(env).expanduser().resolve()
    here = start.resolve()
    for folder in (here, *here.parents):
        if (folder / ROOT_MARKER).is_dir():
            return folder
    from hrc.paths import project_root

    installed = project_root()
    return installed if (installed / ROOT_MARKER).is_dir() else None


def installed_root() -> Path:
    """The installed project's root: where the bundled files (robots/arm5.urdf) are."""
    from hrc.paths import project_root

    return project_root()


def resolve_path(written: str, folder: Path | None, root: Path | None) -> Path | None:
    """An existing file for `written`: absolute as is, else relative to the scenario's folder
    first, then the project root, then the installed project (a scenario anywhere, e.g. in a
    study folder with its own `scenarios/`, finds the bundled robots/arm5.urdf). None when it
    exists nowhere."""
    return _resolve(written, folder, root, Path.is_file)


def resolve_dir(written: str, folder: Path | None, root: Path | None) -> Path | None:
    """An existing folder for `written`, looked for as `resolve_path` looks for a file."""
    return _resolve(written, folder, root, Path.is_dir)


def _resolve(
    written: str, folder: Path | None, root: Path | None, exists: Callable[[Path], bool]
) -> Path | None:
    path = Path(written).expanduser()
    if path.is_absolute():
        return path if exists(path) else None
    for base in (folder, root, installed_root()):
        if base is not None and exists(base / path):
            return (base / path).resolve()
    return None


def resolve_urdf(
    written: str, folder: Path | None, root: Path | None, packages: Sequence[Path]
) -> Path | None:
    """A robot's `urdf`: ``package://NAME/...`` as robots/README.md says (``packages``, then an
    installed Python package NAME), anything else as `resolve_path`."""
    if written.startswith(urdf.PACKAGE):
        return urdf.resolve(written, None, packages)
    return resolve_path(written, folder, root)
