"""The participant's page (services/human_input/client) in headless Debian chromium against a
live trial: `hrc run --input vr` with all five services, the page served by the bridge.

- desktop: the whole of scenarios/minimal.toml done through the page's own keyboard and mouse
  controls; the trial's metrics.json says the task finished;
- immersive: IWER (the WebXR emulation, loaded with ?test=iwer) enters immersive-vr; an
  emulated controller grabs and places H1; the page gets the placement and plays the chime;
- pictures: the desktop and XR views while r1 carries its part with anticipation on, checked
  pixel by pixel (r1 seen at its links, the cue seen and blinking, the parts' colours) and
  saved to test-output/client/ for a person to look at. tests/test_headset_view.py looks at
  the whole scene in every view.

The page and the person's moves: tests/participant_page.py.
"""

from __future__ import annotations

import colorsys
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from .conftest import wait_until
from .goldens import MINIMAL, with_robot_speed
from .participant_page import (
    PAGE_FPS,
    VIEWPORT,
    Live,
    Page,
    assert_whole_scene,
    browser,  # noqa: F401  (a fixture)
    carrying_ra1_lit,
    controller_places,
    freeze_at_ra1_carry,
    grab_part,
    live,  # noqa: F401  (a fixture)
    metrics,
    place_part,
    what_is_seen,
)

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

BLINK_WINDOW_S = 30.0  # the cue is seen lit and unlit within this (2 Hz blinking)


def test_desktop_page_completes_the_minimal_task(
    browser: Any,  # noqa: F811
    live: Callable[..., Live],  # noqa: F811
) -> None:
    run = live()
    trial = run.trial
    page = Page(browser, run.url + "&mode=desktop")
    s = page.state()
    assert s["role"] == "driver" and s["run"] == "waiting_first_grab", s
    grab_part(page, "H1")
    page.wait("task started", lambda s: s["run"] == "running", 5)
    place_part(page, "H1")
    page.wait("task finished", lambda s: s["run"] == "finished", 120)
    rc, out, err = trial.communicate(timeout=60)
    assert rc == 0, (out, err[-3000:])
    m = metrics(trial)
    assert m["task"]["finished"] is True, m["task"]
    assert "part_placed:H1" in page.state()["events"]
    sounds = page.page.evaluate("window.hrcAudioLog")
    assert [a["sound"] for a in sounds if a["cause"] == "part_placed:H1"] == ["chime"], sounds
    # the page drew at most `fps` frames a second (tests/participant_page.py: PAGE_FPS)
    if PAGE_FPS:
        gaps = page.page.evaluate("window.hrcTest.frameTimes().intervals")
        assert len(gaps) >= 5, gaps
        assert min(gaps) >= 1000 / PAGE_FPS - 3, f"frames closer than fps={PAGE_FPS} allows: {gaps}"
    assert not page.errors, page.errors


def test_a_participants_page_has_no_test_hooks(
    browser: Any,  # noqa: F811
    live: Callable[..., Live],  # noqa: F811
) -> None:
    """The hooks the browser tests drive the page with (window.hrcTest) are a chunk of their
    own, loaded only with ?test= in the URL: the page a participant opens has none of them."""
    run = live()
    tab = browser.new_page(viewport=VIEWPORT)
    try:
        loaded: list[str] = []
        tab.on("request", lambda r: loaded.append(r.url))
        tab.goto(run.url + "&mode=desktop")
        tab.wait_for_function("window.hrcApp && window.hrcApp.frames > 0", timeout=90_000)
        assert tab.evaluate("typeof window.hrcTest") == "undefined"
        assert not [u for u in loaded if "test-hooks" in u], loaded
        assert any(u.endswith("/assets/main.js") for u in loaded), loaded
    finally:
        tab.close()


def test_immersive_controller_grabs_and_places_h1(
    browser: Any,  # noqa: F811
    live: Callable[..., Live],  # noqa: F811
) -> None:
    page = Page(browser, live().url + "&test=iwer")
    page.page.click("#enter-vr")  # a user gesture, as a headset's browser needs
    page.wait("immersive session", lambda s: s["xr"], 20)

    # calibration: the right controller on the (real) table top, A pressed -> the table height
    # is its grip's height (the grip centre sits 1-2 cm from the emulated controller's origin)
    page.page.evaluate(
        """() => {
            const c = window.hrcXrDevice.controllers.right;
            c.position.set(0.1, 1.05, -0.5);
            c.updateButtonValue('a-button', 1);
        }"""
    )

    def board_y() -> float:
        return float(page.page.evaluate("window.hrcTest.worldToXr([0, 0, 0])[1]"))

    assert wait_until(lambda: abs(board_y() - 1.05) < 0.025, 10), board_y()
    page.page.evaluate("window.hrcXrDevice.controllers.right.updateButtonValue('a-button', 0)")
    controller_places(page, "H1")  # and away, so the robots can finish
    sounds = page.page.evaluate("window.hrcAudioLog")
    chimes = [a for a in sounds if a["cause"] == "part_placed:H1"]
    assert [a["sound"] for a in chimes] == ["chime"], sounds
    # the audio graph really ran: the context was started, not left suspended
    assert chimes[0]["state"] == "running", sounds
    page.screenshot("xr-after-placing.png")
    assert not page.errors, page.errors


# ---------------------------------------------------------------- pictures


def hue_sat(rgb: tuple[int, int, int]) -> tuple[float, float, float]:
    h, s, v = colorsys.rgb_to_hsv(*(c / 255 for c in rgb))
    return h * 360, s, v


def hex_rgb(color: str) -> tuple[int, int, int]:
    return int(color[1:3], 16), int(color[3:5], 16), int(color[5:7], 16)


def looks_like(pixel: tuple[int, int, int], color: str, tol_deg: float = 10.0) -> bool:
    """Same hue (lighting changes brightness, not hue) and clearly coloured."""
    h, s, _ = hue_sat(pixel)
    eh, _, _ = hue_sat(hex_rgb(color))
    return s > 0.35 and min(abs(h - eh), 360 - abs(h - eh)) <= tol_deg


def found_near(img: Any, xy: tuple[float, float], color: str, radius: int) -> bool:
    x0, y0 = round(xy[0]), round(xy[1])
    w, h = img.size
    return any(
        looks_like(img.getpixel((x, y)), color)
        for x in range(max(0, x0 - radius), min(w, x0 + radius + 1), 2)
        for y in range(max(0, y0 - radius), min(h, y0 + radius + 1), 2)
    )


def test_pictures_while_a_robot_carries_with_anticipation(
    browser: Any,  # noqa: F811
    live: Callable[..., Live],  # noqa: F811
    tmp_path: Path,
) -> None:
    run = live(with_robot_speed(MINIMAL, tmp_path, 0.15))  # a carry long enough for pictures
    desk = Page(browser, run.url + "&mode=desktop")
    # a second client: a spectator, in an emulated headset looking down at the board
    xr = Page(browser, run.spectator_url + "?test=iwer")
    assert xr.state()["role"] == "spectator"
    xr.page.click("#enter-vr")
    xr.wait("immersive session", lambda s: s["xr"], 20)
    xr.page.evaluate(
        """() => {
            const d = window.hrcXrDevice;
            d.position.set(0, 1.55, 0);
            d.quaternion.set(-0.33, 0, 0, 0.944);  // 38 degrees down
        }"""
    )
    scene = desk.scene()
    assert scene["anticipation"] is True
    # each page stops applying frames at the first one in which r1 holds RA1 with its target
    # cue lit (the XR page may run seconds behind on a loaded machine): the positions read and
    # the pictures then agree (the condition is a state: a page told after the grasp freezes at
    # its next frame; the cue may come a frame after the hold, carrying_ra1_lit)
    freeze_at_ra1_carry(xr)
    # the first grab starts the task; H1 is let go where it was, the hand goes back to rest
    grab_part(desk, "H1")
    desk.keys(" ")
    desk.wait("H1 let go", lambda s: s["objects"]["H1"]["holder"] == "", 20)
    desk.keys("r")
    freeze_at_ra1_carry(desk)
    for page in (desk, xr):
        page.wait("r1 carries RA1, its cue lit", carrying_ra1_lit, 30)

    cue = next(c for c in scene["cues"] if c["id"] == "target:RA1")
    h1 = desk.part("H1")
    board_color = scene["board"].get("color", "#1f7336")
    for page, view, other in ((desk, "desktop", xr), (xr, "xr", desk)):
        s = page.state()
        assert s["objects"]["RA1"]["holder"] == "r1", "the carry ended before the pictures"
        assert s["cues"]["target:RA1"]["on"], "r1 carries RA1 but its target cue is off"
        img = page.screenshot(f"{view}-carry.png")
        assert found_near(img, page.project(s["objects"]["RA1"]["p"]), desk.part("RA1")["color"], 6)
        h1_at = s["objects"]["H1"]["p"]
        top = [h1_at[0], h1_at[1], h1_at[2] + h1["size"][2] / 2]
        # H1 in its colour, unless a hand is over it (on a loaded machine a page may freeze
        # before the hand that let H1 go is back at rest)
        drawn_hands = page.page.evaluate("window.hrcTest.probes().hands")
        hand_over = any(math.dist(h[:2], h1_at[:2]) < 0.08 for h in drawn_hands)
        assert hand_over or found_near(img, page.project(top), h1["color"], 4), f"{view}: H1"
        # the cue blinks: seen lit and seen unlit within a window (pictures come slowly on a
        # loaded machine; the frames are frozen meanwhile, the blinking goes on)
        cue_px = page.project([cue["position"][0], cue["position"][1], 0.003])
        lit, dark, i = 0, 0, 0
        deadline = time.monotonic() + BLINK_WINDOW_S
        while not (lit and dark) and time.monotonic() < deadline:
            pixel = page.screenshot(f"{view}-carry-{i % 4}.png").getpixel(
                (round(cue_px[0]), round(cue_px[1]))
            )
            lit += looks_like(pixel, cue["color"])
            dark += looks_like(pixel, board_color, 25)
            i += 1
        assert lit and dark, f"{view}: the target cue did not blink ({lit} lit, {dark}) in {i}"
        # r1 at its links (not at its tool, where RA1 is as yellow as r1) and its target cue
        seen = what_is_seen(page, f"{view}-carry-r1", ("robot:r1", "cue:target:RA1"), (other,))
        assert_whole_scene(seen, view, ["r1"], need=("robot:r1", "cue:target:RA1"))
    assert not desk.errors and not xr.errors, (desk.errors, xr.errors)
