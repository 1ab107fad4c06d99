"""The house rules of the imports (scripts/check_imports.py, run by scripts/lint.sh): the library
never imports a service, no service imports another, and no import cycle among modules or among
the library's rooms. The project keeps them; a tree that breaks each rule is told which."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from hrc.paths import project_root

CHECK = project_root() / "scripts" / "check_imports.py"


def check(root: Path | None = None) -> subprocess.CompletedProcess[str]:
    args = [sys.executable, str(CHECK), *([str(root)] if root else [])]
    return subprocess.run(args, capture_output=True, text=True, timeout=120)


def test_the_project_keeps_the_library_below_the_services_and_has_no_cycle() -> None:
    proc = check()
    assert proc.returncode == 0, proc.stdout
    assert "the library below every service, no cycle" in proc.stdout


def write(root: Path, rel: str, text: str = "") -> None:
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_a_tree_that_breaks_each_rule_is_told_where(tmp_path: Path) -> None:
    write(tmp_path, "python/hrc/__init__.py")
    # the library imports a service (inside a function: it still counts)
    write(tmp_path, "python/hrc/web.py", "def f():\n    from hrc_people.page import x\n")
    # two rooms of the library that import each other, through different modules
    write(tmp_path, "python/hrc/study/__init__.py")
    write(tmp_path, "python/hrc/study/table.py", "from hrc.session.state import s\n")
    write(tmp_path, "python/hrc/session/__init__.py")
    write(tmp_path, "python/hrc/session/state.py", "s = 1\n")
    write(tmp_path, "python/hrc/session/run.py", "from hrc.study import table\n")
    # two modules of a service that import each other (one only for types)
    write(tmp_path, "services/people/hrc_people/__init__.py")
    write(
        tmp_path,
        "services/people/hrc_people/page.py",
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from hrc_people.task import T\n"
        "x = 1\n",
    )
    write(tmp_path, "services/people/hrc_people/task.py", "from hrc_people import page\nT = 1\n")
    # a service that imports another service
    write(tmp_path, "services/robots/hrc_robots/__init__.py", "import hrc_people.page\n")
    proc = check(tmp_path)
    out = proc.stdout
    assert proc.returncode == 1, out
    assert "python/hrc/web.py:2: the library imports hrc_people" in out, out
    assert "services/robots/hrc_robots/__init__.py:1: service hrc_robots imports hrc_people" in out
    assert "cycle among 2 modules: hrc_people.page (line 3) -> hrc_people.task" in out, out
    assert (
        "cycle among 2 rooms of the library: hrc.session (hrc.session.run line 1) -> hrc.study"
        in out
    )
    assert "imports: 2 across the layers, 2 cycle(s)" in out, out


def test_a_folder_that_is_no_project_is_named(tmp_path: Path) -> None:
    proc = check(tmp_path)
    assert proc.returncode == 2 and "holds no python/hrc" in proc.stdout, proc.stdout
