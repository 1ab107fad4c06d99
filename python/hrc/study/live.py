"""Live participants in a study file (`[live]`, docs/studies.md "Running a study with people"):
who they are, the order of their conditions, practice, questionnaires, breaks, and the texts
shown in the page (consent, instructions).

`parse` checks the section in full (problems appended, like the rest of the study file);
`LiveSpec.plan(...)` gives one participant's trials in their order.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hrc.study.order import ORDERS, orders
from hrc.study.questionnaires import Catalogue, Questionnaire
from hrc.study.questionnaires import parse as parse_questionnaire

LIVE_KEYS = {
    "participants",
    "n",
    "order",
    "seed",
    "practice",
    "practice_condition",
    "min_break_s",
    "consent",
    "instructions",
    "instruction",
    "between",
    "blocks",
    "before_session",
    "before_trial",
    "after_trial",
    "end",
    "questionnaire_file",
    "trial_timeout_s",
}
# where a session asks questionnaires, in its order (docs/studies.md)
SLOTS = ("before_session", "before_trial", "after_trial", "end")
_PID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
DEFAULT_TRIAL_TIMEOUT_S = 1800.0  # a live trial's wall time at most (then stopped, failed)
LIVE_SEED_BASE = 7_000_000  # live trial seeds: base + 1000 * participant index + trial index


@dataclass(frozen=True)
class Instruction:
    """A text shown before each trial whose condition has these factor values."""

    when: dict[str, Any]
    text: str
    file: str

    def matches(self, condition: dict[str, Any]) -> bool:
        return all(repr(condition.get(k)) == repr(v) for k, v in self.when.items())


@dataclass(frozen=True)
class LiveTrialPlan:
    """One trial of a live participant's session, before it runs."""

    id: str
    index: int  # 1-based, in the session (practice first)
    condition_index: int  # into the study's conditions
    order_position: int  # 1.. for analysed trials, 0 for practice
    practice: bool
    repetition: int
    seed: int


@dataclass
class LiveSpec:
    participants: list[str]
    order: str = "williams"
    seed: int = 0
    practice: int = 0
    practice_condition: int = 0  # index into the study's conditions
    min_break_s: float = 0.0
    consent: str = ""  # Markdown text ("" : no consent screen)
    consent_file: str = ""
    instructions: str = ""  # Markdown shown once before the first trial
    instructions_file: str = ""
    instruction: list[Instruction] = field(default_factory=list)
    before_session: list[Questionnaire] = field(default_factory=list)  # once, after consent
    before_trial: list[Questionnaire] = field(default_factory=list)  # before each analysed trial
    after_trial: list[Questionnaire] = field(default_factory=list)
    end: list[Questionnaire] = field(default_factory=list)
    trial_timeout_s: float = DEFAULT_TRIAL_TIMEOUT_S
    # between-subject factors: each participant does one level (of their combination) only
    between: list[str] = field(default_factory=list)
    # study.repetitions as blocks: each condition's trials in a row, the blocks in the order
    # (else the whole order again for each repetition)
    blocks: bool = False

    def groups(self, conditions: list[dict[str, Any]]) -> list[list[int]]:
        """The study's conditions by between-subject group (one group: every condition); a
        group's conditions in the study's order. Groups in the order they first appear."""
        keyed: dict[str, list[int]] = {}
        for i, c in enumerate(conditions):
            keyed.setdefault(repr([c.get(f) for f in self.between]), []).append(i)
        return list(keyed.values())

    def orders(self, conditions: list[dict[str, Any]]) -> dict[str, list[int]]:
        """Each participant's conditions (indices into `conditions`) in their order. With
        between-subject factors the roster is dealt over the groups in turn (participant k to
        group k mod G: balanced), and each group's members take the rows of the order (a
        Williams square, say) over its own conditions in turn."""
        groups = self.groups(conditions)
        g = len(groups)
        out: dict[str, list[int]] = {}
        for gi, members in enumerate(groups):
            people = self.participants[gi::g]
            rows = orders(self.order, len(members), len(people), self.seed)
            for pid, row in zip(people, rows, strict=True):
                out[pid] = [members[i] for i in row]
        return out

    def group_of(self, participant: str, conditions: list[dict[str, Any]]) -> list[int]:
        """The conditions of the participant's between-subject group (all without one)."""
        groups = self.groups(conditions)
        return groups[self.participants.index(participant) % len(groups)]

    def plan(
        self, participant: str, conditions: list[dict[str, Any]], repetitions: int, trial_id: Any
    ) -> list[LiveTrialPlan]:
        """The participant's trials: practice, then every condition in their order (the whole
        order again for each repetition, or with `blocks` each condition's repetitions in a
        row). `trial_id(condition, person, repetition)` names them."""
        k = self.participants.index(participant)
        order = self.orders(conditions)[participant]
        out: list[LiveTrialPlan] = []
        # with between-subject factors each practises in their own group's first condition
        practice = self.group_of(participant, conditions)[0] if self.between else None
        practice = self.practice_condition if practice is None else practice
        for p in range(1, self.practice + 1):
            cond = conditions[practice]
            tid = f"practice{p}_{trial_id(cond, participant, 1)}"
            out.append(LiveTrialPlan(tid, len(out) + 1, practice, 0, True, p, 0))
        reps = range(1, repetitions + 1)
        pairs = (
            [(ci, rep) for ci in order for rep in reps]
            if self.blocks
            else [(ci, rep) for rep in reps for ci in order]
        )
        for pos, (ci, rep) in enumerate(pairs, start=1):
            tid = trial_id(conditions[ci], participant, rep)
            out.append(LiveTrialPlan(tid, len(out) + 1, ci, pos, False, rep, 0))
        return [
            LiveTrialPlan(
                t.id,
                t.index,
                t.condition_index,
                t.order_position,
                t.practice,
                t.repetition,
                LIVE_SEED_BASE + 1000 * k + t.index,
            )
            for t in out
        ]

    def instruction_for(self, condition: dict[str, Any]) -> list[Instruction]:
        return [i for i in self.instruction if i.matches(condition)]


def _text_file(where: str, written: Any, folder: Path, problems: list[str]) -> tuple[str, str]:
    """(its text, its path as written) of a Markdown file next to the study."""
    if not isinstance(written, str) or not written:
        problems.append(f"{where}: a Markdown file next to the study (got {written!r})")
        return "", ""
    path = Path(written).expanduser()
    path = path if path.is_absolute() else folder / path
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        problems.append(f"{where}: cannot read {written!r}: {exc.strerror or exc}")
        return "", ""
    except UnicodeDecodeError:
        problems.append(f"{where}: {written!r} is not UTF-8 text")
        return "", ""
    if not text.strip():
        problems.append(f"{where}: {written!r} is empty")
    return text, written


def parse(
    section: Any,
    questionnaires: Any,
    folder: Path,
    conditions: list[dict[str, Any]],
    problems: list[str],
) -> LiveSpec | None:
    """The `[live]` table (and `[questionnaires]`), checked in full."""
    if section is None:
        if questionnaires is not None:
            problems.append("questionnaires: only with a [live] table (who answers them?)")
        return None
    if not isinstance(section, dict):
        problems.append("live: should be a table")
        return None
    for extra in sorted(set(section) - LIVE_KEYS):
        problems.append(f"live.{extra}: unknown key")
    ids = _participants(section, problems)
    spec = LiveSpec(ids)
    order = section.get("order", "williams")
    if order not in ORDERS:
        problems.append(f"live.order: one of {', '.join(ORDERS)} (got {order!r})")
    else:
        spec.order = order
    spec.seed = _int("live.seed", section.get("seed", 0), 0, problems)
    spec.practice = _int("live.practice", section.get("practice", 0), 0, problems)
    spec.practice_condition = _practice_condition(
        section.get("practice_condition"), conditions, problems
    )
    brk = section.get("min_break_s", 0)
    if isinstance(brk, bool) or not isinstance(brk, (int, float)) or not 0 <= brk <= 3600:
        problems.append(f"live.min_break_s: seconds, 0..3600 (got {brk!r})")
    else:
        spec.min_break_s = float(brk)
    tmo = section.get("trial_timeout_s", DEFAULT_TRIAL_TIMEOUT_S)
    if isinstance(tmo, bool) or not isinstance(tmo, (int, float)) or not 30 <= tmo <= 86400:
        problems.append(f"live.trial_timeout_s: seconds, 30..86400 (got {tmo!r})")
    else:
        spec.trial_timeout_s = float(tmo)
    if "consent" in section:
        spec.consent, spec.consent_file = _text_file(
            "live.consent", section["consent"], folder, problems
        )
    if "instructions" in section:
        spec.instructions, spec.instructions_file = _text_file(
            "live.instructions", section["instructions"], folder, problems
        )
    spec.instruction = _instructions(section.get("instruction", []), folder, conditions, problems)
    spec.between = _between(section.get("between", []), conditions, problems)
    blocks = section.get("blocks", False)
    if not isinstance(blocks, bool):
        problems.append(f"live.blocks: true or false (got {blocks!r})")
    else:
        spec.blocks = blocks
    # (one group's practice condition would show it to all)
    if spec.between and "practice_condition" in section and len(spec.groups(conditions)) > 1:
        problems.append(
            "live.practice_condition: with between-subject factors each participant "
            "practises in their own group's first condition; leave it out"
        )
    catalogue = _catalogue(questionnaires, section.get("questionnaire_file"), folder, problems)
    seen: dict[str, str] = {}  # questionnaire -> the slot that asks it
    for slot in SLOTS:
        asked = _asked(f"live.{slot}", section.get(slot, []), catalogue, problems)
        setattr(spec, slot, asked)
        for q in asked:
            if q.id in seen:
                problems.append(
                    f"live.{slot}: {q.id!r} is also asked in live.{seen[q.id]}: its columns "
                    "would clash; define a second questionnaire of the same kind (e.g. "
                    '[questionnaires.ssq_before] kind = "ssq")'
                )
            seen.setdefault(q.id, slot)
    return spec


def _between(raw: Any, conditions: list[dict[str, Any]], problems: list[str]) -> list[str]:
    """Between-subject factors: factors of the study, keys as in [factors] (all of them is a
    between-subject design: one condition per participant)."""
    if not isinstance(raw, list) or not all(isinstance(x, str) for x in raw):
        problems.append('live.between: a list of factor keys, e.g. ["robots.*.max_tcp_speed"]')
        return []
    known = set(conditions[0]) if conditions else set()
    for key in raw:
        if key not in known:
            problems.append(f"live.between: {key!r} is not a factor of the study")
    if len(set(raw)) != len(raw):
        problems.append("live.between: a factor is named twice")
    return [k for k in raw if k in known]


def _participants(section: dict[str, Any], problems: list[str]) -> list[str]:
    listed, n = section.get("participants"), section.get("n")
    if listed is not None and n is not None:
        problems.append("live: give participants (ids) or n (a count), not both")
    if listed is not None:
        if (
            not isinstance(listed, list)
            or not listed
            or not all(isinstance(p, str) for p in listed)
        ):
            problems.append("live.participants: a list of participant ids")
            return []
        bad = [p for p in listed if not _PID.match(p)]
        if bad:
            problems.append(f"live.participants: ids are letters, digits, _ . - (not {bad[0]!r})")
        if len(set(listed)) != len(listed):
            problems.append("live.participants: an id is listed twice")
        return list(listed)
    if n is None:
        problems.append("live: participants = [ids] or n = count (L01, L02, ...)")
        return []
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 9999:
        problems.append(f"live.n: an integer 1..9999 (got {n!r})")
        return []
    width = max(2, len(str(n)))
    return [f"L{i:0{width}d}" for i in range(1, n + 1)]


def _int(where: str, v: Any, lo: int, problems: list[str]) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        problems.append(f"{where}: an integer >= {lo} (got {v!r})")
        return lo
    return v


def _practice_condition(v: Any, conditions: list[dict[str, Any]], problems: list[str]) -> int:
    """A table of factor values naming one condition (default: the first)."""
    if v is None:
        return 0
    if not isinstance(v, dict):
        problems.append(
            "live.practice_condition: a table of factor values, e.g. "
            '{ "conditions.anticipation" = true }'
        )
        return 0
    hits = [
        i for i, c in enumerate(conditions) if all(repr(c.get(k)) == repr(x) for k, x in v.items())
    ]
    unknown = [k for k in v if not any(k in c for c in conditions)]
    if unknown:
        problems.append(f"live.practice_condition.{unknown[0]}: not a factor of the study")
    elif len(hits) != 1:
        what = "no condition" if not hits else f"{len(hits)} conditions"
        problems.append(f"live.practice_condition: {what} has these values (name exactly one)")
    return hits[0] if len(hits) == 1 else 0


def _instructions(
    raw: Any, folder: Path, conditions: list[dict[str, Any]], problems: list[str]
) -> list[Instruction]:
    if not isinstance(raw, list) or not all(isinstance(r, dict) for r in raw):
        problems.append(
            "live.instruction: [[live.instruction]] tables { when = {...}, file = ... }"
        )
        return []
    out: list[Instruction] = []
    for i, r in enumerate(raw):
        where = f"live.instruction[{i}]"
        for extra in sorted(set(r) - {"when", "file"}):
            problems.append(f"{where}.{extra}: unknown key")
        when = r.get("when", {})
        if not isinstance(when, dict):
            problems.append(f"{where}.when: a table of factor values")
            continue
        if not any(all(repr(c.get(k)) == repr(x) for k, x in when.items()) for c in conditions):
            problems.append(f"{where}.when: no condition of the study has these values")
        text, written = _text_file(f"{where}.file", r.get("file"), folder, problems)
        out.append(Instruction(dict(when), text, written))
    return out


def _catalogue(raw: Any, file: Any, folder: Path, problems: list[str]) -> Catalogue:
    import tomllib

    tables: dict[str, Any] = {}
    if file is not None:
        if not isinstance(file, str):
            problems.append("live.questionnaire_file: a TOML file next to the study")
        else:
            try:
                tables.update(tomllib.loads((folder / file).read_text(encoding="utf-8")))
            except OSError as exc:
                problems.append(
                    f"live.questionnaire_file: cannot read {file!r}: {exc.strerror or exc}"
                )
            except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
                problems.append(f"live.questionnaire_file: {file!r} is not valid TOML: {exc}")
    if raw is not None:
        if not isinstance(raw, dict):
            problems.append("questionnaires: a table of questionnaires ([questionnaires.<name>])")
        else:
            for qid in raw:
                if qid in tables:
                    problems.append(f"questionnaires.{qid}: also in the questionnaire_file")
            tables.update(raw)
    cat = Catalogue()
    for qid, spec in tables.items():
        q = parse_questionnaire(qid, spec, problems)
        if q is not None:
            cat.by_id[qid] = q
    return cat


def _asked(where: str, raw: Any, cat: Catalogue, problems: list[str]) -> list[Questionnaire]:
    if not isinstance(raw, list) or not all(isinstance(x, str) for x in raw):
        problems.append(f"{where}: a list of questionnaire names")
        return []
    out: list[Questionnaire] = []
    for qid in raw:
        q = cat.get(qid)
        if q is None:
            problems.append(
                f"{where}: no questionnaire {qid!r} (tlx, ssq, or a [questionnaires.{qid}] table)"
            )
        else:
            out.append(q)
    if len(set(raw)) != len(raw):
        problems.append(f"{where}: a questionnaire is named twice")
    return out
