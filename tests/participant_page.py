"""The participant's page in headless Debian chromium against a live trial, driven like a
person would (shared by the browser tests): the browser, a live trial (`hrc run --input vr`),
the page and its test hooks (window.hrcTest), and the moves of a person at a desktop.

World points are turned into page pixels by the page itself (window.hrcTest.project), and every
position comes from the scene the bridge sent: nothing of the scenario is repeated here.
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
import time
import urllib.request
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from hrc.browser import headless_chromium, output_dir

from .conftest import ROOT, Trial, free_port, wait_until
from .goldens import MINIMAL

log = logging.getLogger(__name__)

CLIENT_DIST = ROOT / "services" / "human_input" / "client" / "dist" / "index.html"
VIEWPORT = {"width": 1280, "height": 800}
# The pages outside a headset draw at most this many frames a second (the client's `fps`): in
# software WebGL a page takes a core for 7-10 frames a second, and the tests wait for the frames
# they need (rendered_frames). 5 took a fifth of the live tests' CPU and 11 % of their time
# (1,333 -> 1,071 CPU-s, 742 -> 659 s); HRC_TEST_FPS=0 draws every frame.
PAGE_FPS = int(os.environ.get("HRC_TEST_FPS", "5"))
# The client's `scale` for a test that checks no picture of the scene (Page's `scale`): its 3D
# view at a quarter of the window's resolution halves a page's CPU in software WebGL; the panel,
# messages and screens are the page's own text, as sharp as ever.
NO_PICTURE_SCALE = 0.25
MAX_TICKS = 240 * 240  # no trial outlives 4 simulated (= wall, realtime) minutes
DRIVER_KEY = "participant-key"
# For the page to take the mouse's moves (it does so with its frames; software WebGL on a loaded
# machine draws a few a second). Once on CI a hand stopped part-way to where the mouse went, for
# 10 s (not understood): a person would move the mouse again, and the test does, INPUT_TRIES
# times. (A page whose run has ended takes no input at all: the failure's message says so.)
INPUT_WAIT_S = 10
INPUT_TRIES = 3
STALL_TIMEOUT_S = 600  # simulated s: longer than MAX_TICKS, so a slow test never meets it


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    if not CLIENT_DIST.is_file():
        pytest.fail(f"{CLIENT_DIST} is missing: scripts/setup.sh builds the participant client")
    with headless_chromium() as b:
        yield b


@dataclass
class Live:
    trial: Trial
    url: str  # the participant's link (it drives)
    spectator_url: str  # anybody else's (the experimenter's)


OPEN_PAGES: list[Page] = []  # closed after each test: a page left open goes on rendering


@pytest.fixture
def live(trial_factory: Callable[..., Trial]) -> Iterator[Callable[..., Live]]:
    """Starts a live trial (realtime, input vr); returns it and the pages' URLs once the bridge
    serves them. The test's pages are closed after it (software WebGL: every open page renders
    on the CPU the next test needs)."""

    def start(scenario: Path = MINIMAL, max_ticks: int = MAX_TICKS, extra: list[str] = ()) -> Live:
        port = free_port()
        trial = trial_factory(
            scenario,
            ticks=0,
            extra=[
                "--input",
                "vr",
                "--vr-port",
                str(port),
                "--max-ticks",
                str(max_ticks),
                # a robot stuck on its own still ends the trial, but never while a test looks
                "--stall-timeout",
                str(STALL_TIMEOUT_S),
                *extra,
            ],
            env={"HRC_VR_DRIVER": DRIVER_KEY},
        )
        url = f"http://127.0.0.1:{port}/"

        def serving() -> bool:
            if trial.proc.poll() is not None:
                raise AssertionError(f"hrc run ended early: {trial.communicate()}")
            try:
                with urllib.request.urlopen(url, timeout=1) as r:
                    return r.status == 200
            except OSError:
                return False

        assert wait_until(serving, 60, 0.2), "the bridge never served the page"
        return Live(trial, f"{url}?driver={DRIVER_KEY}", url)

    yield start
    while OPEN_PAGES:
        OPEN_PAGES.pop().close()


def with_query(url: str, query: str) -> str:
    return url + ("&" if "?" in url else "?") + query


class Page:
    """The page and its test hooks (window.hrcTest), driven like a person would."""

    def __init__(self, browser: Any, url: str, ready: bool = True, scale: float = 1.0) -> None:
        """``ready``: wait for the world on the page (a spectator who comes before the
        participant sees it only once the trial runs). The page loads its test hooks only
        with ``test=`` in its URL (``test=iwer`` too): ``test=hooks`` is added otherwise.
        ``scale``: the client's ``scale`` (the 3D view's resolution against the window's, outside
        a headset), for a test that checks no picture of the scene: at 0.25 a page takes half
        the CPU (software WebGL), and its panel and messages stay as sharp."""
        if "test=" not in url:
            url = with_query(url, "test=hooks")
        if PAGE_FPS and "fps=" not in url:
            url = with_query(url, f"fps={PAGE_FPS}")
        if scale != 1.0:
            url = with_query(url, f"scale={scale:g}")
        self.context = browser.new_context(viewport=VIEWPORT)
        self.page = self.context.new_page()
        self.errors: list[str] = []
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        OPEN_PAGES.append(self)
        self.page.goto(url)
        if ready:
            self.wait_ready()

    def wait_ready(self) -> None:
        # generous: on a loaded machine software WebGL renders a frame or two a second
        self.page.wait_for_function("window.hrcTest && window.hrcTest.ready()", timeout=90_000)
        assert not self.errors, self.errors

    def state(self) -> dict[str, Any]:
        return self.page.evaluate("window.hrcTest.state()")  # type: ignore[no-any-return]

    def text(self) -> dict[str, str]:
        """What the person reads: the status panel and the message."""
        return self.page.evaluate(  # type: ignore[no-any-return]
            """() => ({
                status: document.getElementById('status').textContent,
                message: document.getElementById('message').style.display === 'none'
                    ? '' : document.getElementById('message').textContent,
            })"""
        )

    def scene(self) -> dict[str, Any]:
        return self.page.evaluate("window.hrcApp.sceneMsg")  # type: ignore[no-any-return]

    def part(self, pid: str) -> dict[str, Any]:
        return next(p for p in self.scene()["parts"] if p["id"] == pid)

    def project(self, xyz: list[float]) -> tuple[float, float]:
        p = self.page.evaluate("(xyz) => window.hrcTest.project(xyz)", xyz)
        return p["x"], p["y"]

    def wait(self, what: str, pred: Callable[[dict[str, Any]], bool], timeout: float) -> None:
        ok = wait_until(lambda: pred(self.state()), timeout, 0.1)
        assert ok, f"{what}: not within {timeout:g} s; page state {json.dumps(self.state())[:1500]}"

    def wait_text(self, what: str, pred: Callable[[dict[str, str]], bool], timeout: float) -> None:
        ok = wait_until(lambda: pred(self.text()), timeout, 0.05)
        assert ok, f"{what}: not within {timeout:g} s; the page says {self.text()}"

    def keys(self, key: str, n: int = 1) -> None:
        for _ in range(n):
            self.page.keyboard.press(key)

    def hand(self) -> dict[str, Any]:
        s = self.state()
        return s["hands"][s["active_hand"]]  # type: ignore[no-any-return]

    def height_to(self, z: float) -> None:
        """W/S move the active hand 1 cm up/down."""
        steps = round((z - self.hand()["p"][2]) / 0.01)
        self.keys("w" if steps > 0 else "s", abs(steps))
        assert abs(self.hand()["p"][2] - z) < 0.006, self.hand()

    def move_over(self, x: float, y: float) -> None:
        """The mouse moves the hand on the plane at its height: point at (x, y, hand z). A
        hand at rest is first taken back with a deliberate move of the mouse."""
        if self.state()["parked"]:
            self.take_hand()
        z = self.hand()["p"][2]
        px, py = self.project([x, y, z])

        def there() -> bool:  # a busy page may handle the last (coalesced) move a frame later
            p = self.hand()["p"]
            return abs(p[0] - x) < 0.004 and abs(p[1] - y) < 0.004

        for attempt in range(INPUT_TRIES):
            if attempt:  # a person whose hand did not follow moves the mouse again
                log.warning(
                    "the hand did not follow to (%g, %g): again (%s)",
                    x,
                    y,
                    self.pointer_state(px, py),
                )
                self.page.mouse.move(px, py + 10, steps=2)
            self.page.mouse.move(px, py, steps=12)
            if wait_until(there, INPUT_WAIT_S, 0.05):
                return
        raise AssertionError(
            f"the hand at {self.hand()['p']} after {INPUT_TRIES} moves of the mouse to "
            f"({x}, {y}); {self.frames()}"
        )

    def pointer_to_hand(self) -> None:
        """The mouse onto the hand's pixel, in one move. After a placement the mouse is still
        over the board while the page has taken the hand back to rest; the page puts a hand
        it takes again where the mouse points, so a person first brings the mouse to the hand
        (else the hand jumps back over the board, where a robot may now be)."""
        px, py = self.project(self.hand()["p"])
        self.page.mouse.move(px, py)

    def take_hand(self) -> None:
        """A parked hand follows the mouse again once it has moved on purpose."""
        rest = self.hand()["p"]
        px, py = self.project(rest)
        for attempt in range(INPUT_TRIES):
            if attempt:  # the hand stayed at rest: the person moves the mouse again
                log.warning("the hand stayed at rest: again (%s)", self.pointer_state(px, py))
            self.page.mouse.move(px, py - 120, steps=4)  # up: the rest point is near the bottom
            self.page.mouse.move(px, py, steps=4)
            if wait_until(lambda: not self.state()["parked"], INPUT_WAIT_S, 0.05):
                return
        raise AssertionError(
            f"the hand stays parked after {INPUT_TRIES} deliberate moves of the mouse "
            f"({self.frames()}); {self.pointer_state(px, py)}"
        )

    def pointer_state(self, px: float, py: float) -> str:
        """What the page knows of the mouse, and what lies under (px, py) and 120 px above it
        (for a failure's message)."""
        return (
            json.dumps(
                self.page.evaluate(
                    """([x, y]) => ({
                    parked: window.hrcApp.desktop.parked,
                    last: window.hrcApp.desktop.lastPointer,
                    at: document.elementFromPoint(x, y)?.id,
                    above: document.elementFromPoint(x, y - 120)?.id,
                    enabled: window.hrcApp.desktop.enabled,
                    role: window.hrcApp.role,
                })""",
                    [px, py],
                )
            )
            + f" (the mouse at {px:.0f}, {py:.0f})"
        )

    def frames(self) -> str:
        """How fast the page draws, and how often the bridge's frames come (for a failure's
        message)."""
        count = "() => [window.hrcApp.rendered, window.hrcApp.frames]"
        d0, b0 = self.page.evaluate(count)
        time.sleep(2)
        d1, b1 = self.page.evaluate(count)
        return f"in 2 s the page drew {d1 - d0} frame(s) and had {b1 - b0} from the bridge"

    def screenshot(self, name: str) -> Any:
        from PIL import Image

        png = self.page.screenshot()
        (output_dir("client") / name).write_bytes(png)
        return Image.open(io.BytesIO(png)).convert("RGB")

    def close(self) -> None:
        if self in OPEN_PAGES:
            OPEN_PAGES.remove(self)
        self.context.close()


def freeze_at_ra1_carry(page: Page) -> None:
    """The page stops applying frames at the first one in which r1 holds RA1 with its target
    cue lit (:func:`carrying_ra1_lit` then holds; the hold comes from physics, the cue from the
    orchestrator, on two threads of the bridge: a frame may show the one before the other)."""
    page.page.evaluate("window.hrcTest.freezeWhen('RA1', 'r1', 'target:RA1')")


def freeze_in(
    page: Page, what: str, pred: Callable[[dict[str, Any]], bool], timeout: float
) -> dict[str, Any]:
    """Holds the page still (window.hrcTest.freeze) on a frame in which `pred` holds, and
    returns that frame's state: a state seen before the freeze may be gone by the frame the
    picture shows (a protective stop lasts a few frames when the arm moves away)."""
    deadline = time.monotonic() + timeout
    while True:
        page.wait(what, pred, max(0.1, deadline - time.monotonic()))
        page.page.evaluate("window.hrcTest.freeze(true)")
        state = page.state()  # the frame on screen: later frames wait
        if pred(state):
            return state
        page.page.evaluate("window.hrcTest.freeze(false)")


def carrying_ra1_lit(s: dict[str, Any]) -> bool:
    """r1 holds RA1 and its target cue is lit: the moment :func:`freeze_at_ra1_carry` holds a
    page at."""
    return bool(s["objects"]["RA1"]["holder"] == "r1" and s["cues"]["target:RA1"]["on"])


def grab_part(page: Page, pid: str, timeout: float = 20) -> None:
    """Hand over the part, down to its top face, close the grip; the bridge reports the hold."""
    part = page.part(pid)
    at = page.state()["objects"][pid]["p"]
    x, y, z = at
    top = z + part["size"][2] / 2
    if page.state()["parked"]:  # (a key below takes the hand: the mouse must be at it)
        page.pointer_to_hand()
    page.height_to(max(top + 0.06, 0.10))
    page.move_over(x, y)
    page.height_to(top)
    page.keys(" ")
    page.wait(f"{pid} held", lambda s: s["objects"][pid]["holder"] in ("left", "right"), timeout)


def controller_to(page: Page, xyz: list[float], side: str = "right") -> None:
    """The emulated controller at a world point (through the page's calibration), level."""
    xr = page.page.evaluate("(p) => window.hrcTest.worldToXr(p)", xyz)
    page.page.evaluate(
        """([side, x, y, z]) => {
            const c = window.hrcXrDevice.controllers[side];
            c.position.set(x, y, z);
            c.quaternion.set(0, 0, 0, 1);
        }""",
        [side, *xr],
    )


def squeeze(page: Page, v: float, side: str = "right") -> None:
    page.page.evaluate(
        "([s, v]) => window.hrcXrDevice.controllers[s].updateButtonValue('squeeze', v)", [side, v]
    )


def controller_places(page: Page, pid: str) -> None:
    """The right controller takes `pid` (over it, down, squeeze) and puts it on its target
    (over, down, let go), then moves away so that the robots can finish."""
    part = page.part(pid)
    x, y, z = page.state()["objects"][pid]["p"]
    top = z + part["size"][2] / 2
    tx, ty, tz = part["target"]["xyz"]
    ttop = tz + part["size"][2] / 2
    controller_to(page, [x, y, top + 0.08])
    page.wait("right hand tracked", lambda s: abs(s["hands"]["right"]["p"][0] - x) < 0.005, 10)
    controller_to(page, [x, y, top])
    rendered_frames(page, 1)  # the page reads (and sends) the controller at its next frame
    squeeze(page, 1.0)
    page.wait(f"{pid} held", lambda s: s["objects"][pid]["holder"] == "right", 20)
    for xyz in ([x, y, top + 0.08], [tx, ty, ttop + 0.08], [tx, ty, ttop]):
        controller_to(page, xyz)
        rendered_frames(page, 1)
    squeeze(page, 0.0)
    page.wait(f"{pid} placed", lambda s: f"part_placed:{pid}" in s["events"], 20)
    controller_to(page, [x - 0.4, y - 0.2, top + 0.1])


def yaw_deg(q: list[float]) -> float:
    """The yaw of a quaternion [x, y, z, w] (about the world's z, the page's root frame)."""
    x, y, z, w = q
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def placed(state: dict[str, Any], pid: str) -> bool:
    """The page knows the part placed: from its objects, or from the placement's event, which
    comes before the frame whose objects say so."""
    return bool(state["objects"][pid]["placed"]) or f"part_placed:{pid}" in state["events"]


def place_part(page: Page, pid: str) -> None:
    """Turned to the target's yaw (Q/E, 15 degrees a press), over the target, down, open the
    grip: placed; the page then takes the hand back to rest (it parks after a release)."""
    part = page.part(pid)
    x, y, z = part["target"]["xyz"]
    top = z + part["size"][2] / 2
    turn = (part["target"]["yaw_deg"] - yaw_deg(page.state()["objects"][pid]["q"])) % 360
    turn = turn - 360 if turn > 180 else turn
    page.keys("q" if turn > 0 else "e", round(abs(turn) / 15))
    page.height_to(max(top + 0.06, 0.10))
    page.move_over(x, y)
    page.height_to(top)
    page.keys(" ")
    # (the task's last placement ends the trial: a page that misses the last frame before the
    # bridge closes knows it from the event or the end, which needs every part placed)
    page.wait(f"{pid} placed", lambda s: placed(s, pid) or s["run"] == "finished", 20)
    page.wait("the hand back at rest", lambda s: s["parked"], 10)


# ---------------------------------------------------------------- what a person sees

PROBE_R = 3  # px: the window around a probe point compared with the thing hidden
PROBE_MIN_PIXELS = 5  # of its 49 pixels that must change for the thing to count as seen
PIXEL_DIFF = 30  # |dR| + |dG| + |dB| above this: the pixel changed (grey on grey: ~40)


# things seen at every probe point (assert_whole_scene); the others at some of them
EVERY_POINT = ("robot:", "cue:target", "hands")


def under_a_label(px: tuple[float, float], labels: list[dict[str, Any]]) -> bool:
    """The probe window around page pixel ``px`` touches a label's box (hrcTest.labels())."""
    r = PROBE_R
    win = {"x0": px[0] - r, "y0": px[1] - r, "x1": px[0] + r + 1, "y1": px[1] + r + 1}
    return any(overlap(win, lab) for lab in labels)


def names_over_targets(page: Page) -> list[str]:
    """The participant's target names (hrcTest.labels()) that lie over their own target: its
    cue's footprint (1.3 x the part, where a robot's cue on it lies too), its middle, corners
    and edges' middles as the page draws them. A name is drawn over everything."""
    names = [lab for lab in page.page.evaluate("window.hrcTest.labels()") if "target" in lab]
    parts = {p["id"]: p for p in page.scene()["parts"]}
    points = []  # (label, world xy)
    for lab in names:
        part = parts[lab["target"]]
        (x, y, _), yaw = part["target"]["xyz"], math.radians(part["target"].get("yaw_deg", 0))
        hx, hy = 0.65 * part["size"][0], 0.65 * part["size"][1]
        c, s = math.cos(yaw), math.sin(yaw)
        for a, b in ((a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)):
            dx, dy = a * hx, b * hy
            points.append((lab, [x + dx * c - dy * s, y + dx * s + dy * c]))
    # in one page call: a call a point costs seconds on a headset's page busy rendering
    pixels = page.page.evaluate(
        "(ps) => ps.map((p) => { const q = window.hrcTest.project(p); return [q.x, q.y]; })",
        [[*xy, 0.003] for _, xy in points],
    )
    return [
        f"{lab['target']}'s name over its target at {xy} (px {px})"
        for (lab, xy), px in zip(points, pixels, strict=True)
        if lab["x0"] < px[0] < lab["x1"] and lab["y0"] < px[1] < lab["y1"]
    ]


def overlap(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Two rectangles {x0, y0, x1, y1} (page pixels) overlap."""
    return a["x0"] < b["x1"] and b["x0"] < a["x1"] and a["y0"] < b["y1"] and b["y0"] < a["y1"]


def rendered_frames(page: Page, n: int = 2) -> None:
    """Waits until the page has rendered ``n`` more frames (a change is then on screen)."""
    n0 = page.page.evaluate("window.hrcTest.rendered()")
    page.page.wait_for_function(
        "n => window.hrcTest.rendered() >= n", arg=n0 + n, timeout=90_000, polling=50
    )


def changed_pixels(a: Any, b: Any, xy: tuple[float, float], r: int = PROBE_R) -> int:
    x0, y0 = round(xy[0]), round(xy[1])
    w, h = a.size
    n = 0
    for x in range(max(0, x0 - r), min(w, x0 + r + 1)):
        for y in range(max(0, y0 - r), min(h, y0 + r + 1)):
            pa, pb = a.getpixel((x, y)), b.getpixel((x, y))
            n += sum(abs(u - v) for u, v in zip(pa, pb, strict=True)) > PIXEL_DIFF
    return n


@dataclass
class Seen:
    """How many of a thing's probe points the person sees (and where the others were)."""

    seen: int
    total: int
    misses: list[str]
    under_labels: int = 0  # points left out: a label (drawn over everything) lay over them


def what_is_seen(
    page: Page,
    view: str,
    only: tuple[str, ...] = (),
    others: tuple[Page, ...] = (),
    hold_scene: bool = False,
) -> dict[str, Seen]:
    """For each thing the page names (board, each robot's links, parts, hands, lit cues, the
    status panel): a picture with everything, then one with that thing hidden
    (window.hrcTest.hide); the thing is seen at a probe point where the two pictures differ.
    Colours play no part, so a part in its robot's colour cannot stand in for the robot. A
    point of a thing to be seen at every point (EVERY_POINT) that lies under a label (drawn
    over everything) is left out and counted in ``Seen.under_labels``; a cue's or a robot's point
    not seen is looked at once more with what moves in front of it hidden (_may_lie_in_front).

    The picture is held still meanwhile (frames frozen, cues held lit); the ``others`` pages
    stop rendering meanwhile (software WebGL: the CPU goes to the page looked at). Pictures are
    saved as test-output/client/<view>.png (everything) and <view>-without-<thing>.png.
    ``hold_scene``: the page's frames stay held afterwards (its panel live), so that a next view
    of the same page (after a calibration) shows the same moment, whatever the time it took."""
    for other in others:
        other.page.evaluate("window.hrcTest.pause(true)")
    try:
        return _what_is_seen(page, view, only, hold_scene)
    finally:
        for other in others:
            other.page.evaluate("window.hrcTest.pause(false)")
        # ... and have drawn again: a paused page in an emulated headset shows an empty picture
        # (IWER clears it at each of its frames) until its next drawn frame
        for other in others:
            rendered_frames(other, 1)


def _what_is_seen(
    page: Page, view: str, only: tuple[str, ...], hold_scene: bool
) -> dict[str, Seen]:
    t0 = time.monotonic()
    page.wait("the headset's panel in place", lambda s: not s["panel_moving"], 30)
    page.page.evaluate("window.hrcTest.freeze(true); window.hrcTest.flash(true)")
    rendered_frames(page)
    full = page.screenshot(f"{view}.png")
    probes: dict[str, list[list[float]]] = page.page.evaluate("window.hrcTest.probes()")
    # every probe point's pixel in one page call (the picture is frozen: they stay where they
    # are; a call a point cost a headset view about 10 s on a page busy rendering)
    projected: dict[str, list[list[float]]] = page.page.evaluate(
        """(probes) => Object.fromEntries(Object.entries(probes).map(([name, points]) => [
            name, points.map((p) => { const q = window.hrcTest.project(p); return [q.x, q.y]; }),
        ]))""",
        probes,
    )
    status_box = page.page.evaluate(
        """() => {
            const r = document.getElementById('status').getBoundingClientRect();
            return r.width > 0 ? [r.left + r.width / 2, r.top + r.height / 2] : null;
        }"""
    )
    # the labels are drawn over everything: a point of a thing behind one shows the label, not
    # the thing (a carried part's label may lie over its robot's base), so such a point of a
    # thing seen at every point is left out (it must still be seen at one point at least)
    labels: list[dict[str, Any]] = page.page.evaluate("window.hrcTest.labels()")
    in_xr = page.state()["xr"]
    out: dict[str, Seen] = {}
    for name in sorted(probes.keys() | ({"panel"} if status_box and not in_xr else set())):
        if only and not any(name == o or name.startswith(o + ":") for o in only):
            continue
        points = probes.get(name, [])
        pixels = [(px[0], px[1]) for px in projected.get(name, [])]
        if name == "panel" and not in_xr:
            pixels = [(status_box[0], status_box[1])]
        hide(page, [name], True)
        # One frame: the page draws on the thread that ran the hide, so the next frame drawn is
        # without the thing, and a screenshot shows the last one drawn (in an emulated headset
        # too: IWER draws its layer onto the page within the frame). Waiting for two took the
        # headset view test 98 s instead of 54. (A stale picture would fail the thing as unseen.)
        rendered_frames(page, 1)
        without = page.screenshot(f"{view}-without-{name.replace(':', '-')}.png")
        hide(page, [name], False)
        log.info("%s: %s probed (%.1f s so far)", view, name, time.monotonic() - t0)
        misses = []
        covered = []
        unseen = []  # (point, px, pixels changed)
        for point, px in zip(points or [None], pixels, strict=True):
            if name.startswith(EVERY_POINT) and under_a_label(px, labels):
                covered.append(px)
                continue
            n = changed_pixels(full, without, px)
            if n < PROBE_MIN_PIXELS:
                unseen.append((point, px, n))
        in_front = _may_lie_in_front(name, probes)
        if unseen and in_front:
            unseen = _seen_with_hidden(page, view, name, in_front, unseen)
        for point, px, n in unseen:
            misses.append(f"{point} at px ({px[0]:.0f}, {px[1]:.0f}): {n} pixels change")
        if covered:
            log.info("%s: %s: %d point(s) under a label left out", view, name, len(covered))
        total = len(pixels) - len(covered)
        out[name] = Seen(total - len(misses), total, misses, len(covered))
    rendered_frames(page)
    page.page.evaluate(
        "(hold) => { window.hrcTest.flash(null); window.hrcTest.freeze(hold ? 'scene' : false); }",
        hold_scene,
    )
    return out


def hide(page: Page, names: list[str], on: bool) -> None:
    """Hides (or shows again) the named things for a picture (window.hrcTest.hide), in one page
    call: each call waits for a page busy rendering."""
    page.page.evaluate("([ns, on]) => ns.forEach((n) => window.hrcTest.hide(n, on))", [names, on])


def _may_lie_in_front(name: str, probes: dict[str, list[list[float]]]) -> list[str]:
    """The things that move and may lie between the eye and thing ``name`` at the moment of the
    picture: for a cue, the other cues (cues lie on one another where a part goes onto another:
    a screw's hole on a part whose own target cue is lit while the person still holds it, S1 on
    H1); for a robot, the parts (a part it carries passes between the participant's eye and its
    base: r1's base unseen once, 0 pixels changing, in a driver's view on a loaded machine).
    Still things (board, panel, furniture) are never hidden for a second look: one of them in
    front of a thing is what the check is for."""
    if name.startswith("cue:"):
        return [n for n in probes if n.startswith("cue:") and n != name]
    if name.startswith("robot:"):
        return ["parts"]
    return []


def _seen_with_hidden(
    page: Page,
    view: str,
    name: str,
    hidden: list[str],
    unseen: list[tuple[Any, tuple[float, float], int]],
) -> list[tuple[Any, tuple[float, float], int]]:
    """The points of ``name`` not seen at first, looked at again with the things ``hidden``
    hidden (_may_lie_in_front). Returns the points still unseen."""
    hide(page, hidden, True)
    try:
        rendered_frames(page, 1)
        alone = page.screenshot(f"{view}-only-{name.replace(':', '-')}.png")
        hide(page, [name], True)
        rendered_frames(page, 1)
        without = page.screenshot(f"{view}-only-{name.replace(':', '-')}-hidden.png")
        hide(page, [name], False)
    finally:
        hide(page, hidden, False)
    still = [
        (pt, px, n) for pt, px, n in unseen if changed_pixels(alone, without, px) < PROBE_MIN_PIXELS
    ]
    if len(still) < len(unseen):
        log.info(
            "%s: %s: %d point(s) seen once %s were hidden",
            view,
            name,
            len(unseen) - len(still),
            ", ".join(hidden),
        )
    return still


def assert_whole_scene(
    seen: dict[str, Seen], view: str, robots: list[str], need: tuple[str, ...] = ()
) -> None:
    """Board, every robot at its base, middle and wrist, the parts, the hands, the lit cues and
    the status panel are seen (some of the points of the board, the parts, the panel and an
    outline's corners may be covered by a hand, an arm or the part it surrounds); with
    ``need``, only those things."""
    names = need or ("board", "parts", "hands", "panel", *(f"robot:{r}" for r in robots))
    missing = [n for n in names if n not in seen]
    assert not missing, f"{view}: nothing to probe for {missing}"
    assert any(n.startswith("cue:") for n in seen), f"{view}: no cue is lit"
    bad = []
    for name, s in seen.items():
        every = name.startswith(EVERY_POINT)
        enough = s.total if every else 0.4 * s.total
        if s.seen < max(1, enough):
            under = f" ({s.under_labels} more under a label)" if s.under_labels else ""
            bad.append(f"{name}: seen at {s.seen} of {s.total} points{under}; {s.misses}")
    assert not bad, f"{view}: " + "; ".join(bad)


def metrics(trial: Trial) -> dict[str, Any]:
    return json.loads((trial.out / "metrics.json").read_text())  # type: ignore[no-any-return]


def trial_path(trial: Trial, name: str) -> Path:
    return trial.out / name
