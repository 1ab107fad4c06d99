"""The study file's [live] table (hrc.study.live, via load_study): checked in full, and each
live participant's trials in their counterbalanced order."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.paths import project_root
from hrc.study import StudyError, load_study

MINIMAL = project_root() / "scenarios" / "minimal.toml"


def study(tmp_path: Path, live: str, extra: str = "", factors: str = "") -> Path:
    (tmp_path / "consent.md").write_text("# Consent\nYes?\n")
    (tmp_path / "cues.md").write_text("Cues on.\n")
    factors = (
        factors
        or '"conditions.anticipation" = [true, false]\n"robots.*.max_tcp_speed" = [0.25, 0.5]'
    )
    path = tmp_path / "study.toml"
    path.write_text(
        f'[study]\nname = "s"\nscenario = "{MINIMAL}"\n[factors]\n{factors}\n'
        f"{extra}\n[live]\n{live}"
    )
    return path


def test_each_live_participant_does_every_condition_in_a_williams_order(tmp_path: Path) -> None:
    s = load_study(
        study(tmp_path, 'n = 4\npractice = 2\nconsent = "consent.md"'), motion_check=False
    )
    assert s.live is not None and s.live.participants == ["L01", "L02", "L03", "L04"]
    assert s.people == [] and s.trials == []  # people only: no simulated trials
    firsts = []
    for pid in s.live.participants:
        trials = s.live_trials(pid)
        assert [t.plan.practice for t in trials] == [True, True, False, False, False, False]
        assert [t.plan.order_position for t in trials] == [0, 0, 1, 2, 3, 4]
        assert trials[0].condition == s.conditions[0]  # practice: the first condition by default
        order = [t.plan.condition_index for t in trials if not t.plan.practice]
        assert sorted(order) == [0, 1, 2, 3]
        firsts.append(order[0])
        for t in trials:  # a live trial's scenario: the participant's id, input vr
            assert 'input = "vr"' in t.scenario_text and f'name = "{pid}"' in t.scenario_text
        assert len({t.id for t in trials}) == 6 and trials[0].id.startswith("practice1_")
    assert sorted(firsts) == [0, 1, 2, 3]  # each condition first once across the square


def test_the_practice_condition_and_per_condition_instructions_are_named_by_factor_values(
    tmp_path: Path,
) -> None:
    live = (
        'participants = ["A7", "B2"]\npractice = 1\norder = "fixed"\n'
        'practice_condition = { "conditions.anticipation" = false, '
        '"robots.*.max_tcp_speed" = 0.5 }\n'
        '[[live.instruction]]\nwhen = { "conditions.anticipation" = true }\nfile = "cues.md"\n'
    )
    s = load_study(study(tmp_path, live), motion_check=False)
    assert s.live is not None
    trials = s.live_trials("B2")
    assert trials[0].condition == {"conditions.anticipation": False, "robots.*.max_tcp_speed": 0.5}
    shown = [bool(s.live.instruction_for(t.condition)) for t in trials[1:]]
    assert shown == [True, True, False, False]  # fixed order: anticipation true first
    with pytest.raises(KeyError):
        s.live_trials("L01")


def test_every_problem_of_a_live_table_is_listed(tmp_path: Path) -> None:
    live = (
        'participants = ["L01", "L01"]\norder = "balanced"\npractice = -1\nmin_break_s = "5"\n'
        'consent = "missing.md"\nafter_trial = ["tlx", "nasa"]\nend = ["tlx"]\ncolour = 1\n'
        'practice_condition = { "conditions.anticipation" = "maybe" }\n'
    )
    with pytest.raises(StudyError) as err:
        load_study(study(tmp_path, live), motion_check=False)
    text = "\n".join(err.value.problems)
    for want in (
        "live.colour: unknown key",
        "live.participants: an id is listed twice",
        "live.order: one of williams, latin, random, fixed (got 'balanced')",
        "live.practice: an integer >= 0 (got -1)",
        "live.min_break_s: seconds, 0..3600 (got '5')",
        "live.consent: cannot read 'missing.md'",
        "live.after_trial: no questionnaire 'nasa'",
        "live.end: 'tlx' is also asked in live.after_trial",
        "live.practice_condition: no condition has these values",
    ):
        assert want in text, f"{want!r} not in:\n{text}"


def test_questionnaires_need_a_live_table_and_ids_must_not_clash(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(
        f'[study]\nname = "s"\nscenario = "{MINIMAL}"\n[participants]\nn = 1\n'
        '[questionnaires.q]\nitems = [{ id = "a", text = "A?" }]\n'
    )
    with pytest.raises(StudyError, match="questionnaires: only with a \\[live\\] table"):
        load_study(path, motion_check=False)
    with pytest.raises(StudyError, match="'P01' is also a simulated participant's id"):
        load_study(
            study(tmp_path, 'participants = ["P01"]', extra="[participants]\nn = 1\n"),
            motion_check=False,
        )


def test_questionnaires_before_the_session_and_before_each_trial(tmp_path: Path) -> None:
    """Four slots: before_session (demographics, a baseline SSQ), before_trial, after_trial,
    end; a questionnaire in one slot only (its columns would clash), so the SSQ before and
    after exposure are two questionnaires of one kind."""
    live = (
        'n = 2\nbefore_session = ["demographics", "ssq_before"]\nbefore_trial = ["ready"]\n'
        'after_trial = ["tlx"]\nend = ["ssq"]\n'
        '[questionnaires.ssq_before]\nkind = "ssq"\n'
        '[questionnaires.ready]\nitems = [{ id = "rested", text = "I feel rested." }]\n'
    )
    s = load_study(study(tmp_path, live), motion_check=False)
    assert s.live is not None
    assert [q.id for q in s.live.before_session] == ["demographics", "ssq_before"]
    demographics = s.live.before_session[0]
    assert demographics.title == "About you" and demographics.score_names() == []
    assert [i.id for i in demographics.items if i.required] == ["handedness"]
    assert [q.id for q in s.live.before_trial] == ["ready"]
    assert s.live.before_session[1].score_names()[-1] == "total_score"
    clash = 'n = 2\nbefore_session = ["ssq"]\nend = ["ssq"]\n'
    with pytest.raises(StudyError, match=r"live\.end: 'ssq' is also asked in live\.before_session"):
        load_study(study(tmp_path, clash), motion_check=False)


def test_a_mixed_design_deals_the_between_factor_over_the_roster_balanced(
    tmp_path: Path,
) -> None:
    """2 x 2 mixed: speed between subjects, anticipation within. Four people: two per speed
    (dealt in turn over the roster), each doing both anticipation levels at their speed, the
    two of a group in opposite orders; each practises at their own speed."""
    live = 'n = 4\npractice = 1\nbetween = ["robots.*.max_tcp_speed"]\n'
    s = load_study(study(tmp_path, live), motion_check=False)
    assert s.live is not None and s.live.between == ["robots.*.max_tcp_speed"]
    speed, ant = "robots.*.max_tcp_speed", "conditions.anticipation"
    seen: dict[float, list[list[bool]]] = {}
    for pid in s.live.participants:
        trials = s.live_trials(pid)
        speeds = {t.condition[speed] for t in trials}
        assert len(speeds) == 1, (pid, speeds)  # one level of the between factor, practice too
        analysed = [t.condition[ant] for t in trials if not t.plan.practice]
        assert sorted(analysed) == [False, True], (pid, analysed)  # every within level
        seen.setdefault(speeds.pop(), []).append(analysed)
    assert sorted(seen) == [0.25, 0.5] and all(len(v) == 2 for v in seen.values()), seen
    for orders in seen.values():  # counterbalanced within each group
        assert orders[0] != orders[1], seen
    with pytest.raises(StudyError, match=r"live\.between: 'speed' is not a factor"):
        load_study(study(tmp_path, 'n = 4\nbetween = ["speed"]\n'), motion_check=False)


def test_repetitions_in_blocks_keep_each_conditions_trials_together(tmp_path: Path) -> None:
    """live.blocks: each condition's repetitions in a row (else the whole order again)."""
    path = study(
        tmp_path, "n = 2\nblocks = true\n", factors='"conditions.anticipation" = [true, false]'
    )
    path.write_text(path.read_text().replace('name = "s"', 'name = "s"\nrepetitions = 3'))

    def values(pid: str) -> list[bool]:
        s = load_study(path, motion_check=False)
        return [t.condition["conditions.anticipation"] for t in s.live_trials(pid)]

    assert values("L01") == [True] * 3 + [False] * 3  # the Williams rows: L01 on, then off
    assert values("L02") == [False] * 3 + [True] * 3
    path.write_text(path.read_text().replace("blocks = true", "blocks = false"))
    assert values("L01") == [True, False] * 3


def test_a_session_kept_before_the_ssq_scores_were_renamed_gives_items_and_scores_apart(
    tmp_path: Path,
) -> None:
    """A session.json written when the SSQ's subscale scores were named like its items
    (`nausea`) gives the item's answer under `q.ssq.nausea` and the subscale, scored again
    from the answers, under `q.ssq.nausea_score` (the score had overwritten the answer)."""
    from hrc.study import session_state as st
    from hrc.study.questionnaires import builtin
    from hrc.study.table import live_rows

    s = load_study(study(tmp_path, 'participants = ["L01"]\nend = ["ssq"]'), motion_check=False)
    ssq = builtin("ssq")
    answers = {i: 1 for i in ssq.item_ids()} | {"nausea": 3}
    old = {"nausea": 28.62, "oculomotor": 7.58, "disorientation": 13.92, "total": 14.96}
    out = tmp_path / "out"
    st.save(
        st.SessionState(
            study="s", participant="L01", created=st.now_iso(), order=[], trials=[],
            end_answers={"ssq": answers}, end_scores={"ssq": old}, status="done",
        ),
        st.session_dir(out, "L01") / "session.json",
    )  # fmt: skip
    # (a row per trial: one trial, its answers beside the session's)
    state = st.load(st.session_dir(out, "L01") / "session.json")
    assert state is not None
    trial = s.live_trials("L01")[0]
    state.trials = [
        st.TrialState(
            id=trial.id, index=1, practice=False, order_position=1,
            condition=trial.condition, condition_index=0, seed=1, input_hash="", status="skipped",
            attempts=[st.Attempt(started=st.now_iso(), outcome="skipped")],
        )
    ]  # fmt: skip
    st.save(state, st.session_dir(out, "L01") / "session.json")
    (row,) = live_rows(s, out)
    assert row["q.ssq.nausea"] == 3  # the answer as given
    scores = ssq.score(answers)
    for name in ("nausea_score", "oculomotor_score", "disorientation_score", "total_score"):
        assert row[f"q.ssq.{name}"] == scores[name], name
    assert "q.ssq.total" not in row and "q.ssq.oculomotor" not in row
