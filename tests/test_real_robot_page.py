"""The participant's page draws a real arm from its description's meshes (robots/README.md): the
thesis board with two Pandas (pybullet's data folder, OBJ meshes named package://...), live in
headless chromium. Each arm is hidden once through the page's test hook, and the picture must
change at its base, middle and wrist: without the meshes (not served, not loaded) the arm has
nothing to draw there. The pictures are kept in test-output/client/panda-*.png.
"""

from __future__ import annotations

import urllib.error
import urllib.request
from typing import Any

import pytest

from .participant_page import (
    Page,
    browser,  # noqa: F401  (a fixture)
    live,  # noqa: F401  (a fixture)
    what_is_seen,
)
from .test_real_robots import PANDA

pytestmark = [pytest.mark.slow, pytest.mark.e2e]


def status(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return int(r.status)
    except urllib.error.HTTPError as exc:
        return exc.code


def test_the_page_shows_a_real_arm_from_its_meshes(browser: Any, live: Any) -> None:  # noqa: F811
    run = live(PANDA)
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
