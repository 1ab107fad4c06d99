"""The participant's page under safety_policy = "ssm" (docs/safety-ssm.md), in headless Debian
chromium against a live trial with every real service: the participant's hand, moved with the
page's own desktop controls, takes H1 (which starts the task) and holds it beside the spot where
r1 will put its part; r1 slows, makes a protective stop before the hand, and the page draws r1's
protective zone red around the arm (the arm still visible in it); the hand places H1 away from
there and goes back to rest, r1 resumes and the task finishes.
The picture is saved as test-output/client/ssm-zone.png.

And the thesis scene from the desktop view, saved as thesis-desktop.png: only the label a
participant needs is shown (their next part's), none overlap; later, a robot's part on its way is
labelled.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hrc.browser import output_dir
from hrc.scenario import Ssm
from hrc.ssm import Zone, protective_distance
from hrc.wire import pb

from .conftest import ROOT, wait_until
from .participant_page import (
    VIEWPORT,
    Live,
    Page,
    browser,
    freeze_in,
    grab_part,
    live,
    metrics,
    names_over_targets,
    overlap,
    place_part,
    rendered_frames,
)
from .test_participant_client import hex_rgb, looks_like
from hrc_human_input.stream import ClientView, WorldMirror, frame_json

__all__ = ["browser", "live"]  # the fixtures, shared with test_participant_client


# One transport arm with one part (as tests/test_ssm_run.py) and one part of the participant's,
# H1, lying 6 cm in front of RA1's target: the first grab starts the task, then r1 takes RA1
# from its table to the board, where the participant's hand holds H1.
SCENARIO = """
[scenario]
name = "ssm-zone"
tick_hz = 240
seed = 1
stall_timeout_s = 60

[participant]
name = "P00"
input = "vr"

[conditions]
safety_policy = "ssm"

[robots.r1]
role = "transport"
urdf = "robots/arm5.urdf"
base = { xyz = [0.45, 0.55, 0.0], yaw = 180 }
max_tcp_speed = 0.3
home = [0.35, 0.30, 0.35]
intermediate = [0.20, 0.25, 0.25]
retreat = [0.45, 0.45, 0.40]

[[parts]]
id = "H1"
owner = "human"
size = [0.04, 0.04, 0.04]
start = { xyz = [0.04, 0.10, 0.02], yaw = 0 }
target = { xyz = [-0.22, -0.12, 0.02], yaw = 0 }

[[parts]]
id = "RA1"
owner = "r1"
size = [0.04, 0.04, 0.06]
start = { xyz = [0.66, 0.30, 0.03], yaw = 0 }
target = { xyz = [0.04, 0.16, 0.03], yaw = 0 }

[sequence]
human = ["H1"]
r1 = ["RA1"]

[workspace]
envelope = [{ min = [-0.35, -0.25, -0.05], max = [0.35, 0.25, 0.50] }]
"""


def ssm_scenario(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "robots").symlink_to(ROOT / "robots")
    path = folder / "ssm-zone.toml"
    path.write_text(SCENARIO)
    return path


def toward(before: tuple[int, ...], after: tuple[int, ...], color: str) -> float | None:
    """How well the change of a pixel points at `color` (cosine, 1 = straight at it); None if
    the pixel hardly changed or already had that colour."""
    d = [a - b for a, b in zip(after, before, strict=True)]
    want = [c - b for c, b in zip(hex_rgb(color), before, strict=True)]
    nd, nw = math.hypot(*d), math.hypot(*want)
    if nd < 8 or nw < 8:
        return None
    return sum(x * y for x, y in zip(d, want, strict=True)) / (nd * nw)


def robot_state(speed: float, scale: float | None) -> pb.RobotState:
    st = pb.RobotState(robot="r1", tcp_speed=speed, joint_names=["j"], joint_positions=[0.0])
    if scale is not None:
        st.speed_scale = scale
    return st


def test_frames_carry_the_zone_on_change_with_hrc_ssm_numbers() -> None:
    params = Ssm()
    mirror = WorldMirror({"r1": ["j"]}, {}, {"r1": Zone(params)})
    view = ClientView()

    def frame() -> dict[str, Any]:
        snap, _events = mirror.snapshot(1, 0.0, None)
        return json.loads(frame_json(view, snap, 0))  # type: ignore[no-any-return]

    mirror.on_robot_state(robot_state(0.4, None))
    z = frame()["zones"]["r1"]
    assert z["state"] == "normal"
    assert z["radius"] == pytest.approx(protective_distance(params, 0.4), abs=0.005)
    assert "zones" not in frame()  # unchanged: not sent again
    mirror.on_robot_state(robot_state(0.401, 0.8))  # slowed; the radius within its centimetre
    assert frame()["zones"]["r1"]["state"] == "reduced"
    mirror.on_task_event(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_PROTECTIVE_STOP, robot="r1"))
    mirror.on_robot_state(robot_state(0.0, 0.0))
    z = frame()["zones"]["r1"]
    assert z["state"] == "stopped"
    assert z["radius"] == pytest.approx(protective_distance(params, 0.0), abs=0.005)
    mirror.on_task_event(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_PROTECTIVE_RESUME, robot="r1"))
    assert frame()["zones"]["r1"]["state"] == "reduced"
    # another policy: no zones, frames as before
    plain = WorldMirror({"r1": ["j"]}, {})
    plain.on_robot_state(robot_state(0.4, None))
    snap, _ = plain.snapshot(1, 0.0, None)
    assert "zones" not in json.loads(frame_json(ClientView(), snap, 0))


@pytest.mark.slow
@pytest.mark.e2e
def test_the_page_draws_r1s_zone_red_when_the_hand_stops_it(
    browser: Any, live: Callable[..., Live], tmp_path: Path
) -> None:
    run = live(ssm_scenario(tmp_path / "scenario"))
    trial = run.trial
    page = Page(browser, run.url + "&mode=desktop")
    scene = page.scene()
    assert scene["safety_policy"] == "ssm"
    style = scene["ssm_zone"]
    robot = next(r for r in scene["robots"] if r["id"] == "r1")
    page.wait("r1's zone", lambda s: s["robots"]["r1"]["zone"] is not None, 20)
    first = page.state()["robots"]["r1"]["zone"]
    assert first["state"] in ("normal", "reduced") and 0.1 < first["radius"] < 1.5, first

    # the right hand takes H1 (the task starts) and holds it up, beside RA1's target
    grab_part(page, "H1")
    page.wait("task started", lambda s: s["run"] == "running", 10)
    page.height_to(0.10)
    s = freeze_in(page, "r1 stopped", lambda s: s["robots"]["r1"]["zone"]["state"] == "stopped", 90)
    zone = s["robots"]["r1"]["zone"]
    tcp = s["robots"]["r1"]["tcp"]
    rendered_frames(page)  # the state on screen (the page draws a few frames a second)
    with_zone = page.screenshot("ssm-zone.png")
    page.page.evaluate("window.hrcTest.showZones(false)")
    rendered_frames(page)
    without = page.screenshot("ssm-zone-hidden.png")
    page.page.evaluate("window.hrcTest.showZones(true)")

    # pixels around the tool, half a radius away in the board's plane and above: the zone
    # tints them towards its stopped colour (red), not towards normal or reduced
    red = style["colors"]["stopped"]
    scores: list[float] = []
    for k in range(12):
        a = 2 * math.pi * k / 12
        off = 0.5 * zone["radius"]
        for p in (
            [tcp[0] + off * math.cos(a), tcp[1] + off * math.sin(a), tcp[2]],
            [tcp[0] + off * math.cos(a), tcp[1], tcp[2] + off * math.sin(a)],
        ):
            x, y = page.project(p)
            if not (0 <= x < with_zone.width and 0 <= y < with_zone.height):
                continue
            px = (round(x), round(y))
            score = toward(without.getpixel(px), with_zone.getpixel(px), red)
            if score is not None:
                scores.append(score)
    assert len(scores) >= 12, f"the zone changed too few pixels near r1's tool: {scores}"
    assert sorted(scores)[len(scores) // 2] > 0.9, f"not tinted red near r1: {scores}"
    # the arm stays visible in its zone: its colour at the tool
    tcp_px = page.project(tcp)
    r = 14
    assert any(
        looks_like(with_zone.getpixel((x, y)), robot["color"], 14)
        for x in range(round(tcp_px[0]) - r, round(tcp_px[0]) + r, 2)
        for y in range(round(tcp_px[1]) - r, round(tcp_px[1]) + r, 2)
    ), "r1 is hidden by its zone"

    # the hand puts H1 away and rests: r1 resumes by itself and finishes
    page.page.evaluate("window.hrcTest.freeze(false)")
    place_part(page, "H1")
    page.wait("r1 resumed", lambda s: s["robots"]["r1"]["zone"]["state"] != "stopped", 30)
    page.wait("task finished", lambda s: s["run"] == "finished", 120)
    rc, out, err = trial.communicate(timeout=60)
    assert rc == 0, (out, err[-3000:])
    assert metrics(trial)["task"]["finished"] is True
    kinds = [
        json.loads(line).get("kind")
        for line in (trial.out / "events.jsonl").read_text().splitlines()
    ]
    assert "PROTECTIVE_STOP" in kinds and "PROTECTIVE_RESUME" in kinds, kinds
    assert "COLLISION" not in kinds, "the hand touched r1"
    assert not page.errors, page.errors
    assert (output_dir("client") / "ssm-zone.png").is_file()


@pytest.mark.slow
@pytest.mark.e2e
def test_the_thesis_scene_on_the_desktop_has_readable_part_labels(
    browser: Any, live: Callable[..., Live]
) -> None:
    page = Page(browser, live(ROOT / "scenarios" / "thesis.toml").url + "&mode=desktop")
    page.wait("the parts' state", lambda s: "H1" in s["objects"], 20)
    rendered_frames(page)  # (labels show or hide with the frames drawn after the state came)
    labels = page.page.evaluate("window.hrcTest.labels()")
    page.screenshot("thesis-desktop.png")
    shown = {lab["part"] for lab in labels if "part" in lab}
    # the participant's next part is labelled; the others lie on tables, unlabelled (yet)
    assert shown == {"H1"}, labels
    # each of the participant's targets is named (none placed yet), clear of its outline
    named = {lab["target"] for lab in labels if "target" in lab}
    assert named == {"H1", "H2", "H3", "H4", "H5", "H6"}, labels
    assert not names_over_targets(page)
    clashes = [
        (a["text"], b["text"])
        for i, a in enumerate(labels)
        for b in labels[i + 1 :]
        if overlap(a, b)
    ]
    assert not clashes, f"overlapping labels: {clashes}"

    # a robot's "Waiting for you: ..." label stands high above its base, where the page's status
    # panel is: it comes down clear of it (it hid behind it), and stays in the view
    text = "Waiting for you: H2, H5"
    for rid in ("r1", "r2"):
        page.page.evaluate("([r, t]) => window.hrcTest.showWaiting(r, t)", [rid, text])
    seen: dict[str, Any] = {}

    def clear() -> bool:
        seen["boxes"] = page.page.evaluate("window.hrcTest.boxes()")
        seen["waiting"] = [
            lab for lab in page.page.evaluate("window.hrcTest.labels()") if lab.get("cue")
        ]
        return (
            len(seen["waiting"]) == 2
            and all(w["text"] == text for w in seen["waiting"])
            and not any(overlap(w, b) for w in seen["waiting"] for b in seen["boxes"].values())
        )

    assert "status" in page.page.evaluate("window.hrcTest.boxes()")
    assert wait_until(clear, 20), f"a waiting label under a box of the page: {seen}"
    for w in seen["waiting"]:
        assert w["x0"] >= 0 and w["y0"] >= 0 and w["x1"] <= VIEWPORT["width"], seen
    rendered_frames(page)
    page.screenshot("thesis-desktop-waiting.png")
    for rid in ("r1", "r2"):
        page.page.evaluate("(r) => window.hrcTest.showWaiting(r, null)", rid)

    # the task starts with H1 taken; r1 brings RA1: that label is shown on its way
    grab_part(page, "H1")
    page.wait("r1 carries RA1", lambda s: s["objects"]["RA1"]["holder"] == "r1", 60)
    page.page.evaluate("window.hrcTest.freeze(true)")
    labels = page.page.evaluate("window.hrcTest.labels()")
    page.screenshot("thesis-desktop-carry.png")
    assert {"H1", "RA1"} <= {lab.get("part") for lab in labels}, labels
    assert not page.errors, page.errors
