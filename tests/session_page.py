"""A live participant's session (`hrc session`) in headless Debian chromium, done like a person
would (shared by the session tests): the study files, the session's process and its console,
and the page's screens answered with the mouse (desktop) or the controller's ray (headset).
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from websockets.sync.client import ClientConnection

from hrc.bench.client import REST_LEFT, REST_RIGHT, connect_when_up, grab, move

from .conftest import HRC, ROOT, free_port, ignore_sigint, wait_until
from .goldens import MINIMAL
from .participant_page import Page, grab_part, place_part

CONSENT = (
    "# Consent\n\nYou take part in a study of **working with robots**.\n\n"
    "- You may stop at any time.\n"
)
INSTRUCTIONS = (
    "# How it works\n\nPlace your part on its outlined target. The robots work beside you.\n"
)
CUES = "In this block the robots **show their targets** before they move.\n"


def write_study(
    folder: Path, live: str, simulated: int = 2, factors: str = "", consent: str = CONSENT
) -> Path:
    """A study of minimal.toml with two conditions (anticipation on, off), `simulated`
    scripted participants and the `[live]` table given, the texts beside it."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "consent.md").write_text(consent)
    (folder / "instructions.md").write_text(INSTRUCTIONS)
    (folder / "cues.md").write_text(CUES)
    factors = factors or '"conditions.anticipation" = [true, false]'
    sim = f"[participants]\nn = {simulated}\nseed_base = 300\n" if simulated else ""
    text = (
        f'[study]\nname = "people"\nscenario = "{MINIMAL}"\n\n[factors]\n{factors}\n\n{sim}\n{live}'
    )
    path = folder / "study.toml"
    path.write_text(text)
    return path


class Session:
    """`hrc session STUDY --participant ID` in the background; its console lines kept."""

    def __init__(
        self,
        study: Path,
        participant: str,
        out: Path,
        mode: str = "desktop",
        sigint_ignored: bool = False,
        port: int | None = None,
    ) -> None:
        self.port = port or free_port()
        self.argv = [
            HRC, "session", str(study), "--participant", participant, "--out", str(out),
            "--port", str(self.port), "--page-mode", mode,
        ]  # fmt: skip
        self.lines: list[str] = []
        self.proc = subprocess.Popen(
            self.argv,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=ROOT,
            start_new_session=True,
            env={**os.environ, "CI": "true"},
            # as a script's background job (or nohup, or a CI runner) starts it
            preexec_fn=ignore_sigint if sigint_ignored else None,
        )
        threading.Thread(target=self._read, daemon=True).start()
        ok = wait_until(lambda: self.url() is not None or self.proc.poll() is not None, 120, 0.1)
        assert ok and self.url(), f"hrc session printed no page link: {self.console()}"

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def console(self) -> str:
        return "\n".join(self.lines[-40:])

    def url(self) -> str | None:
        for line in self.lines:
            m = re.search(r"participant's page: (http://\S+)", line)
            if m:
                return m.group(1)
        return None

    def said(self, pattern: str, timeout: float) -> None:
        ok = wait_until(lambda: any(re.search(pattern, ln) for ln in self.lines), timeout, 0.2)
        assert ok, f"the console never said /{pattern}/ within {timeout:g} s:\n{self.console()}"

    def command(self, c: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(c + "\n")
        self.proc.stdin.flush()

    def interrupt(self) -> int:
        """Ctrl-C, as in the experimenter's terminal."""
        os.killpg(self.proc.pid, signal.SIGINT)
        return self.wait(60)

    def wait(self, timeout: float) -> int:
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(
                f"hrc session did not end within {timeout:g} s:\n{self.console()}"
            ) from None

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()


# ------------------------------------------------- the page played by a WebSocket client


def page_link(s: Session) -> tuple[str, str]:
    """(the session's WebSocket URL, the participant's key) from the printed link."""
    url = s.url()
    assert url
    parts = urlsplit(url)
    key = parse_qs(parts.query)["driver"][0]
    return f"ws://{parts.netloc}/session?driver={key}", key


def screen(ws: ClientConnection, kind: str = "") -> dict[str, Any]:
    """The next screen the session shows (of `kind`, if given; others passed over)."""
    while True:
        msg = json.loads(ws.recv(timeout=60))
        if msg.get("type") == "screen" and (not kind or msg["kind"] == kind):
            return msg


def place_by_socket(
    port: int, key: str, pid: str = "H1", holding: Callable[[], None] | None = None
) -> None:
    """A session's trial played by a Python participant on the trial's bridge (port, the
    session's driver key), as the page would: the right hand takes `pid` from its start, puts
    it on its target, lets go and goes back to rest; returns once the trial has finished.
    `holding`: called with the part in the hand (a participant who stops there a while)."""
    client = connect_when_up(f"ws://127.0.0.1:{port}/ws?driver={key}&page=py-{pid}", 60)
    try:
        got = client.wait_for(lambda m: m.msg.get("type") == "scene", 30)
        assert got is not None, "the trial's bridge sent no scene"
        part = next(p for p in got[1].msg["parts"] if p["id"] == pid)
        above = grab(client, part)
        held = client.wait_for(
            lambda m: (
                m.msg.get("type") == "frame"
                and m.msg["objects"].get(pid, {}).get("holder") == "right"
            ),
            30,
        )
        assert held is not None, f"{pid} was never held"
        if holding is not None:
            holding()
        # (grab() holds it min(2 cm, half its height) above its centre, and lifts it 10 cm)
        tx, ty, tz = part["target"]["xyz"]
        down = (tx, ty, tz + min(0.02, part["size"][2] / 2))
        over = (tx, ty, tz + 0.10)
        move(client, above, over, 1.0, REST_LEFT)
        move(client, over, down, 1.0, REST_LEFT, 10)
        client.hands(REST_LEFT, down, 0.0, 0.0)
        placed = client.wait_for(
            lambda m: (
                m.msg.get("type") == "frame" and m.msg["objects"].get(pid, {}).get("placed") is True
            ),
            30,
        )
        assert placed is not None, f"{pid} was not placed on its target"
        move(client, down, REST_RIGHT, 0.0, REST_LEFT)
        done = client.wait_for(
            lambda m: m.msg.get("type") == "frame" and m.msg["run"] == "finished", 180
        )
        assert done is not None or client.closed, "the trial did not finish"
    finally:
        client.close()


# ---------------------------------------------------------------- the page's screens


def form(page: Page) -> dict[str, Any]:
    return page.page.evaluate("window.hrcTest && window.hrcTest.form()")  # type: ignore[no-any-return]


def wait_screen(
    page: Page, kinds: tuple[str, ...], after: int = 0, timeout: float = 120
) -> dict[str, Any]:
    """The page's next screen of one of `kinds` newer than screen `after`."""

    def there() -> bool:
        f = form(page)
        return bool(
            f and f["kind"] in kinds and f["id"] > after and (f["visible"] or f["kind"] == "trial")
        )

    ok = wait_until(there, timeout, 0.1)
    assert ok, f"no {kinds} screen after #{after} within {timeout:g} s; the page shows {form(page)}"
    return form(page)


def wait_enabled(page: Page, wid: str, timeout: float) -> dict[str, Any]:
    """The screen once its widget `wid` can be pressed (a break's Start)."""

    def enabled() -> bool:
        return any(w["id"] == wid and not w["disabled"] for w in form(page)["widgets"])

    assert wait_until(enabled, timeout, 0.2), f"{wid} stays disabled: {form(page)}"
    return form(page)


def widget(f: dict[str, Any], wid: str) -> dict[str, Any]:
    found = [w for w in f["widgets"] if w["id"] == wid]
    assert found, f"no widget {wid!r} on the {f['kind']} screen: {[w['id'] for w in f['widgets']]}"
    return found[0]


class Pointer:
    """Clicks on the form: the mouse on the desktop; in the headset, the right controller aimed
    at the point from below the eyes and its trigger pulled."""

    def __init__(self, page: Page, headset: bool = False) -> None:
        self.page = page
        self.headset = headset

    def click_at(self, x: float, y: float) -> None:
        pt = self.page.page.evaluate("([x, y]) => window.hrcTest.formPoint(x, y)", [x, y])
        if not self.headset:
            assert "x" in pt, f"the form is not on the page: {pt}"
            self.page.page.mouse.click(pt["x"], pt["y"])
            return
        assert "xr" in pt, f"the form is not in the headset: {pt}"
        self.aim(pt["xr"])
        self.trigger(1.0)
        self.trigger(0.0)

    def aim(self, target: list[float]) -> None:
        """The right controller 35 cm below and in front of the head, pointing at `target`."""
        head = self.page.page.evaluate(
            "() => { const p = window.hrcXrDevice.position; return [p.x, p.y, p.z]; }"
        )
        origin = [head[0] + 0.15, head[1] - 0.35, head[2] - 0.2]
        d = [t - o for t, o in zip(target, origin, strict=True)]
        n = math.sqrt(sum(c * c for c in d))
        d = [c / n for c in d]
        # the rotation taking -z onto d: axis (-z) x d, angle acos(-z . d)
        axis = [d[1], -d[0], 0.0]  # (0, 0, -1) x d
        s = math.sqrt(axis[0] ** 2 + axis[1] ** 2)
        angle = math.acos(max(-1.0, min(1.0, -d[2])))
        if s < 1e-9:
            q = [0.0, 0.0, 0.0, 1.0]
        else:
            k = math.sin(angle / 2) / s
            q = [axis[0] * k, axis[1] * k, 0.0, math.cos(angle / 2)]
        self.page.page.evaluate(
            """([p, q]) => {
                const c = window.hrcXrDevice.controllers.right;
                c.position.set(p[0], p[1], p[2]);
                c.quaternion.set(q[0], q[1], q[2], q[3]);
            }""",
            [origin, q],
        )
        # the page reads the controller at its next frame (and acts on it then)
        from .participant_page import rendered_frames

        rendered_frames(self.page, 1)

    def trigger(self, value: float) -> None:
        self.page.page.evaluate(
            "(v) => window.hrcXrDevice.controllers.right.updateButtonValue('trigger', v)", value
        )
        from .participant_page import rendered_frames

        rendered_frames(self.page, 1)

    def press(self, f: dict[str, Any], wid: str) -> None:
        w = widget(f, wid)
        assert not w["disabled"], f"{wid} is disabled on the {f['kind']} screen"
        self.click_at(w["x"] + w["w"] / 2, w["y"] + w["h"] / 2)


def answer_questionnaire(
    page: Page, pointer: Pointer, answers: dict[str, Any], submit: bool = True
) -> dict[str, Any]:
    """Answers the questionnaire on screen, page by page, as `answers` says (a scale: its
    value, clicked where it lies on the scale; a Likert item or choice: its box; text: typed
    on the keyboard, or on the panel's keyboard in the headset); returns the form as sent
    (`submit` false: as it is once the items of its first page are answered, not sent)."""
    f = form(page)
    assert f["kind"] == "questionnaire", f
    sid = f["id"]
    for _ in range(20):  # pages
        f = form(page)
        ids = {w["id"].split("=")[0] for w in f["widgets"]}
        for item, value in answers.items():
            if item not in ids:
                continue
            if f["answers"].get(item) == value:
                continue
            w = next(w for w in f["widgets"] if w["id"].split("=")[0] == item)
            if w["kind"] == "scale":
                x0, width = w["x"] + 10, w["w"] - 20
                pointer.click_at(x0 + width * value / 100, w["y"] + w["h"] / 2)
            elif w["kind"] == "text":
                pointer.press(f, item)
                if pointer.headset:
                    kb = form(page)
                    assert kb["keyboard"] == item, kb
                    for ch in str(value):
                        pointer.press(form(page), "key:space" if ch == " " else f"key:{ch}")
                    pointer.press(form(page), "key:done")
                else:
                    page.page.keyboard.type(str(value))
                    page.page.keyboard.press("Enter")
            else:
                pointer.press(f, f"{item}={value}")
            f = form(page)
            assert f["answers"].get(item) == value, (item, value, f["answers"])
        if not submit:
            return f
        buttons = {w["id"] for w in f["widgets"]}
        if "submit" in buttons:
            pointer.press(f, "submit")
            ok = wait_until(
                lambda: (form(page) or {}).get("id", sid) != sid or form(page)["sent"], 30, 0.1
            )
            assert ok, form(page)
            return f
        pointer.press(f, "next")
    raise AssertionError(f"the questionnaire never reached its Submit button: {form(page)}")


TLX_ANSWERS = {
    "mental": 55,
    "physical": 20,
    "temporal": 40,
    "performance": 25,
    "effort": 50,
    "frustration": 10,
}


def do_trial(page: Page) -> None:
    """The trial on screen: the page connects to its bridge; H1 is grabbed and placed (the
    desktop page's keyboard and mouse); the trial finishes."""
    wait_screen(page, ("trial",), timeout=180)
    page.wait_ready()
    grab_part(page, "H1", timeout=60)
    place_part(page, "H1")
    page.wait("the trial finished", lambda s: s["run"] == "finished", 180)
