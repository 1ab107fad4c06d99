"""``hrc fit``: a person's scripted-participant parameters from the recordings of their trials.

Each trial gives the participant's input as recorded (`participant-input.jsonl`, the replay
format) and what happened (`events.jsonl`: grabs, placements, the outline cues). From them:

- **Movements**: intervals where the active hand moves faster than `ONSET_SPEED`. A minimum-jerk
  move spends a known share of its time and path below any threshold, so each interval's
  duration and path are corrected back to the whole move's (`_jerk_share`).
- **What each move was**: by where it ends, relative to the grasp and release points the events
  give: onto or above a part before it is grabbed (a reach: the model's 6 cm width), onto its
  release point while held (2 x the placement tolerance), above it while held (6 cm), straight up
  from the grasp (a lift: 10 cm). Other moves (to rest, withdrawals) only count for the speed cap.
- **Movement time law** MT = a + b log2(2D/W) + c D: non-negative least squares over the moves
  the peak-speed cap did not shorten; `peak_hand_speed` is the highest peak seen (a lower bound
  when no move reached the cap, said in `notes`).
- **Reaction time**: from a part's outline cue (or the end of the hand's previous move, if later)
  to the onset of the reach for it; the median, as the model's parameter is a median. Its
  standard error is the reactions' own log spread over the square root of their number: with the
  model's spread (0.25) and the thesis's six reactions a trial, about 7 % from two trials, so
  a person's estimate misses by up to about 15 % by chance alone, whatever their caution.
- **What the moves can tell apart** (`uncertainty`): a and b are resampled with the moves
  (`BOOTSTRAP` resamples, seeded); their relative standard errors and correlation are given. On
  a task whose moves have few distinct difficulties a and b trade off (a longer a, a smaller b
  fit the same moves): where they cannot be told apart (`AB_LOCKSTEP`, `AB_CORRELATION`,
  `AB_REL_SE`) b is held at the profile's value and only a (and c) fitted, said in `notes`.
  The movement time law is checked on moves it did not use: each move left out once, predicted
  by the law fitted to the others (`mt_heldout_error`, mean absolute relative error).
- **Dwells and grip**: the grip's closing and opening ramps; the pause between arriving at a part
  and leaving with it (`pick_dwell_s`); twice the pause between arriving at the target and
  starting to let go (`place_dwell_s`).
- `stop_above`: whether reaches come in two moves (stop above the part, then descend).

Not estimated (left to the profile or study): caution, collision reaction, placement error,
hold-back limits, handedness.
"""

from __future__ import annotations

import itertools
import json
import math
import statistics
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from hrc.geometry import Vec3, distance
from hrc.metrics import EVENTS_FILE
from hrc.participant.motor import MIN_JERK_PEAK_FACTOR, REACTION_LOG_SD, fitts_index
from hrc.participant.plans import GROSS_WIDTH, PICK_WIDTH
from hrc.participant.recording import load_recording
from hrc.scenario.models import DEFAULT_TOLERANCE_M, ScriptedParams
from hrc.study.trial import RECORDING_FILE

Array = npt.NDArray[np.float64]
ONSET_SPEED = 0.03  # m/s: a hand faster than this moves
NEAR_M = 0.03  # a move ending this close to a grasp / release point ends there
ABOVE_XY_M = 0.02  # ... this close in x, y (and higher) ends above it
CAP_SHARE = 0.99  # a move whose peak is this close to the highest peak was capped ...
CAP_MOVES = 3  # ... when at least this many moves peak there
# c (the transport term) is fitted only when 3 uncapped moves are this many times longer than the
# shortest: on moves of one length it cannot be told from the intercept
C_SPAN = 2.0
ONSET_LAG_S = 0.05  # a move this long before the cue's record may already answer it
TRIM_SD = 2.5  # reactions further than this many log-sds from their median are not counted
SCENARIO_FILE = "scenario.toml"  # the trial's resolved scenario (hrc run writes it)
BOOTSTRAP = 200  # resamples of the moves for a's and b's uncertainty
BOOTSTRAP_SEED = 0  # a person's fit is the same every time
# a and b cannot be told apart when they move in lockstep across resamples (|correlation| at
# least AB_LOCKSTEP; the thesis task's recordings reach 0.97 with b known to 10 %), or nearly so
# (AB_CORRELATION) with b's standard error above AB_REL_SE of b
AB_LOCKSTEP = 0.99
AB_CORRELATION = 0.95
AB_REL_SE = 0.5
B_PROFILE = float(ScriptedParams.model_fields["fitts_b_s"].default)  # b held here, then


class FitError(ValueError):
    """Recordings from which no parameter can be estimated (the message says why)."""


@dataclass(frozen=True)
class Move:
    t_on: float  # onset, corrected to the whole move
    t_end: float
    p0: Vec3
    p1: Vec3
    path_m: float  # the whole move's path
    peak: float  # m/s, highest sampled speed

    @property
    def mt(self) -> float:
        return self.t_end - self.t_on


@dataclass
class TrialMeasures:
    """What one trial shows of the person."""

    trial: str
    moves: list[Move] = field(default_factory=list)
    classified: list[tuple[Move, float]] = field(default_factory=list)  # (move, Fitts width)
    reactions_s: list[float] = field(default_factory=list)
    pick_dwells_s: list[float] = field(default_factory=list)
    place_half_dwells_s: list[float] = field(default_factory=list)
    grip_close_s: list[float] = field(default_factory=list)
    grip_open_s: list[float] = field(default_factory=list)
    reach_moves: list[int] = field(default_factory=list)  # moves per reach


def _jerk_share(fraction_of_peak: float) -> tuple[float, float]:
    """For a minimum-jerk move, the share of its time and of its path spent below
    ``fraction_of_peak`` of its peak speed at each end (tau_1, s(tau_1))."""
    f = min(max(fraction_of_peak, 0.0), 1.0)
    # speed / peak = 16 tau^2 (1 - tau)^2  ->  4 tau (1 - tau) = sqrt(f)
    tau = (1.0 - math.sqrt(max(0.0, 1.0 - math.sqrt(f)))) / 2.0
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
    return tau, s


def segment_moves(ts: Array, pos: Array) -> list[Move]:
    """The hand's moves: runs of samples faster than ONSET_SPEED, corrected to whole moves."""
    if len(ts) < 3:
        return []
    # A live client updates the hand at its own rate and the recording holds the last pose
    # between updates: speeds are taken between distinct poses (a still hand's samples are all
    # one pose, so it stays still).
    keep = np.concatenate(([True], np.any(np.diff(pos, axis=0) != 0.0, axis=1)))
    keep[-1] = True
    ts, pos = ts[keep], pos[keep]
    if len(ts) < 3:
        return []
    dt = np.diff(ts)
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    speed = np.divide(step, dt, out=np.zeros_like(step), where=dt > 0)
    moving = speed > ONSET_SPEED
    moves: list[Move] = []
    i, n = 0, len(speed)
    while i < n:
        if not moving[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and moving[j + 1]:
            j += 1
        # samples i .. j+1 span the run (speed k is between samples k and k+1)
        peak = float(speed[i : j + 1].max())
        if j - i >= 2 and peak > 2.0 * ONSET_SPEED:
            tau, s = _jerk_share(ONSET_SPEED / peak)
            t0, t1 = float(ts[i]), float(ts[j + 1])
            whole = (t1 - t0) / (1.0 - 2.0 * tau)
            path = float(step[i : j + 1].sum()) / (1.0 - 2.0 * s)
            moves.append(
                Move(
                    t0 - tau * whole,
                    t1 + tau * whole,
                    tuple(pos[i]),
                    tuple(pos[j + 1]),
                    path,
                    peak,
                )
            )
        i = j + 1
    return moves


def _read_events(path: Path) -> list[dict[str, Any]]:
    out = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError as exc:
            raise FitError(f"{path}: line {n} is not JSON: {exc.msg}") from exc
    return out


def _at(ts: Array, values: Array, t: float) -> Any:
    """The sample at or just before time t."""
    k = int(np.searchsorted(ts, t, side="right")) - 1
    return values[max(0, min(k, len(values) - 1))]


def _ramps(ts: Array, grip: Array, closing: bool) -> list[tuple[float, float]]:
    """(start, end) of each full grip ramp 0 -> 1 (closing) or 1 -> 0."""
    lo, hi = (0.0, 1.0) if closing else (1.0, 0.0)
    out = []
    start: float | None = None
    for k in range(1, len(grip)):
        prev, cur = grip[k - 1], grip[k]
        if prev == lo and cur != lo and (cur > prev) == closing:
            start = float(ts[k - 1])
        if start is not None and cur == hi:
            out.append((start, float(ts[k])))
            start = None
        elif start is not None and (cur < prev) == closing and cur != prev:
            start = None  # turned back
    return out


def _tolerance_m(folder: Path) -> float:
    """The trial's placement tolerance (its scenario.toml; the default without one)."""
    try:
        raw = tomllib.loads((folder / SCENARIO_FILE).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        return DEFAULT_TOLERANCE_M
    value = raw.get("placement", {}).get("tolerance_m", DEFAULT_TOLERANCE_M)
    return float(value) if isinstance(value, (int, float)) else DEFAULT_TOLERANCE_M


def measure_trial(folder: Path) -> TrialMeasures:
    tolerance_m = _tolerance_m(folder)
    rec_path, ev_path = folder / RECORDING_FILE, folder / EVENTS_FILE
    for p in (rec_path, ev_path):
        if not p.is_file():
            raise FitError(
                f"{folder}: no {p.name} (a trial folder of hrc run --record or a session)"
            )
    recording = load_recording(rec_path)
    events = _read_events(ev_path)
    grabs = [
        e
        for e in events
        if e.get("type") == "event"
        and e.get("kind") == "PART_GRABBED"
        and e.get("agent") == "human"
    ]
    if not grabs:
        raise FitError(f"{folder}: the participant grabbed no part ({ev_path.name})")
    hand = grabs[0].get("hand") or "right"
    samples = recording.samples
    ts = np.array([s.t for s in samples])
    pos = np.array([s.hand(hand).position for s in samples], dtype=float)
    grip = np.array([s.left_grip if hand == "left" else s.right_grip for s in samples])
    m = TrialMeasures(folder.name)
    m.moves = segment_moves(ts, pos)
    m.grip_close_s = [b - a for a, b in _ramps(ts, grip, True)]
    m.grip_open_s = [b - a for a, b in _ramps(ts, grip, False)]

    placed = {
        e["part"]: e["sim_time"]
        for e in events
        if e.get("type") == "event" and e.get("kind") == "PART_PLACED" and e.get("agent") == "human"
    }
    cues: dict[str, float] = {}
    for e in events:
        if e.get("type") == "cue" and e.get("kind") == "OUTLINE" and e.get("on"):
            cues.setdefault(e["part"], e["sim_time"])
    first_grab: dict[str, float] = {}
    for e in grabs:
        first_grab.setdefault(e["part"], e["sim_time"])
    prev_release: Vec3 | None = None
    for part, t_grab in sorted(first_grab.items(), key=lambda kv: kv[1]):
        t_cue = cues.get(part, 0.0)
        # the reaction: from the cue (or the end of the hand's last move, if later) to the onset
        # of the first move towards the part (not the withdrawal from the last part placed)
        first = next(
            (
                mv
                for mv in m.moves
                if t_cue - ONSET_LAG_S <= mv.t_on < t_grab
                and (prev_release is None or distance(mv.p0, prev_release) > NEAR_M)
            ),
            None,
        )
        if first is not None:
            before = [mv.t_end for mv in m.moves if mv.t_end <= first.t_on + 1e-9]
            start = max([t_cue, *before])
            m.reactions_s.append(max(0.0, first.t_on - start))
        if part not in placed:
            continue
        t_place = placed[part]
        grasp = tuple(_at(ts, pos, t_grab))
        # the release: the last time the grip crossed below 0.5 before the placement
        opening = [
            float(ts[k])
            for k in range(1, len(grip))
            if grip[k - 1] >= 0.5 > grip[k] and t_grab < ts[k] <= t_place + 1e-9
        ]
        if not opening:
            continue
        t_release = opening[-1]
        release = tuple(_at(ts, pos, t_release))
        prev_release = release
        reach = [
            mv
            for mv in m.moves
            if t_cue - 1e-9 <= mv.t_end <= t_grab + 1e-9
            and (distance(mv.p1, grasp) <= NEAR_M or _above(mv.p1, grasp))
        ]
        if reach:
            m.reach_moves.append(len(reach))
            m.classified += [(mv, PICK_WIDTH) for mv in reach]
            after = [mv for mv in m.moves if mv.t_on >= reach[-1].t_end - 1e-9]
            if after and after[0].t_on < t_release:
                m.pick_dwells_s.append(after[0].t_on - reach[-1].t_end)
        for mv in m.moves:
            if not (t_grab - 1e-9 <= mv.t_on and mv.t_end <= t_release + 1e-9):
                continue
            if distance(mv.p1, release) <= NEAR_M:
                m.classified.append((mv, 2.0 * tolerance_m))
                if 0.0 <= t_release - mv.t_end < 5.0:
                    m.place_half_dwells_s.append(
                        max(0.0, _grip_start(ts, grip, mv.t_end) - mv.t_end)
                    )
            elif _above(mv.p1, release):
                m.classified.append((mv, PICK_WIDTH))
            elif distance(mv.p0, grasp) <= NEAR_M and math.dist(mv.p0[:2], mv.p1[:2]) < ABOVE_XY_M:
                m.classified.append((mv, GROSS_WIDTH))
    return m


def _above(p: Vec3, q: Vec3) -> bool:
    return math.dist(p[:2], q[:2]) <= ABOVE_XY_M and p[2] - q[2] > NEAR_M


def _grip_start(ts: Array, grip: Array, t: float) -> float:
    """When the grip starts to open after time t."""
    k = int(np.searchsorted(ts, t, side="left"))
    for j in range(max(1, k), len(grip)):
        if grip[j] < grip[j - 1]:
            return float(ts[j - 1])
    return t


def nonnegative_lstsq(x: Array, y: Array) -> Array:
    """Least squares with every coefficient >= 0, for a few columns: the best of the ordinary
    fits over each subset of columns whose coefficients all come out >= 0 (the others 0)."""
    n = x.shape[1]
    best, best_err = np.zeros(n), float(np.sum(y * y))
    for mask in itertools.product((False, True), repeat=n):
        cols = [i for i in range(n) if mask[i]]
        if not cols:
            continue
        sol, *_ = np.linalg.lstsq(x[:, cols], y, rcond=None)
        if np.any(sol < 0.0):
            continue
        coef = np.zeros(n)
        coef[cols] = sol
        err = float(np.sum((x @ coef - y) ** 2))
        if err < best_err - 1e-15:
            best, best_err = coef, err
    return best


def _kept_logs(values: list[float]) -> list[float]:
    """The logs of the reactions within TRIM_SD log-sds of their median (a reaction held up by
    a collision or a robot in the way is not one); empty without a positive value."""
    logs = [math.log(v) for v in values if v > 0.0]
    if not logs:
        return []
    centre = statistics.median(logs)
    return [x for x in logs if abs(x - centre) <= TRIM_SD * REACTION_LOG_SD] or [centre]


def lognormal_median(values: list[float]) -> float:
    """The median of the model's lognormal reaction times (log-sd REACTION_LOG_SD): the mean
    of the kept logs (its estimate with the least spread)."""
    kept = _kept_logs(values)
    return math.exp(statistics.fmean(kept)) if kept else 0.0


def lognormal_rel_se(values: list[float]) -> float:
    """The relative standard error of :func:`lognormal_median`: the kept reactions' log spread
    (at least the model's, as a few draws understate it) over the square root of their
    number."""
    kept = _kept_logs(values)
    if not kept:
        return 0.0
    spread = statistics.stdev(kept) if len(kept) > 1 else REACTION_LOG_SD
    return math.expm1(max(spread, REACTION_LOG_SD) / math.sqrt(len(kept)))


@dataclass
class Fit:
    """A person's estimated parameters, and how they were found."""

    params: dict[str, float | bool]
    counts: dict[str, int]
    notes: list[str]
    # relative standard errors (`<param>_rel_se`), a's and b's correlation, the movement time
    # law's error on moves it did not use (`mt_heldout_error`)
    uncertainty: dict[str, float] = field(default_factory=dict)


def _law(x: Array, y: Array, b_fixed: float | None) -> Array:
    """The movement time law's coefficients (a, b[, c]) >= 0, with b held at `b_fixed` if given."""
    if b_fixed is None:
        return nonnegative_lstsq(x, y)
    rest = [i for i in range(x.shape[1]) if i != 1]
    coef = np.zeros(x.shape[1])
    coef[rest] = nonnegative_lstsq(x[:, rest], y - b_fixed * x[:, 1])
    coef[1] = b_fixed
    return coef


def _ab_spread(x: Array, y: Array) -> tuple[float, float, float]:
    """a's and b's standard deviations over bootstrap resamples of the moves, and their
    correlation (0 where either does not vary)."""
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    draws = np.array(
        [
            nonnegative_lstsq(x[idx], y[idx])[:2]
            for idx in rng.integers(0, len(y), (BOOTSTRAP, len(y)))
        ]
    )
    sd_a, sd_b = (float(v) for v in draws.std(axis=0))
    corr = float(np.corrcoef(draws.T)[0, 1]) if sd_a > 0 and sd_b > 0 else 0.0
    return sd_a, sd_b, corr


def _heldout_error(x: Array, y: Array, b_fixed: float | None) -> float:
    """Mean absolute relative error of each move's time predicted by the law fitted without it."""
    errors = []
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        predicted = float(x[i] @ _law(x[keep], y[keep], b_fixed))
        errors.append(abs(predicted - y[i]) / y[i])
    return float(np.mean(errors))


def fit_measures(trials: list[TrialMeasures]) -> Fit:
    moves = [mv for t in trials for mv in t.moves]
    if not moves:
        raise FitError("no hand movement found in the recordings")
    notes: list[str] = []
    uncertainty: dict[str, float] = {}
    if len(trials) == 1:
        notes.append("rests on one trial: its estimates are less sure than from two (uncertainty)")
    v_peak = max(mv.peak for mv in moves)
    # Moves the cap shortened all peak at the cap; free moves peak where their length and time
    # put them. A cap is seen when several moves share the highest peak.
    at_cap = [mv for mv in moves if mv.peak >= CAP_SHARE * v_peak]
    cap_seen = len(at_cap) >= CAP_MOVES
    classified = [(mv, w) for t in trials for mv, w in t.classified]
    free = [(mv, w) for mv, w in classified if not (cap_seen and mv.peak >= CAP_SHARE * v_peak)]
    if cap_seen:
        # a capped move lasts 1.875 D / v: the cap from those moves' own paths and times
        peak_hand_speed = statistics.median(
            MIN_JERK_PEAK_FACTOR * mv.path_m / mv.mt for mv in at_cap
        )
    else:
        peak_hand_speed = v_peak
        notes.append(
            "no speed cap seen (fewer than "
            f"{CAP_MOVES} moves share the highest peak): peak_hand_speed is the highest peak, "
            "a lower bound"
        )
    params: dict[str, float | bool] = {"peak_hand_speed": round(peak_hand_speed, 4)}
    if len(free) >= 3:
        paths = [mv.path_m for mv, _w in free]
        with_c = sum(d >= C_SPAN * min(paths) for d in paths) >= 3
        x = np.array(
            [[1.0, fitts_index(mv.path_m, w), mv.path_m][: 3 if with_c else 2] for mv, w in free]
        )
        y = np.array([mv.mt for mv, _w in free])
        coef = nonnegative_lstsq(x, y)
        sd_a, sd_b, corr = _ab_spread(x, y)
        b_fixed = None
        rel_b = sd_b / coef[1] if coef[1] > 0 else 0.0
        if abs(corr) >= AB_LOCKSTEP or (abs(corr) >= AB_CORRELATION and rel_b >= AB_REL_SE):
            b_fixed = B_PROFILE
            coef = _law(x, y, b_fixed)
            ids = x[:, 1]
            notes.append(
                f"a and b cannot be told apart on these moves (difficulties {ids.min():.1f}-"
                f"{ids.max():.1f} bits; a and b correlate {corr:+.2f} across resamples, b's "
                f"error {100 * rel_b:.0f} %): b held at the profile's "
                f"{b_fixed:g} s/bit, a fitted"
            )
        else:
            for i, key in enumerate(("fitts_a_s", "fitts_b_s")):
                if coef[i] > 0:
                    uncertainty[f"{key}_rel_se"] = round(float((sd_a, sd_b)[i] / coef[i]), 4)
        uncertainty["fitts_ab_correlation"] = round(corr, 4)
        if len(y) >= 4:
            uncertainty["mt_heldout_error"] = round(_heldout_error(x, y, b_fixed), 4)
        params.update(fitts_a_s=round(float(coef[0]), 4), fitts_b_s=round(float(coef[1]), 4))
        if with_c:
            params["fitts_c_s_per_m"] = round(float(coef[2]), 4)
        else:
            params["fitts_c_s_per_m"] = 0.0
            notes.append(
                f"fewer than 3 uncapped moves over {C_SPAN:g} x the shortest "
                f"({min(paths):.2f} m): fitts_c_s_per_m not fitted (0)"
            )
    else:
        notes.append(f"only {len(free)} uncapped moves of known kind: no movement-time law fitted")
    reactions = [r for t in trials for r in t.reactions_s]
    if reactions:
        params["reaction_time_s"] = round(lognormal_median(reactions), 4)
        uncertainty["reaction_time_s_rel_se"] = round(lognormal_rel_se(reactions), 4)
    grips_c = [g for t in trials for g in t.grip_close_s]
    grips_o = [g for t in trials for g in t.grip_open_s]
    if grips_c:
        params["grip_close_s"] = round(statistics.median(grips_c), 4)
    if grips_o:
        params["grip_open_s"] = round(statistics.median(grips_o), 4)
    picks = [d for t in trials for d in t.pick_dwells_s]
    if picks:
        params["pick_dwell_s"] = round(statistics.median(picks), 4)
    places = [d for t in trials for d in t.place_half_dwells_s]
    if places:
        params["place_dwell_s"] = round(2.0 * statistics.median(places), 4)
    per_reach = [n for t in trials for n in t.reach_moves]
    if per_reach:
        params["stop_above"] = statistics.median(per_reach) >= 2
    counts = {
        "moves": len(moves),
        "moves_of_known_kind": len(classified),
        "moves_capped": len(at_cap) if cap_seen else 0,
        "reactions": len(reactions),
    }
    return Fit(params, counts, notes, uncertainty)


def fit_folders(folders: list[Path]) -> Fit:
    if not folders:
        raise FitError("no trial folder given")
    return fit_measures([measure_trial(f) for f in folders])
