"""`hrc session STUDY --participant ID`: one live participant through their trials, in their
order, with the texts and questionnaires of the study file between them (docs/studies.md,
"Running a study with people").

The main thread walks the session's steps (consent, instructions, each trial with its ready
screen and questionnaires, the end questionnaires); every step's result is saved in
session.json before the next begins, so the same command resumes after any crash. Each trial
is a live `hrc run --input vr` in its own process group, bounded by the study's
`trial_timeout_s`. Everything the main thread waits for (the page, the trial's process, the
experimenter's commands) arrives in one queue.

Why one file of over 600 lines: the session's steps are one sequence over one state and one
queue; split, a step's resume rule would live apart from the step.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import json
import logging
import os
import queue
import secrets
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from hrc.priority import carry_niceness
from hrc.session.web import SessionServer
from hrc.study import session_state as st
from hrc.study.live import LiveSpec
from hrc.study.questionnaires import Questionnaire
from hrc.study.spec import LiveTrial, Study
from hrc.study.trial import RECORDING_FILE, judge, read_metrics, stop_process
from hrc.trial.processes import die_with_parent

log = logging.getLogger(__name__)

STATUS_EVERY_S = 30.0  # the console's status line while a trial runs
STOP_GRACE_S = 15.0  # a stopped trial's SIGTERM, then SIGKILL to its process group
# an attempt's reason when its `hrc session` ended during it (found so on resume)
CUT_SHORT = "the session process ended during this trial (killed or crashed); it runs again"
PAGE_GRACE_S = 10.0  # the page gone this long during a trial: the trial is stopped, failed
BRIDGE_START_S = 90.0  # hrc run's services up and its bridge serving, at most
VR_WAIT_S = 300.0  # the trial waits this long for the page to connect to its bridge
HELP = (
    "commands (type a letter, Enter): p pause/continue before the next step, r repeat the "
    "trial in progress, s skip it (or the next one), e end the session (resume later with the "
    "same command), n TEXT a note on the trial in progress (or the last one), f [TEXT] flag it, "
    "? status"
)


class SessionEnd(Exception):
    """The session stops here (its state is saved): `code` is the command's exit code."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


@dataclass
class Options:
    out: Path
    host: str = "127.0.0.1"
    port: int = 8770
    vr_port: int = 0  # 0: a free port for each trial
    token: str | None = None
    mode: str = ""  # the page's mode in the printed link: "", "desktop" or "xr"


class Session:
    def __init__(
        self, study: Study, participant: str, opts: Options, console: IO[str] | None = None
    ) -> None:
        if study.live is None:
            raise SessionEnd(
                f"{study.path}: the study has no [live] table: no live participants", 2
            )
        if participant not in study.live.participants:
            ids = ", ".join(study.live.participants[:8])
            raise SessionEnd(
                f"--participant {participant!r}: not a live participant of the study ({ids}, ...)",
                2,
            )
        self.study = study
        self.live: LiveSpec = study.live
        self.pid = participant
        self.opts = opts
        self.out = opts.out
        self.dir = st.session_dir(self.out, participant)
        self.path = self.dir / "session.json"
        self.console = console or sys.stderr
        self.trials = {t.id: t for t in study.live_trials(participant)}
        self.paused = False
        self.trial_status = ""  # the running trial's last status line (its hrc run's console)
        self.trial_port = 0  # the trials' bridge port, once chosen
        self.screen_id = 0
        self.screen: dict[str, Any] = {}
        self.break_until = 0.0
        self.t0 = time.monotonic()
        self._lock = self._take_lock()
        self.state = self._load_or_create()
        # one link for the whole session: after a crash the same command serves the same key,
        # and the page that was open redials and goes on by itself
        if not self.state.key:
            self.state.key = secrets.token_urlsafe(9)
            st.save(self.state, self.path)
        self.key = self.state.key
        self.server = SessionServer(opts.host, opts.port, self.key, opts.token)
        self.inbox = self.server.inbox

    # ------------------------------------------------------------------ state
    def _take_lock(self) -> IO[str]:
        """One `hrc session` per participant at a time (two would write the same file); the
        lock goes with the process, however it ends."""
        self.dir.mkdir(parents=True, exist_ok=True)
        f = open(self.dir / "lock", "a+", encoding="utf-8")  # held until the process exits
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.seek(0)
            holder = f.read().strip() or "?"
            f.close()
            raise SessionEnd(
                f"{self.pid}'s session is already running (process {holder}): one session per "
                "participant at a time",
                2,
            ) from None
        f.seek(0)
        f.truncate()
        f.write(str(os.getpid()))
        f.flush()
        return f

    def _load_or_create(self) -> st.SessionState:
        saved = st.load(self.path)
        plan = list(self.trials.values())
        if saved is None:
            order = self.live.orders(self.study.conditions)[self.pid]
            state = st.SessionState(
                self.study.name,
                self.pid,
                st.now_iso(),
                order,
                [
                    st.TrialState(
                        t.id,
                        t.plan.index,
                        t.plan.practice,
                        t.plan.order_position,
                        t.condition,
                        t.plan.condition_index,
                        t.plan.seed,
                        t.input_hash,
                        t.plan.repetition,
                    )
                    for t in plan
                ],
            )
            state.note("session created")
            st.save(state, self.path)
            return state
        if saved.status == "declined":
            raise SessionEnd(
                f"{self.pid} declined consent ({(saved.consent or {}).get('at', '?')}): the "
                f"session does not run again; remove {self.dir} to start it anew",
                2,
            )
        if [t.id for t in saved.trials] != [t.id for t in plan]:
            raise SessionEnd(
                f"{self.path}: the study's trials for {self.pid} changed since the session began "
                "(factors, order, practice or repetitions): finish it with the study file it "
                "began with, or remove the folder to start anew",
                2,
            )
        for ts in saved.trials:  # an edited scenario: trials still to run take the new inputs
            if not ts.done and ts.input_hash != self.trials[ts.id].input_hash:
                ts.input_hash = self.trials[ts.id].input_hash
            for attempt in ts.attempts:  # cut short by the end of the last `hrc session`
                if not attempt.outcome:
                    attempt.outcome = "failed"
                    attempt.reason = CUT_SHORT
        if saved.status == "running":  # nobody said it stopped: killed, or the machine went
            saved.note("the last session process ended without a word (killed or crashed)")
        saved.status = "running"
        saved.note("session resumed")
        st.save(saved, self.path)
        return saved

    def _save(self) -> None:
        st.save(self.state, self.path)
        from hrc.study.table import write_study_table

        try:
            write_study_table(self.study, self.out)
        except (
            OSError,
            ValueError,
            ImportError,
        ) as exc:  # the table can be rebuilt: never stop a session for it
            log.warning("the study's table was not rewritten: %s", exc)

    def say(self, line: str) -> None:
        elapsed = int(time.monotonic() - self.t0)
        with contextlib.suppress(OSError, ValueError):
            self.console.write(f"[{elapsed // 60:02d}:{elapsed % 60:02d}] {line}\n")
            self.console.flush()

    def progress(self) -> dict[str, int]:
        """Trials done (ok or stalled: the participant did them), skipped, and in all."""
        trials = self.state.trials
        skipped = sum(t.status == "skipped" for t in trials)
        done = sum(t.done for t in trials) - skipped
        return {"done": done, "skipped": skipped, "total": len(trials)}

    def status(self) -> str:
        p = self.progress()
        page = "page connected" if self.server.connected() else "page not connected"
        paused = ", PAUSED" if self.paused else ""
        skipped = f" ({p['skipped']} skipped)" if p["skipped"] else ""
        trial = f"; trial: {self.trial_status}" if self.trial_status else ""
        return f"{self.pid}: {p['done']}/{p['total']} trials done{skipped}, {page}{paused}{trial}"

    # ------------------------------------------------------------------ the run
    def url(self) -> str:
        host = "127.0.0.1" if self.opts.host in ("0.0.0.0", "::") else self.opts.host
        q = f"?session=1&driver={self.key}"
        if self.opts.token:
            q += f"&token={self.opts.token}"
        if self.opts.mode:
            q += f"&mode={self.opts.mode}"
        return f"http://{host}:{self.server.bound_port}/{q}"

    def run(self) -> int:
        from hrc.study.sweep import write_study_files

        try:
            write_study_files(self.study, self.out)
            self.server.start()
            threading.Thread(target=self._read_commands, name="console", daemon=True).start()
            n = len(self.state.trials)
            left = sum(not t.done for t in self.state.trials)
            self.say(
                f"session {self.study.name!r}, participant {self.pid}: {n} trials, {left} to do "
                f"-> {self.dir}"
            )
            self.say(f"participant's page: {self.url()}")
            self.say(HELP)
            while True:
                if not self._step():
                    break
            self.state.status = "done"
            self.state.note("session done")
            self._save()
            self.show(
                "done", title="Thank you!", text="The session is over. Thank you for taking part."
            )
            self.say(f"session done: {self.status()}")
            self._linger()
            return 0
        except SessionEnd as end:
            self.say(str(end))
            return end.code
        finally:
            self._stopping()
            self.server.stop()

    def _stopping(self) -> None:
        """The process leaves with the session not over (the experimenter's `e`, Ctrl-C, a
        signal, an error, a port it could not serve): session.json says so, and the page, if
        there is one, says in words that the session goes on later, on that same page."""
        if self.state.status not in ("running", "ended"):
            return  # done or declined: the page has its last screen
        if self.state.status == "running":
            self.state.status = "stopped"
            self.state.note("session stopped")
            try:
                st.save(self.state, self.path)
            except OSError as exc:
                log.warning("session.json not rewritten: %s", exc)
        if self.server.connected():
            why = (
                "The experimenter has ended the session for now."
                if self.state.status == "ended"
                else "The session has stopped for now."
            )
            self.show(
                "paused",
                title="Paused",
                text=f"{why} Please wait: it goes on from here, on this page, when the "
                "experimenter continues it.",
            )
            self._linger(1.0)

    def _linger(self, seconds: float = 3.0) -> None:
        """The page gets the last screen before the server goes."""
        end = time.monotonic() + seconds
        while time.monotonic() < end and self.server.connected():
            time.sleep(0.1)

    def _step(self) -> bool:
        """Does the next step of the session; False when none is left."""
        s, live = self.state, self.live
        if self.paused:
            self._paused()
        if live.consent and s.consent is None:
            return self._consent()
        for q in live.before_session:  # demographics, a baseline SSQ
            if q.id not in s.start_answers:
                self._questionnaire(q, None, at="start")
                return True
        if live.instructions and "instructions" not in s.seen:
            self._text("instructions", "Instructions", live.instructions)
            return True
        for ts in s.trials:  # answers owed for a trial that is done (a crash in between)
            if ts.status in ("ok", "stalled") and not ts.practice:
                for q in live.after_trial:
                    if q.id not in ts.answers:
                        self._questionnaire(q, ts)
                        return True
        nxt = next((t for t in s.trials if not t.done), None)
        if nxt is not None:
            trial = self.trials[nxt.id]
            for i, ins in enumerate(live.instruction_for(trial.condition)):
                key = f"instruction:{nxt.id}:{i}"
                if key not in s.seen:
                    self._text(key, "Before the next trial", ins.text)
                    return True
            for q in [] if nxt.practice else live.before_trial:
                if q.id not in nxt.answers:
                    self._questionnaire(q, nxt)
                    return True
            self._trial(nxt, trial)
            return True
        for q in live.end:
            if q.id not in s.end_answers:
                self._questionnaire(q, None)
                return True
        return False

    # ------------------------------------------------------------------ screens
    def show(self, kind: str, **fields: Any) -> int:
        self.screen_id += 1
        self.screen = {
            "id": self.screen_id,
            "kind": kind,
            "participant": self.pid,
            "progress": self.progress(),
            **fields,
        }
        self.server.show(self.screen)
        return self.screen_id

    def _wait(
        self,
        sid: int,
        types: tuple[str, ...],
        timeout: float | None = None,
        draft: tuple[str, Questionnaire] | None = None,
    ) -> dict[str, Any] | None:
        """The page's next answer to screen `sid` (of one of `types`); commands are handled on
        the way, and (`draft`: its key and questionnaire) the answers given so far are kept.
        None after `timeout` seconds."""
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                return None
            try:
                kind, msg = self.inbox.get(timeout=0.5 if left is None else min(0.5, left))
            except queue.Empty:
                continue
            if kind == "page" and msg.get("type") in types and msg.get("screen") == sid:
                return msg
            if kind == "page" and msg.get("type") == "draft" and msg.get("screen") == sid:
                if draft is not None:
                    self._keep_draft(draft[0], draft[1], msg.get("answers"))
                continue
            if kind == "cmd":
                self._command(msg["c"], running=None, text=msg.get("text", ""))
                if self.paused and types:  # held now, the screen waited on comes back after
                    waiting = self.screen
                    self._paused()
                    self.screen = waiting
                    self.server.show(waiting)
            elif kind == "connected":
                self.say("participant's page connected")
            elif kind == "gone":
                self.say("participant's page gone: waiting for it (the same link reopens it)")

    def _consent(self) -> bool:
        sid = self.show("consent", title="Consent", text=self.live.consent)
        msg = self._wait(sid, ("consent",))
        assert msg is not None
        accepted = msg.get("accepted") is True
        self.state.consent = {"accepted": accepted, "at": st.now_iso()}
        self.state.note("consent " + ("accepted" if accepted else "declined"))
        if not accepted:
            self.state.status = "declined"
            self._save()
            self.show(
                "ended",
                title="Thank you",
                text="You did not agree: the session ends here. Please tell the experimenter.",
            )
            self._linger()
            raise SessionEnd(
                f"{self.pid} declined consent: the session ends (nothing was recorded)", 0
            )
        self._save()
        self.say("consent accepted")
        return True

    def _text(self, key: str, title: str, text: str) -> None:
        sid = self.show("text", title=title, text=text)
        self._wait(sid, ("continue",))
        self.state.seen.append(key)
        self.state.note(f"shown {key}")
        self._save()

    def _keep_draft(self, key: str, q: Questionnaire, answers: object) -> None:
        """The answers given so far (the page sends them as they are given): kept in
        session.json and in the screen a reopened page gets."""
        if not isinstance(answers, dict):
            return
        kept = {
            i.id: answers[i.id]
            for i in q.items
            if answers.get(i.id) is not None and i.check(answers[i.id]) is None
        }
        if kept == self.state.drafts.get(key):
            return
        self.state.drafts[key] = kept
        self.screen = {**self.screen, "draft": kept}
        self.server.keep(self.screen)
        st.save(self.state, self.path)

    def _questionnaire(self, q: Questionnaire, ts: st.TrialState | None, at: str = "end") -> None:
        """Asks `q` about trial `ts` (before or after it), or, without one, `at` the session's
        start or end; the answers are kept (session.json, and the trial's answers.json)."""
        where = f"for {ts.id}" if ts else f"at the session's {at}"
        self.say(f"questionnaire {q.id} ({where})")
        key = f"{ts.id if ts else at}:{q.id}"
        problems: list[str] = []
        while True:
            sid = self.show(
                "questionnaire",
                questionnaire=q.to_wire(),
                problems=problems,
                draft=self.state.drafts.get(key, {}),
            )
            msg = self._wait(sid, ("answers",), draft=(key, q))
            assert msg is not None
            answers = msg.get("answers")
            if not isinstance(answers, dict):
                problems = ["the answers did not arrive whole: please answer again"]
                continue
            answers = {k: v for k, v in answers.items() if v is not None and v != ""}
            problems = q.check(answers)
            if not problems:
                break
            self._keep_draft(key, q, answers)  # asked again: with what was given
            self.say(f"questionnaire {q.id}: incomplete ({problems[0]}); asked again")
        self.state.drafts.pop(key, None)
        scores = q.score(answers)
        if ts is None and at == "start":
            self.state.start_answers[q.id] = answers
            self.state.start_scores[q.id] = scores
        elif ts is None:
            self.state.end_answers[q.id] = answers
            self.state.end_scores[q.id] = scores
        else:
            ts.answers[q.id] = answers
            ts.scores[q.id] = scores
            # beside the trial's own files too (session.json stays the one that resumes)
            folder = self.out / "trials" / ts.id
            if folder.is_dir():
                doc = {"answers": ts.answers, "scores": ts.scores}
                (folder / "answers.json").write_text(json.dumps(doc, indent=1), encoding="utf-8")
        self.state.note(f"answered {q.id}", trial=ts.id if ts else None)
        self._save()

    def _paused(self) -> None:
        sid = self.show(
            "paused", title="Paused", text="The experimenter has paused the session. Please wait."
        )
        self.say("paused: p continues")
        while self.paused:
            self._wait(sid, (), timeout=0.5)
        self.say("continued")

    # ------------------------------------------------------------------ a trial
    def _trial(self, ts: st.TrialState, trial: LiveTrial) -> None:
        n = len(self.state.trials)
        what = "practice trial" if ts.practice else f"trial {ts.order_position}"
        cond = ", ".join(f"{k} = {v!r}" for k, v in ts.condition.items())
        title = f"{'Practice' if ts.practice else 'Trial'} {ts.index} of {n}"
        text = (
            "A practice trial: it does not count. Place the parts as you learned."
            if ts.practice
            else "Place your parts in their order. The robots work beside you."
        )
        break_s = max(0.0, self.break_until - time.monotonic())
        sid = self.show(
            "ready", title=title, text=text, break_s=round(break_s, 1), practice=ts.practice
        )
        self.say(
            f"next: {ts.index}/{n} {ts.id} ({what}; {cond}): waiting for the participant to start"
        )
        while True:
            msg = self._wait(sid, ("start",))
            if ts.status == "skipped":  # skipped while the ready screen showed
                return
            if msg is not None and time.monotonic() >= self.break_until - 0.5:
                break
        self._run_trial(ts, trial)

    def _run_trial(self, ts: st.TrialState, trial: LiveTrial) -> None:
        resolved = self.out / "resolved" / f"{ts.id}.toml"
        resolved.parent.mkdir(parents=True, exist_ok=True)
        resolved.write_text(trial.scenario_text, encoding="utf-8")
        trial_dir = self.out / "trials" / ts.id
        if trial_dir.exists():  # an earlier attempt: kept beside, not lost
            keep = self.dir / "attempts" / f"{ts.id}-{len(ts.attempts)}"
            keep.parent.mkdir(parents=True, exist_ok=True)
            shutil.rmtree(keep, ignore_errors=True)
            shutil.move(str(trial_dir), keep)
        from hrc.ports import free_port

        # one port for every trial of the session (reserved while it runs): the experimenter's
        # spectator link stays the same from trial to trial
        if not self.trial_port:
            self.trial_port = self.opts.vr_port or free_port()
        port = self.trial_port
        log_path = self.dir / f"hrc-run-{ts.id}-{len(ts.attempts) + 1}.log"
        argv = [
            sys.executable, "-m", "hrc.cli.main", "run", str(resolved),
            "--out", str(trial_dir), "--seed", str(ts.seed), "--input", "vr",
            "--vr-host", self.opts.host, "--vr-port", str(port), "--vr-wait", str(VR_WAIT_S),
            "--participant", self.pid, "--record", str(trial_dir / RECORDING_FILE),
            "--no-reach-check",
        ]  # fmt: skip
        env = {**os.environ, "HRC_VR_DRIVER": self.key}
        if self.opts.token:
            env["HRC_VR_TOKEN"] = self.opts.token
        attempt = st.Attempt(st.now_iso())
        ts.attempts.append(attempt)
        self.state.note(f"trial {ts.id} started", attempt=len(ts.attempts))
        st.save(self.state, self.path)
        t0 = time.monotonic()
        with open(log_path, "w", encoding="utf-8") as logf:
            # The trial ends (as on Ctrl-C: its records written) if the session process dies,
            # even by kill -9: else it waited up to VR_WAIT_S for a page that redials the next
            # session process, holding the trial port that one needs.
            proc = subprocess.Popen(
                argv, stdout=logf, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                env=env, start_new_session=True,
                preexec_fn=functools.partial(die_with_parent, signal.SIGTERM),
            )  # fmt: skip
            carry_niceness(proc.pid)
            threading.Thread(
                target=lambda: self.inbox.put(("exit", {"code": proc.wait()})), daemon=True
            ).start()
            stopped = ""
            try:
                stopped = self._watch(ts, proc, port, t0, TrialLog(log_path))
            except BaseException:
                stop_process(proc, STOP_GRACE_S)
                attempt.outcome, attempt.reason = (
                    "failed",
                    "the session was interrupted (Ctrl-C or a signal)",
                )
                attempt.wall_s = round(time.monotonic() - t0, 3)
                ts.status, ts.reason = "failed", attempt.reason
                self.state.note(f"trial {ts.id} failed: {attempt.reason}")
                self._save()
                raise
        self.trial_status = ""
        attempt.wall_s = round(time.monotonic() - t0, 3)
        attempt.exit_code = proc.returncode
        metrics = read_metrics(trial_dir / "metrics.json")
        tail = log_path.read_text(encoding="utf-8", errors="replace")
        outcome, reason = judge(proc.returncode, metrics, tail, stopped)
        if stopped.startswith("skipped"):
            outcome = "skipped"
        attempt.outcome, attempt.reason = outcome, reason
        ts.status, ts.reason = outcome, reason
        if "address already in use" in reason and not self.opts.vr_port:
            self.trial_port = 0  # somebody else took it meanwhile: the next attempt picks anew
        self.state.note(f"trial {ts.id} {outcome}", reason=reason)
        self._save()
        self.say(
            f"trial {ts.id}: {outcome}"
            + (f" ({reason.splitlines()[0][:200]})" if reason else "")
            + f", {attempt.wall_s:.0f} s"
        )
        if outcome in ("ok", "stalled"):
            self.break_until = time.monotonic() + self.live.min_break_s
        if stopped.startswith("ended"):  # (the page is told as the process leaves: _stopping)
            self.state.status = "ended"
            self._save()
            raise SessionEnd(
                "session ended by the experimenter: resume with the same command "
                f"({self.status()})",
                0,
            )

    def _watch(
        self, ts: st.TrialState, proc: subprocess.Popen[Any], port: int, t0: float, tl: TrialLog
    ) -> str:
        """Waits for the trial's end; returns why it was stopped ("" if it ended by itself).
        What the trial's console says (hrc run's: task events as they come, "waiting for the
        participant: H3", a status line every 15 s) is shown on the session's console too."""
        self.trial_status = ""
        served = False
        gone_at: float | None = None if self.server.connected() else time.monotonic()
        deadline = t0 + self.live.trial_timeout_s
        self.show("starting", title="Starting", text="The trial is starting...")
        told = t0
        cond = ", ".join(f"{k} = {v!r}" for k, v in ts.condition.items())
        while True:
            if time.monotonic() - told >= STATUS_EVERY_S:
                told = time.monotonic()
                el = int(told - t0)
                page = "page connected" if gone_at is None else "PAGE GONE"
                state = "running" if served else "starting"
                self.say(
                    f"trial {ts.index}/{len(self.state.trials)} {ts.id} ({cond}): {state} "
                    f"{el // 60}:{el % 60:02d}, {page}"
                    + (f" | {self.trial_status}" if self.trial_status else "")
                )
            for line in tl.new_lines():
                if line.startswith("status: "):
                    self.trial_status = line.removeprefix("status: ")
                elif line.startswith(("[task", "run ended:", "trial FAILED")):
                    self.say(f"{ts.id}: {line}")
            if not served and _serving(self.opts.host, port):
                served = True
                self.show("trial", port=port, trial=ts.id)
                self.say(f"trial {ts.id} running (spectators: http://127.0.0.1:{port}/)")
            now = time.monotonic()
            if not served and now - t0 > BRIDGE_START_S:
                return self._stop(
                    proc, f"the trial's bridge did not serve within {BRIDGE_START_S:g} s"
                )
            if now > deadline:
                return self._stop(
                    proc,
                    f"timed out after {self.live.trial_timeout_s:g} s of wall time "
                    "(trial_timeout_s)",
                )
            if gone_at is not None and now - gone_at > PAGE_GRACE_S:
                return self._stop(
                    proc, f"the participant's page closed (gone for {PAGE_GRACE_S:g} s)"
                )
            try:
                kind, msg = self.inbox.get(timeout=0.25)
            except queue.Empty:
                continue
            if kind == "exit":
                return ""
            if kind == "gone":
                gone_at = time.monotonic()
                self.say(
                    "participant's page gone during the trial: it fails unless the page is back "
                    "within "
                    f"{PAGE_GRACE_S:g} s"
                )
            elif kind == "connected":
                gone_at = None
                self.say("participant's page back")
                if served:
                    self.show("trial", port=port, trial=ts.id)
            elif kind == "cmd":
                why = self._command(msg["c"], running=ts, text=msg.get("text", ""))
                if why:
                    return self._stop(proc, why)

    def _stop(self, proc: subprocess.Popen[Any], why: str) -> str:
        self.say(f"stopping the trial: {why}")
        stop_process(proc, STOP_GRACE_S)
        with contextlib.suppress(queue.Empty):  # its exit notice
            while True:
                kind, msg = self.inbox.get(timeout=2.0)
                if kind == "exit":
                    break
                self.inbox.put((kind, msg))
                time.sleep(0.05)
        return why

    # ------------------------------------------------------------------ the experimenter
    def _read_commands(self) -> None:
        stream = sys.stdin
        if stream is None or not stream.readable():
            return
        with contextlib.suppress(OSError, ValueError):
            for line in stream:
                c = line.strip().lower()[:1]
                if c:
                    self.inbox.put(("cmd", {"c": c, "text": line.strip()[1:].strip()}))

    def _command(self, c: str, running: st.TrialState | None, text: str = "") -> str:
        """Does what the experimenter typed; a reason to stop the running trial, or ""."""
        if c == "?":
            self.say(self.status())
        elif c in ("n", "f"):
            self._annotate(c == "f", text, running)
        elif c == "p":
            self.paused = not self.paused
            self.say(
                "pause: the session holds before its next step" if self.paused else "pause lifted"
            )
        elif c == "r":
            if running is None:
                self.say("r: no trial is running (r repeats the trial in progress)")
            else:
                return "repeated by the experimenter"
        elif c == "s":
            if running is not None:
                return "skipped by the experimenter"
            nxt = next((t for t in self.state.trials if not t.done), None)
            if nxt is not None:
                nxt.status, nxt.reason = "skipped", "skipped by the experimenter"
                self.state.note(f"trial {nxt.id} skipped")
                self._save()
                self.say(f"skipped {nxt.id}")
                self.inbox.put(("page", {"type": "start", "screen": self.screen_id}))
        elif c == "e":
            if running is not None:
                return "ended by the experimenter"
            self.state.status = "ended"
            self._save()
            raise SessionEnd(
                "session ended by the experimenter: resume with the same command "
                f"({self.status()})",
                0,
            )
        else:
            self.say(HELP)
        return ""

    def _annotate(self, flag: bool, text: str, running: st.TrialState | None) -> None:
        """`n TEXT` / `f [TEXT]`: a note on, or a flag for, the trial in progress or else the
        last one run (before any trial: the session's own notes); kept in session.json and in
        the table's `notes` and `flagged` columns."""
        if not flag and not text:
            self.say("n TEXT: type the note after the n (n the participant sneezed)")
            return
        tried = [t for t in self.state.trials if t.attempts]
        on = running or (tried[-1] if tried else None)
        note = {"at": st.now_iso(), "text": text, **({"flag": True} if flag else {})}
        (on.notes if on is not None else self.state.notes).append(note)
        self._save()
        what = "flagged" if flag else "note"
        self.say(f"{what} on {on.id if on else 'the session'}" + (f": {text}" if text else ""))


class TrialLog:
    """The lines a trial's `hrc run` adds to its log (its console: stdout and stderr), as they
    come; a line still being written waits for its end."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._offset = 0
        self._partial = b""

    def new_lines(self) -> list[str]:
        try:
            with open(self.path, "rb") as f:
                f.seek(self._offset)
                data = f.read(1 << 20)
        except OSError:
            return []
        self._offset += len(data)
        *lines, self._partial = (self._partial + data).split(b"\n")
        return [ln.decode("utf-8", "replace").rstrip("\r") for ln in lines]


def _serving(host: str, port: int) -> bool:
    h = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    try:
        with urllib.request.urlopen(f"http://{h}:{port}/", timeout=1) as r:
            return bool(r.status == 200)
    except OSError:
        return False
