"""The study file (docs/studies.md): parse, check in full, and expand into trials.

    study = load_study("studies/thesis-speed-anticipation.toml")   # StudyError lists problems
    for trial in study.trials: ...                                   # resolved scenarios

A trial is (condition, participant, repetition); its scenario is the base scenario with the
condition's factor values and the participant's parameters written into the parsed TOML, checked
with the project's scenario checks (`hrc.scenario.loads`).
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hrc import scenario as sc
from hrc.scenario.paths import find_project_root, installed_root, resolve_path
from hrc.study import live as live_spec
from hrc.study.live import LiveSpec, LiveTrialPlan
from hrc.tomlw import dumps

FORMAT_VERSION = 1  # part of every trial's input hash: bump when a resolved input changes meaning
DESIGNS = ("factorial", "list")
DISTS = ("normal", "uniform")
PARTICIPANT_PARAMS = tuple(sc.ScriptedParams.model_fields)
# keys of [study]
STUDY_KEYS = {"name", "scenario", "repetitions", "design", "description", "record", "seeds"}
REPETITION_SEED_STRIDE = 100_000  # repetition r > 1 of a participant: seed + (r - 1) * stride
# study.seeds: "participant" (default): a participant's trials of every condition share a seed
# (common random numbers: a comparison between conditions sees no noise of its own); "trial":
# each trial its own seed, as a real person's noise differs from one trial to the next.
SEEDS = ("participant", "trial")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_SHORT = {
    "max_tcp_speed": "speed",
    "anticipation": "ant",
    "safety_policy": "pol",
    "stall_timeout_s": "stall",
    "reaction_time_s": "rt",
    "peak_hand_speed": "hand",
}


class StudyError(Exception):
    """A study that cannot run: `problems` lists every problem found ("key: message")."""

    def __init__(self, problems: list[str], source: str | Path = "<study>") -> None:
        self.problems = list(problems)
        self.source = str(source)
        super().__init__("\n".join(f"{self.source}: {p}" for p in self.problems))


@dataclass(frozen=True)
class Dist:
    """A participant parameter: a fixed value, or a seeded draw from a distribution."""

    kind: str  # "fixed" | "normal" | "uniform"
    value: Any = None
    mean: float = 0.0
    sd: float = 0.0
    min: float = -math.inf
    max: float = math.inf

    def draw(self, rng: np.random.Generator) -> Any:
        if self.kind == "fixed":
            return self.value
        if self.kind == "uniform":
            return round(float(rng.uniform(self.min, self.max)), 6)
        # normal, truncated to [min, max] by drawing again (clipped after 100 tries)
        for _ in range(100):
            x = float(rng.normal(self.mean, self.sd))
            if self.min <= x <= self.max:
                return round(x, 6)
        return round(min(max(x, self.min), self.max), 6)


@dataclass(frozen=True)
class Person:
    """One participant of a study: simulated (parameters drawn) or a replay file."""

    id: str
    seed: int
    params: dict[str, Any] = field(default_factory=dict)
    replay: Path | None = None
    fitted_from: str | None = None  # a twin: the participant whose recordings it was fitted to


@dataclass(frozen=True)
class Trial:
    id: str
    condition: dict[str, Any]  # factor key -> value
    person: Person
    repetition: int
    seed: int
    scenario_text: str  # the resolved scenario, TOML
    input_hash: str


@dataclass
class Study:
    name: str
    path: Path
    scenario: Path
    design: str
    repetitions: int
    factors: dict[str, list[Any]]  # factor key -> its levels (list design: the values seen)
    conditions: list[dict[str, Any]]
    people: list[Person]
    dists: dict[str, Dist]
    text: str
    trials: list[Trial] = field(default_factory=list)
    live: LiveSpec | None = None
    record: bool = False  # each simulated trial records its participant's input
    seeds: str = "participant"  # study.seeds: one seed per participant, or per trial
    # the parsed base scenario (paths made portable) and where it is: live trials resolve from it
    base_raw: dict[str, Any] = field(default_factory=dict)
    base_folder: Path | None = None

    def live_trials(self, participant: str) -> list[LiveTrial]:
        """A live participant's trials in their session's order (practice first), each with its
        resolved scenario: the condition's values, the participant's id, input "vr"."""
        if self.live is None or participant not in self.live.participants:
            raise KeyError(participant)
        out: list[LiveTrial] = []
        for plan in self.live.plan(participant, self.conditions, self.repetitions, trial_id):
            cond = self.conditions[plan.condition_index]
            overrides = {"participant.name": participant, "participant.input": "vr", **cond}
            text = dumps(apply_overrides(self.base_raw, overrides))
            out.append(LiveTrial(plan, cond, text, input_hash(text, plan.seed)))
        return out


@dataclass(frozen=True)
class LiveTrial:
    plan: LiveTrialPlan
    condition: dict[str, Any]
    scenario_text: str
    input_hash: str

    @property
    def id(self) -> str:
        return self.plan.id


# ---------------------------------------------------------------- factor paths


def _targets(raw: dict[str, Any], key: str) -> tuple[list[list[str]], str | None]:
    """The concrete paths a dotted factor key names in the parsed scenario (`*` matches every key
    of a table), or a problem."""
    parts = key.split(".")
    if any(not p for p in parts) or len(parts) < 2:
        return [], "not a dotted scenario key (e.g. robots.*.max_tcp_speed)"
    paths: list[list[str]] = [[]]
    for depth, part in enumerate(parts[:-1]):
        nxt: list[list[str]] = []
        for path in paths:
            node: Any = raw
            for p in path:
                node = node[p]
            if part == "*":
                if not isinstance(node, dict) or not node:
                    where = ".".join(path) or "the scenario"
                    return [], f"'*' needs a table of ids at {where}"
                nxt.extend([*path, k] for k in node)
            elif isinstance(node, dict) and (part in node or depth == 0):
                # a top-level table the base scenario leaves out ([conditions]) may be set;
                # a misspelt one is then an unknown key for the scenario checks
                node.setdefault(part, {})
                nxt.append([*path, part])
            else:
                return [], f"the scenario has no table {'.'.join([*path, part])}"
        paths = nxt
    if parts[-1] == "*":
        return [], "the last part must name a key, not '*'"
    return [[*path, parts[-1]] for path in paths], None


def apply_overrides(raw: dict[str, Any], values: dict[str, Any]) -> dict[str, Any]:
    """A copy of the parsed scenario with each dotted key set (see `_targets`)."""
    out = copy.deepcopy(raw)
    for key, value in values.items():
        paths, problem = _targets(out, key)
        if problem:
            raise KeyError(f"{key}: {problem}")
        for path in paths:
            node = out
            for p in path[:-1]:
                node = node.setdefault(p, {})
            node[path[-1]] = value
    return out


# ---------------------------------------------------------------- parsing


def _parse_dist(key: str, spec: Any, problems: list[str]) -> Dist | None:
    where = f"participants.{key}"
    if key not in PARTICIPANT_PARAMS:
        problems.append(
            f"{where}: not a participant parameter (one of {', '.join(PARTICIPANT_PARAMS)})"
        )
        return None
    if not isinstance(spec, dict):
        return Dist("fixed", value=spec)
    kind = spec.get("dist")
    if kind not in DISTS:
        problems.append(f"{where}.dist: should be one of {', '.join(DISTS)} (got {kind!r})")
        return None
    allowed = {"dist", "min", "max"} | ({"mean", "sd"} if kind == "normal" else set())
    for extra in sorted(set(spec) - allowed):
        problems.append(f"{where}.{extra}: unknown key for a {kind} distribution")
    nums: dict[str, float] = {}
    for name in sorted(allowed - {"dist"}):
        if name not in spec:
            if kind == "uniform" or name in ("mean", "sd"):
                problems.append(f"{where}.{name}: missing")
            continue
        v = spec[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            problems.append(f"{where}.{name}: should be a finite number (got {v!r})")
            continue
        nums[name] = float(v)
    lo, hi = nums.get("min", -math.inf), nums.get("max", math.inf)
    if lo > hi:
        problems.append(f"{where}: min {lo} is above max {hi}")
    if nums.get("sd", 0.0) < 0:
        problems.append(f"{where}.sd: should be >= 0")
    if kind == "normal" and "mean" in nums and not lo <= nums["mean"] <= hi:
        problems.append(f"{where}.mean: {nums['mean']} is outside [min, max]")
    return Dist(kind, mean=nums.get("mean", 0.0), sd=nums.get("sd", 0.0), min=lo, max=hi)


def _find(written: str, folder: Path) -> Path | None:
    path = Path(written).expanduser()
    if path.is_absolute():
        return path if path.is_file() else None
    for base in (folder, find_project_root(folder)):
        if base is not None and (base / path).is_file():
            return (base / path).resolve()
    return None


def _people(
    section: Any, folder: Path, problems: list[str]
) -> tuple[list[Person], dict[str, Dist]]:
    if not isinstance(section, dict):
        problems.append("participants: missing table [participants] (n, seed_base, ...)")
        return [], {}
    section = dict(section)
    n = section.pop("n", 0)
    seed_base = section.pop("seed_base", 1000)
    replays = section.pop("replay", [])
    fitted_written = section.pop("fitted", None)
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        problems.append(f"participants.n: should be an integer >= 0 (got {n!r})")
        n = 0
    if isinstance(seed_base, bool) or not isinstance(seed_base, int) or seed_base < 0:
        problems.append(f"participants.seed_base: should be an integer >= 0 (got {seed_base!r})")
        seed_base = 0
    if not isinstance(replays, list) or not all(isinstance(r, str) for r in replays):
        problems.append("participants.replay: should be a list of file paths")
        replays = []
    dists: dict[str, Dist] = {}
    for key, spec in section.items():
        d = _parse_dist(key, spec, problems)
        if d is not None:
            dists[key] = d
    people: list[Person] = []
    width = max(2, len(str(n)))
    for i in range(1, n + 1):
        seed = seed_base + i
        rng = np.random.default_rng(seed)
        params = {k: d.draw(rng) for k, d in dists.items()}  # in file order: deterministic
        people.append(Person(f"P{i:0{width}d}", seed, params))
    if fitted_written is not None:
        # what the fit does not estimate, a fixed value here gives the twins too
        fixed = {k: d.value for k, d in dists.items() if d.kind == "fixed"}
        people += _twins(fitted_written, folder, seed_base + n + len(replays), fixed, problems)
    for j, written in enumerate(replays, start=1):
        path = _find(written, folder)
        if path is None:
            problems.append(f"participants.replay[{j - 1}]: no such file {written!r}")
            continue
        people.append(Person(f"R{j:02d}", seed_base + n + j, {}, path))
    if not people and not problems:
        problems.append("participants: no participant (set n > 0 or give replay files)")
    return people, dists


def _twins(
    written: Any, folder: Path, seed0: int, fixed: dict[str, Any], problems: list[str]
) -> list[Person]:
    """The simulated twins of a `participants.fitted` table (`hrc fit`'s fitted.toml): one
    scripted participant per person, with the parameters fitted to their recordings."""
    where = "participants.fitted"
    if not isinstance(written, str):
        problems.append(f"{where}: should be the path of a fitted.toml (hrc fit)")
        return []
    path = _find(written, folder)
    if path is None:
        problems.append(f"{where}: no such file {written!r}")
        return []
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8")).get("fitted")
    except (OSError, tomllib.TOMLDecodeError) as exc:
        problems.append(f"{where}: {path}: cannot read: {exc}")
        return []
    if not isinstance(table, dict) or not table:
        problems.append(f"{where}: {path} has no [fitted.<participant>] table")
        return []
    twins = []
    for i, (who, values) in enumerate(sorted(table.items()), start=1):
        if not isinstance(values, dict):
            problems.append(f"{where}: {path}: fitted.{who} should be a table")
            continue
        params = {**fixed, **{k: v for k, v in values.items() if k in PARTICIPANT_PARAMS}}
        twins.append(Person(f"{who}-twin", seed0 + i, params, fitted_from=str(who)))
    return twins


def _conditions(raw: dict[str, Any], design: str, problems: list[str]) -> list[dict[str, Any]]:
    factors = raw.get("factors", {})
    listed = raw.get("conditions", [])
    if not isinstance(factors, dict):
        problems.append("factors: should be a table of dotted keys -> lists of values")
        factors = {}
    if design == "factorial":
        if listed:
            problems.append('conditions: only with design = "list" (use [factors] here)')
        levels: dict[str, list[Any]] = {}
        for key, values in factors.items():
            if not isinstance(values, list) or not values:
                problems.append(f"factors.{key}: should be a non-empty list of values")
                continue
            if len({repr(v) for v in values}) != len(values):
                problems.append(f"factors.{key}: a value is listed twice")
            levels[key] = values
        combos = itertools.product(*levels.values())
        return [dict(zip(levels, combo, strict=True)) for combo in combos]
    if factors:
        problems.append('factors: only with design = "factorial" (use [[conditions]] here)')
    if not isinstance(listed, list) or not listed or not all(isinstance(c, dict) for c in listed):
        problems.append('conditions: design = "list" needs [[conditions]] tables')
        return []
    keys = list(dict.fromkeys(k for c in listed for k in c))
    for i, c in enumerate(listed):
        missing = [k for k in keys if k not in c]
        if missing:
            problems.append(
                f"conditions[{i}]: missing {', '.join(missing)} (every condition "
                "sets the same keys)"
            )
    return [dict(c) for c in listed]


def _portable_paths(raw: dict[str, Any], folder: Path) -> None:
    """Rewrite file paths (robot URDFs, a replay file) so the resolved scenario works from any
    folder: relative to the installed project when the file is inside it (a cluster worker has
    its own copy), else absolute."""
    root = installed_root().resolve()
    project = find_project_root(folder)

    def fix(written: str) -> str:
        found = resolve_path(written, folder, project)
        if found is None:
            return written  # the scenario check names it
        try:
            return str(found.resolve().relative_to(root))
        except ValueError:
            return str(found)

    for robot in (raw.get("robots") or {}).values():
        if isinstance(robot, dict) and isinstance(robot.get("urdf"), str):
            robot["urdf"] = fix(robot["urdf"])
    part = raw.get("participant")
    if isinstance(part, dict) and isinstance(part.get("replay_file"), str):
        part["replay_file"] = fix(part["replay_file"])


def _short(key: str, value: Any) -> str:
    last = key.rsplit(".", 1)[-1]
    name = _SHORT.get(last, last)
    text = (
        {True: "True", False: "False"}.get(value, str(value))
        if isinstance(value, bool)
        else (f"{value:g}" if isinstance(value, float) else str(value))
    )
    return re.sub(r"[^A-Za-z0-9.\-]+", "-", f"{name}{text}")


def trial_id(condition: dict[str, Any], person: str, repetition: int) -> str:
    """e.g. ``speed0.5_antTrue_P03_r1``: the factor values, participant and repetition."""
    return "_".join([*(_short(k, v) for k, v in condition.items()), person, f"r{repetition}"])


def trial_seed(seed: int, condition: dict[str, Any]) -> int:
    """A seed of its own for a participant's trial in `condition` (`study.seeds = "trial"`):
    derived from the participant's seed and the condition's values, so it does not depend on
    which other conditions or people the study has."""
    text = json.dumps(condition, sort_keys=True, default=str)
    return int.from_bytes(hashlib.sha256(f"{seed}|{text}".encode()).digest()[:4], "big") >> 1


def input_hash(scenario_text: str, seed: int) -> str:
    data = f"v{FORMAT_VERSION}\nseed={seed}\n{scenario_text}".encode()
    return hashlib.sha256(data).hexdigest()[:16]


def load_study(
    path: str | Path,
    *,
    motion_check: bool = True,
    participants: int | None = None,
    seeds: str | None = None,
) -> Study:
    """Read and check a study file, and resolve every trial's scenario; StudyError lists every
    problem (the study's own, then each distinct scenario problem with the condition it comes
    from). `participants` and `seeds` replace the file's `participants.n` and `study.seeds`
    (`hrc power` simulates its own pool of people)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
        raw = tomllib.loads(text)
    except OSError as exc:
        raise StudyError([f"file: cannot read: {exc.strerror or exc}"], path) from exc
    except tomllib.TOMLDecodeError as exc:
        raise StudyError([f"toml: not valid TOML: {exc}"], path) from exc
    folder = path.resolve().parent
    problems: list[str] = []
    if participants is not None and isinstance(raw.get("participants"), dict):
        raw["participants"]["n"] = participants
    tables = {"study", "factors", "conditions", "participants", "live", "questionnaires"}
    for extra in sorted(set(raw) - tables):
        problems.append(f"{extra}: unknown table")
    head = raw.get("study")
    if not isinstance(head, dict):
        raise StudyError([*problems, "study: missing table [study] (name, scenario)"], path)
    for extra in sorted(set(head) - STUDY_KEYS):
        problems.append(f"study.{extra}: unknown key")
    name = head.get("name", "")
    if not isinstance(name, str) or not _NAME.match(name):
        problems.append(f"study.name: letters, digits, '_', '-', '.' (got {name!r})")
    design = head.get("design", "factorial")
    if design not in DESIGNS:
        problems.append(f"study.design: should be one of {', '.join(DESIGNS)} (got {design!r})")
        design = "factorial"
    record = head.get("record", False)
    if not isinstance(record, bool):
        problems.append(f"study.record: should be true or false (got {record!r})")
        record = False
    seeds = seeds or head.get("seeds", "participant")
    if seeds not in SEEDS:
        problems.append(f"study.seeds: should be one of {', '.join(SEEDS)} (got {seeds!r})")
    reps = head.get("repetitions", 1)
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 1:
        problems.append(f"study.repetitions: should be an integer >= 1 (got {reps!r})")
        reps = 1
    base_written = head.get("scenario")
    base = _find(base_written, folder) if isinstance(base_written, str) else None
    if base is None:
        problems.append(f"study.scenario: no such scenario file {base_written!r}")
    conditions = _conditions(raw, design, problems)
    live = live_spec.parse(raw.get("live"), raw.get("questionnaires"), folder, conditions, problems)
    if live is not None and "participants" not in raw:
        people: list[Person] = []  # a study with people only
        dists: dict[str, Dist] = {}
    else:
        people, dists = _people(raw.get("participants"), folder, problems)
    if live is not None:
        clash = set(live.participants) & {p.id for p in people}
        if clash:
            problems.append(
                f"live.participants: {sorted(clash)[0]!r} is also a simulated participant's id"
            )
    if problems or base is None:
        raise StudyError(problems, path)

    base_text = base.read_text(encoding="utf-8")
    try:
        base_raw = tomllib.loads(base_text)
    except tomllib.TOMLDecodeError as exc:
        raise StudyError([f"study.scenario: {base}: not valid TOML: {exc}"], path) from exc
    # every factor key must name something in the scenario
    keys = list(dict.fromkeys(k for c in conditions for k in c))
    for key in keys:
        _paths, problem = _targets(copy.deepcopy(base_raw), key)
        if problem:
            where = "factors" if design == "factorial" else "conditions"
            problems.append(f"{where}.{key}: {problem}")
    if problems:
        raise StudyError(problems, path)
    _portable_paths(base_raw, base.parent)
    root = find_project_root(base.parent)

    study = Study(
        name=name,
        path=path.resolve(),
        scenario=base,
        design=design,
        repetitions=reps,
        factors={k: _levels(conditions, k) for k in keys},
        conditions=conditions,
        people=people,
        dists=dists,
        text=text,
        live=live,
        record=record,
        seeds=seeds,
        base_raw=base_raw,
        base_folder=base.parent,
    )
    seen: set[str] = set()
    checked: set[str] = set()
    for cond in conditions:
        for person in people:
            overrides: dict[str, Any] = {"participant.name": person.id}
            if person.replay is not None:
                overrides["participant.input"] = "replay"
                overrides["participant.replay_file"] = str(person.replay)
            overrides.update({f"participant.{k}": v for k, v in person.params.items()})
            overrides.update(cond)  # a factor wins over a drawn parameter
            resolved = apply_overrides(base_raw, overrides)
            try:
                scen_text = dumps(resolved)
            except (TypeError, ValueError) as exc:
                problems.append(f"{_cond_name(cond)}: {exc}")
                continue
            # the motion check depends on the robots and parts only: once per distinct layout
            layout = repr({k: resolved.get(k) for k in ("robots", "parts", "sequence")})
            want_motion = motion_check and layout not in checked
            try:
                sc.loads(scen_text, folder=base.parent, project_root=root, motion_check=want_motion)
                checked.add(layout)
            except sc.ScenarioError as exc:
                for p in exc.problems:
                    who = f" ({person.id})" if p.key.startswith("participant.") else ""
                    line = f"{_cond_name(cond)}{who}: {p.key}: {p.message}"
                    if line not in seen:
                        seen.add(line)
                        problems.append(line)
                continue
            for rep in range(1, reps + 1):
                seed = person.seed + (rep - 1) * REPETITION_SEED_STRIDE
                if seeds == "trial":
                    seed = trial_seed(seed, cond)
                tid = trial_id(cond, person.id, rep)
                study.trials.append(
                    Trial(tid, cond, person, rep, seed, scen_text, input_hash(scen_text, seed))
                )
    if live is not None:
        for cond in conditions:  # a live trial's scenario: the condition with input "vr"
            overrides = {
                "participant.name": live.participants[0],
                "participant.input": "vr",
                **cond,
            }
            try:
                sc.loads(
                    dumps(apply_overrides(base_raw, overrides)),
                    folder=base.parent,
                    project_root=root,
                )
            except (TypeError, ValueError) as exc:
                problems.append(f"{_cond_name(cond)} (live): {exc}")
            except sc.ScenarioError as exc:
                for p in exc.problems:
                    line = f"{_cond_name(cond)} (live): {p.key}: {p.message}"
                    if line not in seen:
                        seen.add(line)
                        problems.append(line)
    ids = [t.id for t in study.trials]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        problems.append(f"trial ids repeat (two factor values print alike): {', '.join(dup[:5])}")
    if problems:
        raise StudyError(problems, path)
    return study


def _levels(conditions: list[dict[str, Any]], key: str) -> list[Any]:
    out: list[Any] = []
    for c in conditions:
        if key in c and all(repr(c[key]) != repr(v) for v in out):
            out.append(c[key])
    return out


def _cond_name(cond: dict[str, Any]) -> str:
    return "condition " + (", ".join(f"{k} = {v!r}" for k, v in cond.items()) or "(base)")
