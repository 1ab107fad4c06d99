"""The participant's page draws a real arm from its description's meshes (robots/README.md): the
thesis board with two Pandas (the maker's, Collada meshes, from ../shared/robots; pybullet's
data folder's, OBJ meshes named package://...), live in headless chromium. Each arm is hidden
once through the page's test hook, and the picture must change at its base, middle and wrist:
without the meshes (not served, not loaded) the arm has nothing to draw there. The pictures are
kept in test-output/client/panda-*.png.
"""

from __future__ import annotations

import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from .participant_page import (
    Page,
    browser,  # noqa: F401  (a fixture)
    live,  # noqa: F401  (a fixture)
    what_is_seen,
)
from .test_real_robots import PANDA, SHARED_PANDA

pytestmark = [pytest.mark.slow, pytest.mark.e2e]


def status(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return int(r.status)
    except urllib.error.HTTPError as exc:
        return exc.code


def with_makers_panda(folder: Path) -> Path:
    """thesis-panda.toml with r1 the maker's Panda (FR3 family; Collada visual meshes, STL
    collision meshes), beside r2, pybullet's (OBJ meshes named package://...)."""
    text = PANDA.read_text()
    r1 = text[text.index("[robots.r1]") : text.index("[robots.r2]")]
    mine = (
        r1.replace('"package://pybullet_data/franka_panda/panda.urdf"', f'"{SHARED_PANDA}"')
        .replace('base_link = "panda_link0"', 'base_link = "fer_link0"')
        .replace('tip_link = "panda_hand"', 'tip_link = "fer_link8"')
        .replace("tcp = { xyz = [0.0, 0.0, 0.1034] }", "tcp = { xyz = [0.0, 0.0, 0.2] }")
    )
    mine = "\n".join(ln for ln in mine.split("\n") if not ln.startswith("gripper"))
    assert mine.count("fer_link") == 2, mine
    path = folder / "two-pandas.toml"
    path.write_text(text.replace(r1, mine))
    return path


def test_the_page_shows_a_real_arm_from_its_meshes(
    browser: Any,  # noqa: F811
    live: Any,  # noqa: F811
    tmp_path: Path,
) -> None:
    # r1: the maker's Panda, drawn from Collada; r2: pybullet's, from OBJ
    run = live(with_makers_panda(tmp_path) if SHARED_PANDA.is_file() else PANDA)
    base = run.spectator_url
    # What urdf-loader asks for package://meshes/visual/link1.obj; nothing else of the data
    # folder (another robot's file, a path out of it) is served.
    assert status(base + "robots/meshes/visual/link1.obj") == 200
    assert status(base + "robots/meshes/collision/link1.obj") == 200
    assert status(base + "robots/franka_panda/meshes/visual/link1.obj") == 200  # package named
    assert status(base + "robots/xarm/xarm_description/meshes/xarm6/visual/link1.stl") == 404
    assert status(base + "robots/../franka_panda/panda.urdf") == 404
    page = Page(browser, run.url)
    robots = page.state()["robots"]
    assert all(r["loaded"] for r in robots.values()), robots
    # The probe points sit on the links' meshes: an arm whose meshes did not load has none.
    probes = page.page.evaluate("window.hrcTest.probes()")
    for robot in ("robot:r1", "robot:r2"):
        assert len(probes.get(robot, [])) >= 3, f"{robot}: no mesh to probe ({probes.get(robot)})"
    seen = what_is_seen(page, "panda-desktop", only=("robot",))
    for robot in ("robot:r1", "robot:r2"):
        assert robot in seen, f"nothing to probe for {robot}: {sorted(seen)}"
        s = seen[robot]
        assert s.seen == s.total, f"{robot}: seen at {s.seen} of {s.total} points; {s.misses}"
