"""A study with people (`hrc session`, docs/studies.md "Running a study with people"): a live
participant's session in headless Debian chromium, the desktop page as the participant —
consent, instructions, a practice trial, two trials in the participant's counterbalanced
order, NASA-TLX after each and a Likert item at the end — with the page closed during the
second trial and the session resumed by the same command; then the study's table and report
with these live rows beside the simulated participants. The same session in an emulated
headset (IWER) is answered with the controller's ray.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from .conftest import HRC, ROOT, wait_until
from .goldens import MINIMAL
from .participant_page import (  # noqa: F401  (browser: a fixture)
    NO_PICTURE_SCALE,
    OPEN_PAGES,
    Page,
    browser,
    controller_places,
    grab_part,
    rendered_frames,
)
from .session_page import (
    TLX_ANSWERS,
    Pointer,
    Session,
    answer_questionnaire,
    do_trial,
    form,
    wait_enabled,
    wait_screen,
    widget,
    write_study,
)

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

# no picture of the scene is checked here: the desktop session's pages draw at NO_PICTURE_SCALE
SCALE = NO_PICTURE_SCALE
# two pages: a paragraph over three lines of the file, then enough to fill the first page
LONG_CONSENT = (
    "# Consent\n\nYou take part in a study of **working with robots**: the robots work\n"
    "beside you while you place parts\non a board.\n\n"
    + "".join(f"- Point {i}: what you should know about the study, item {i}.\n" for i in range(9))
    + "\nSome people feel unwell in VR. Tell the experimenter at once if you feel dizzy or "
    "sick:\nthe session stops whenever you want.\n"
)
LIVE = """[live]
participants = ["L01", "L02", "L03"]
order = "williams"
practice = 1
practice_condition = { "conditions.anticipation" = true }
min_break_s = 4
consent = "consent.md"
instructions = "instructions.md"
after_trial = ["tlx"]
end = ["trust"]

[[live.instruction]]
when = { "conditions.anticipation" = true }
file = "cues.md"

[questionnaires.trust]
title = "After the session"
points = 5
anchors = ["strongly disagree", "strongly agree"]
items = [{ id = "safe", text = "I felt safe working beside the robots." }]
"""


@pytest.fixture
def sessions() -> Iterator[list[Session]]:
    started: list[Session] = []
    yield started
    for s in started:
        s.stop()
    while OPEN_PAGES:
        OPEN_PAGES.pop().close()


def shot(page: Page, name: str) -> None:
    page.screenshot(name)


@pytest.mark.timeout(1800)  # four live trials and a sweep, in software WebGL on a loaded machine
def test_a_participant_at_the_desktop_does_a_whole_session_resumed_after_the_page_closed(
    browser: Any,  # noqa: F811
    sessions: list[Session],
    tmp_path: Path,
) -> None:
    study = write_study(tmp_path / "study", LIVE, consent=LONG_CONSENT)
    out = tmp_path / "out"
    # the simulated participants first: the same study folder, the same table
    sweep = subprocess.run(
        [HRC, "sweep", str(study), "--out", str(out), "--workers", "2"],
        capture_output=True, text=True, cwd=ROOT, timeout=600,
    )  # fmt: skip
    assert sweep.returncode == 0, sweep.stderr[-3000:]

    s = Session(study, "L02", out)  # L02: the second row of the square, anticipation off first
    sessions.append(s)
    page = Page(browser, s.url(), ready=False, scale=SCALE)
    mouse = Pointer(page)

    f = wait_screen(page, ("consent",))
    assert "working with robots" in page.page.evaluate("window.hrcApp.form.screen.text")
    # a paragraph is one text, whatever the file's line breaks (they were kept); the first of
    # its two pages ends above "page 1 of 2" (which overlapped its last line)
    text = f["text"]
    assert "study of working with robots: the robots work beside you while you" in " ".join(
        text["lines"]
    ), text
    assert text["pages"] == 2 and text["bottom"] + 8 < text["pageLine"], text
    shot(page, "session-consent.png")
    mouse.press(f, "more")
    f = form(page)
    said = [line for line in f["text"]["lines"] if line]
    assert said[-1].endswith("the session stops whenever you want."), f["text"]
    mouse.press(f, "yes")
    f = wait_screen(page, ("text",), f["id"])
    assert f["title"] == "Instructions"
    shot(page, "session-instructions.png")
    mouse.press(f, "continue")
    # the practice trial is in the condition the file names (anticipation on): its text first
    f = wait_screen(page, ("text",), f["id"])
    assert "show their targets" in page.page.evaluate("window.hrcApp.form.screen.text")
    mouse.press(f, "continue")
    f = wait_screen(page, ("ready",), f["id"])
    assert f["title"] == "Practice 1 of 3", f
    shot(page, "session-ready.png")
    mouse.press(f, "start")
    do_trial(page)
    # no questionnaire after practice: the first trial of L02's order (anticipation off) next,
    # after a break (Start is off until it is over)
    f = wait_screen(page, ("ready",), f["id"])
    assert f["title"] == "Trial 2 of 3", f
    assert widget(f, "start")["disabled"], f
    shot(page, "session-break.png")
    f = wait_enabled(page, "start", 60)
    mouse.press(f, "start")
    do_trial(page)
    f = wait_screen(page, ("questionnaire",), f["id"])
    shot(page, "session-questionnaire-tlx.png")
    answer_questionnaire(page, mouse, TLX_ANSWERS)
    # the second trial (anticipation on: its text again, then ready); the page closes in it
    f = wait_screen(page, ("text",), f["id"])
    mouse.press(f, "continue")
    wait_screen(page, ("ready",), f["id"])
    f = wait_enabled(page, "start", 60)
    mouse.press(f, "start")
    page.wait_ready()
    page.close()
    s.said(r"trial antTrue_L02_r1: failed \(the participant's page closed", 120)
    state = json.loads((out / "sessions" / "L02" / "session.json").read_text())
    assert [t["status"] for t in state["trials"]] == ["ok", "ok", "failed"], state["trials"]
    # one spectator link for the session: every trial's bridge on the same port
    links = {m for line in s.lines for m in re.findall(r"spectators: (http://\S+)\)", line)}
    assert len(links) == 1, s.console()
    # the participant opens the link again and starts the trial; in it hrc session is killed
    # (kill -9): the page says in words that the session is not running
    page = Page(browser, s.url(), ready=False, scale=SCALE)
    mouse = Pointer(page)
    f = wait_screen(page, ("ready",))
    assert f["title"] == "Trial 3 of 3", f
    mouse.press(f, "start")
    wait_screen(page, ("trial",), timeout=180)
    page.wait_ready()
    grab_part(page, "H1", timeout=60)  # mid-trial: H1 in the hand
    os.kill(s.proc.pid, signal.SIGKILL)
    assert s.wait(30) == -signal.SIGKILL
    # (in the trial the form is not on screen: the message says it, not "the next screen
    # follows in a moment", which nothing would follow)
    away = "The session is not running"
    assert wait_until(lambda: away in page.text()["message"], 60), page.text()
    assert "The experimenter has stopped" not in page.text()["message"]  # nobody did
    assert wait_until(lambda: "the session is not running" in page.text()["status"], 10), (
        page.text()
    )
    assert away in (form(page)["notice"] or ""), form(page)
    shot(page, "session-not-running.png")

    # the same command resumes, on the same link: the page that was open goes on by itself,
    # with the failed trial again, its questionnaire, the end
    s2 = Session(study, "L02", out, port=s.port)
    sessions.append(s2)
    assert s2.url() == s.url()
    path = out / "sessions" / "L02" / "session.json"
    # (the page was in the trial: the new process's first screen is the trial's ready again)
    assert wait_until(lambda: form(page)["kind"] == "ready" and not form(page)["notice"], 60), form(
        page
    )
    f = form(page)
    assert f["kind"] == "ready" and f["title"] == "Trial 3 of 3", f  # nothing asked again
    shot(page, "session-resumed-ready.png")
    mouse.press(f, "start")
    do_trial(page)
    f = wait_screen(page, ("questionnaire",), f["id"])
    # the tab closes mid-questionnaire: reopened, it has the answers already given
    given = {"mental": 70, "physical": 20}
    answer_questionnaire(page, mouse, given, submit=False)
    drafts = lambda: json.loads(path.read_text())["drafts"]  # noqa: E731
    assert wait_until(lambda: drafts().get("antTrue_L02_r1:tlx") == given, 30), drafts()
    page.close()
    page = Page(browser, s2.url(), ready=False, scale=SCALE)
    mouse = Pointer(page)
    f = wait_screen(page, ("questionnaire",))
    assert form(page)["answers"] == given, form(page)
    shot(page, "session-questionnaire-reopened.png")
    # nothing of the page's under the form's corners (the status panel and key help were)
    assert page.page.evaluate("window.hrcTest.boxes()") == {}, "a box under the form"
    answer_questionnaire(page, mouse, {**TLX_ANSWERS, "mental": 70})
    f = wait_screen(page, ("questionnaire",), f["id"])
    assert f["title"] == "After the session", f
    shot(page, "session-questionnaire-likert.png")
    answer_questionnaire(page, mouse, {"safe": 4})
    wait_screen(page, ("done",), f["id"])
    shot(page, "session-done.png")
    assert s2.wait(60) == 0, s2.console()

    table = pd.read_csv(out / "trials.csv")
    live = table[table["participant_kind"] == "live"].set_index("trial")
    sim = table[table["participant_kind"] == "simulated"]
    assert len(sim) == 4 and set(sim["participant"]) == {"P01", "P02"}, sim
    assert list(live.index) == ["practice1_antTrue_L02_r1", "antFalse_L02_r1", "antTrue_L02_r1"]
    assert list(live["order_position"]) == [0, 1, 2]
    assert list(live["practice"]) == [True, False, False]
    assert list(live["outcome"]) == ["ok", "ok", "ok"]
    assert list(live["attempts"]) == [1, 1, 3]  # the page closed; hrc session killed
    assert live.loc["antFalse_L02_r1", "q.tlx.mental"] == 55
    assert live.loc["antTrue_L02_r1", "q.tlx.mental"] == 70
    raw = sum({**TLX_ANSWERS, "mental": 70}.values()) / 6  # the raw TLX: the six scales' mean
    assert live.loc["antTrue_L02_r1", "q.tlx.raw"] == pytest.approx(raw, abs=1e-3)
    assert pd.isna(live.loc["practice1_antTrue_L02_r1", "q.tlx.mental"])
    assert list(live["q.trust.safe"]) == [4, 4, 4]
    assert (live["task.finished"] == True).all()  # noqa: E712
    # the failed attempt is kept beside the trial
    assert any((out / "sessions" / "L02" / "attempts").iterdir())

    rep = subprocess.run([HRC, "report", str(out)], capture_output=True, text=True, timeout=300)
    assert rep.returncode == 0, rep.stderr[-3000:]
    report = (out / "report.html").read_text()
    assert "Live and simulated participants" in report
    assert "<th>live</th><th>simulated</th>" in report
    assert "q.tlx.raw" in report and "factors + order_position" in report
    assert "practice trials left out" in report

    # the person's recorded movements, replayed at another robot speed (they do not react)
    recording = out / "trials" / "antTrue_L02_r1" / "participant-input.jsonl"
    replayed = tmp_path / "replayed.toml"
    replayed.write_text(
        f'[study]\nname = "replayed"\nscenario = "{MINIMAL}"\n[factors]\n'
        '"robots.*.max_tcp_speed" = [0.25, 0.5]\n'
        f'[participants]\nreplay = ["{recording}"]\n'
    )
    again = subprocess.run(
        [HRC, "sweep", str(replayed), "--out", str(tmp_path / "replayed"), "--workers", "2"],
        capture_output=True, text=True, cwd=ROOT, timeout=600,
    )  # fmt: skip
    assert again.returncode == 0, again.stderr[-3000:]
    rows = pd.read_csv(tmp_path / "replayed" / "trials.csv")
    assert list(rows["participant_kind"]) == ["replay", "replay"], rows
    assert list(rows["outcome"]) == ["ok", "ok"] and rows["task.finished"].all(), rows
    assert rows["parts.H1.placed_s"].notna().all()


LIVE_HEADSET = """[live]
participants = ["H01"]
consent = "consent.md"
instructions = "instructions.md"
after_trial = ["tlx"]
end = ["trust"]

[questionnaires.trust]
title = "After the session"
points = 5
anchors = ["strongly disagree", "strongly agree"]
items = [
  { id = "safe", text = "I felt safe working beside the robots." },
  { id = "remark", kind = "text", text = "Anything you want to tell us?" },
]
"""


@pytest.mark.timeout(900)
def test_the_session_in_a_headset_is_answered_with_the_controller_ray(
    browser: Any,  # noqa: F811
    sessions: list[Session],
    tmp_path: Path,
) -> None:
    study = write_study(
        tmp_path / "study", LIVE_HEADSET, simulated=0, factors='"conditions.anticipation" = [true]'
    )
    out = tmp_path / "out"
    s = Session(study, "H01", out, mode="xr")
    sessions.append(s)
    page = Page(browser, s.url() + "&test=iwer", ready=False)
    ray = Pointer(page, headset=True)
    f = wait_screen(page, ("consent",))
    page.page.click("#enter-vr")  # a user gesture, as a headset's browser needs
    page.wait("immersive session", lambda st: st["xr"], 30)
    assert wait_until(lambda: form(page)["in_headset"], 30), form(page)
    shot(page, "session-xr-consent.png")
    ray.press(f, "yes")
    f = wait_screen(page, ("text",), f["id"])
    ray.press(f, "continue")
    f = wait_screen(page, ("ready",), f["id"])
    ray.press(f, "start")
    wait_screen(page, ("trial",), f["id"], timeout=180)
    page.wait_ready()
    # the panel is gone while the trial runs (from the page's next frame on)
    assert wait_until(lambda: not form(page)["in_headset"], 10), form(page)
    # hrc session killed mid-trial (kill -9): the headset says so; the same command again,
    # and the page in the headset goes on, at the trial's ready screen
    os.kill(s.proc.pid, signal.SIGKILL)
    assert s.wait(30) == -signal.SIGKILL
    away = "The session is not running"
    panel = lambda: " ".join(page.page.evaluate("window.hrcTest.panelText()").split())  # noqa: E731
    assert wait_until(lambda: away in panel(), 60), panel()  # what the headset's panel says
    assert "The experimenter has stopped" not in panel()
    rendered_frames(page)
    shot(page, "session-xr-not-running.png")
    s = Session(study, "H01", out, mode="xr", port=s.port)
    sessions.append(s)
    assert wait_until(lambda: form(page)["kind"] == "ready" and form(page)["in_headset"], 60), form(
        page
    )
    f = form(page)
    ray.press(f, "start")
    wait_screen(page, ("trial",), f["id"], timeout=180)
    page.wait_ready()
    controller_places(page, "H1")
    page.wait("the trial finished", lambda st: st["run"] == "finished", 180)
    f = wait_screen(page, ("questionnaire",), f["id"])
    assert wait_until(lambda: form(page)["in_headset"], 10), form(page)  # at its next frame
    shot(page, "session-xr-questionnaire.png")
    answer_questionnaire(page, ray, TLX_ANSWERS)
    f = wait_screen(page, ("questionnaire",), f["id"])
    answer_questionnaire(page, ray, {"safe": 5, "remark": "ok"})
    wait_screen(page, ("done",), f["id"])
    assert s.wait(60) == 0, s.console()

    state = json.loads((out / "sessions" / "H01" / "session.json").read_text())
    assert state["trials"][0]["answers"]["tlx"] == TLX_ANSWERS
    cut, done = state["trials"][0]["attempts"]
    assert cut["outcome"] == "failed" and done["outcome"] == "ok", state["trials"][0]
    beside = json.loads((out / "trials" / state["trials"][0]["id"] / "answers.json").read_text())
    assert beside["answers"]["tlx"] == TLX_ANSWERS and beside["scores"]["tlx"]["raw"] > 0
    assert state["end_answers"]["trust"] == {"safe": 5, "remark": "ok"}
