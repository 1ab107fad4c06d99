"""The researcher's view of a live trial: `hrc run --web`, the rerun web viewer opened in headless
chromium (software WebGL). The logger's blueprint must show the 3D scene large, seen from behind
the participant, with the plots and the event log in a narrow column. The screenshot is saved in
test-output/viewer/ for a person to look at."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from hrc.browser import headless_chromium, output_dir
from hrc.ports import free_port

from .conftest import HRC, ROOT
from hrc_logger.entities import rgb
from hrc_logger.view import HUMAN_PART_RGB

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

VIEWPORT = {"width": 1600, "height": 900}
SCENE_RIGHT = 0.74  # the scene's right edge, as a fraction of the width (3 : 1 columns)
HUMAN_PARTS = HUMAN_PART_RGB  # the participant's parts (orange)
R1_PARTS = rgb("yellow")  # r1's parts
UI_BARS_PX = 50  # the viewer's top bar and bottom time bar (a blue play button)


def wait_for_port(port: int, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), 0.5).close()
            return
        except OSError:
            time.sleep(0.3)
    raise AssertionError(f"the web viewer never listened on port {port}")


def near(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 8) -> np.ndarray:
    """Mask of the pixels of `rgb`'s hue (within `tol` degrees), saturated and bright enough.
    Shading scales the channels and translucency mixes in the white background, neither moves
    the hue: it separates the participant's orange (31°) from r1's yellow (50°) where a
    per-channel distance would not."""
    px = img[:, :, :3].astype(float)
    hi, lo = px.max(axis=2), px.min(axis=2)
    return (
        (np.abs(_hue_deg(px) - _hue_deg(np.array([[rgb]], dtype=float))[0, 0]) <= tol)
        & ((hi - lo) > 0.5 * np.maximum(hi, 1.0))
        & (hi > 90)
    )


def _hue_deg(px: np.ndarray) -> np.ndarray:
    r, g, b = px[..., 0], px[..., 1], px[..., 2]
    return np.degrees(np.arctan2(np.sqrt(3.0) * (g - b), 2.0 * r - g - b)) % 360.0


def test_the_web_viewer_shows_the_scene_large_from_behind_the_participant(
    tmp_path: Path, ik_bin: Path
) -> None:
    from PIL import Image

    web = free_port()
    # realtime and long: the viewer lives as long as the trial; we interrupt it when done
    proc = subprocess.Popen(
        [
            HRC,
            "run",
            str(ROOT / "scenarios" / "thesis.toml"),
            "--out",
            str(tmp_path / "out"),
            "--mode",
            "realtime",
            "--max-ticks",
            str(240 * 600),
            "--web",
            "--web-port",
            str(web),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    shot = output_dir("viewer") / "rerun-web-viewer.png"
    try:
        assert proc.stdout is not None
        url = ""
        for line in proc.stdout:  # the URL hrc run prints for a person to open
            if line.startswith("rerun web viewer: "):
                url = line.split(": ", 1)[1].strip()
                break
        assert url.startswith(f"http://127.0.0.1:{web}/?url="), url
        wait_for_port(web, 60)
        with headless_chromium() as browser:
            page = browser.new_page(viewport=VIEWPORT)
            page.goto(url, timeout=120_000)
            page.wait_for_selector("canvas", timeout=120_000)
            # Compiling the viewer and rendering in software takes a while on a loaded machine:
            # look until the parts of both the participant and r1 are drawn in the scene.
            deadline = time.monotonic() + 240
            while True:
                time.sleep(10)
                page.screenshot(path=str(shot), timeout=120_000)
                img = np.asarray(Image.open(shot).convert("RGB"))[UI_BARS_PX:-UI_BARS_PX]
                w = img.shape[1]
                scene, side = img[:, : int(SCENE_RIGHT * w)], img[:, int(SCENE_RIGHT * w) :]
                human, yellow = near(scene, HUMAN_PARTS), near(scene, R1_PARTS)
                if (human.sum() > 400 and yellow.sum() > 400) or time.monotonic() > deadline:
                    break
            # the parts come first (static); give the arms' joint states time to stream in
            time.sleep(20)
            page.screenshot(path=str(shot), timeout=120_000)
            img = np.asarray(Image.open(shot).convert("RGB"))[UI_BARS_PX:-UI_BARS_PX]
            scene, side = img[:, : int(SCENE_RIGHT * w)], img[:, int(SCENE_RIGHT * w) :]
            human, yellow = near(scene, HUMAN_PARTS), near(scene, R1_PARTS)
    finally:
        os.killpg(proc.pid, signal.SIGINT)  # hrc run stops its services and keeps the files
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    # The page shows the recording: the participant's parts and r1's parts are in the scene ...
    assert human.sum() > 400, f"no participant parts drawn in the scene (see {shot})"
    assert yellow.sum() > 400, f"no r1 parts drawn in the scene (see {shot})"
    # ... and the scene is large: the parts on the board and r1's table spread over more than a
    # fifth of the screen's width (the default layout gave the scene a third of the width and of
    # the height: the same parts spread over about a ninth)
    cols = np.flatnonzero(human | yellow) % scene.shape[1]
    lo, hi = np.percentile(cols, [5, 95])
    assert hi - lo > w / 5, f"the scene is small: parts over {hi - lo:.0f} of {w} px ({shot})"
    # the side column holds the plots, not the scene
    assert near(side, HUMAN_PARTS, 5).sum() < human.sum() / 10
