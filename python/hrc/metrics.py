"""A trial's metrics. `pb.Metrics` (proto/hrc/v2/hrc.proto) is their one schema; every field is
described in docs/metrics.md.

metrics.json, the metrics records of events.jsonl and the run summary are all this JSON form of
the message (`to_dict`; `from_dict` reads it back), by the rule of `hrc.wire.jsonmap`: keys and
nesting as the message declares them, null for what is not set.

The trial's conditions (`conditions`) are built here too, once: the orchestrator puts them into
metrics.json, the logger writes them as the settings line at the top of log.txt.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hrc import scenario as sc
from hrc.atomic import write_json_atomic
from hrc.scenario.convert import ssm_to_proto
from hrc.wire import pb
from hrc.wire.jsonmap import dict_to_message, enum_text, message_to_dict


def to_dict(metrics: pb.Metrics) -> dict[str, Any]:
    return message_to_dict(metrics)


def from_dict(data: Mapping[str, Any]) -> pb.Metrics:
    """ValueError when a key is not in the schema or a value does not fit its field."""
    return dict_to_message(data, pb.Metrics())


log = logging.getLogger(__name__)

METRICS_FILE = "metrics.json"
LOGGER_STATS_FILE = "logger_stats.json"  # the logger's own counters (its lag, what it lost)
TEXT_LOG_FILE = "log.txt"  # the logger's readable log (hrc run adds its ACCESS REFUSED line)
EVENTS_FILE = "events.jsonl"  # the logger's records: events, cues, metrics (docs/metrics.md)


def add_recording(trial_dir: Path) -> bool:
    """What the logger could not record (logger_stats.json's ``recording``), into metrics.json:
    hrc run does it once every service has left, as only then is it known. False when either
    file is missing or unreadable (metrics.json is then left as it is)."""
    path = trial_dir / METRICS_FILE
    try:
        m = from_dict(json.loads(path.read_text()))
        stats = json.loads((trial_dir / LOGGER_STATS_FILE).read_text())
        m.recording.CopyFrom(dict_to_message(stats["recording"], pb.RecordingMetrics()))
        write_json_atomic(path, to_dict(m))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        log.debug("no recording figures in %s: %s", path, exc)
        return False
    return True


def access_metrics(refused: Mapping[str, int]) -> pb.AccessMetrics:
    """`pb.AccessMetrics` of the refused links counted by reason (its other fields)."""
    return pb.AccessMetrics(refused_links=sum(refused.values()), **refused)


def add_access(trial_dir: Path, access: pb.AccessMetrics) -> bool:
    """The links physics refused for want of the trial's credentials into metrics.json, and,
    when there were any, an ACCESS REFUSED line at the end of log.txt. hrc run does it once every
    service has left. False when metrics.json is missing or unreadable (it is then left as it
    is; log.txt still gets its line)."""
    if access.refused_links:
        text_log = trial_dir / TEXT_LOG_FILE
        try:
            if text_log.exists():
                with text_log.open("a", encoding="utf-8") as f:
                    f.write(access_line(access) + "\n")
        except OSError as exc:
            log.warning("no ACCESS REFUSED line in %s: %s", text_log, exc)
    path = trial_dir / METRICS_FILE
    try:
        m = from_dict(json.loads(path.read_text()))
        m.access.CopyFrom(access)
        write_json_atomic(path, to_dict(m))
    except (OSError, ValueError, TypeError) as exc:
        log.debug("no access figures in %s: %s", path, exc)
        return False
    return True


def access_line(access: pb.AccessMetrics) -> str:
    return (
        f"ACCESS REFUSED: {access.refused_links} attempt(s) to open a link to the trial's bus "
        f"without its credentials (none given {access.no_credentials}, unknown user "
        f"{access.unknown_user}, wrong password {access.wrong_password}); nothing they would "
        "have sent reached the trial (metrics.json, access)."
    )


def conditions(s: sc.Scenario) -> pb.TrialConditions:
    """Every condition a study can vary, as the trial ran it (overrides applied)."""
    c = pb.TrialConditions(
        anticipation=s.conditions.anticipation,
        safety_policy=s.conditions.safety_policy.to_proto(),
    )
    for rid, robot in s.robots.items():
        c.robots[rid].max_tcp_speed = robot.max_tcp_speed
    p = s.participant
    c.participant.input = sc.InputSource(p.input).to_proto()
    if p.replay_file is not None:
        c.participant.replay_file = p.replay_file
    if p.input == sc.InputSource.SCRIPTED:  # the other sources ignore these parameters
        for name, value in sc.scripted_wire_values(p.scripted_params()).items():
            setattr(c.participant, name, value)
    c.participant.provoke_probability = p.provoke_probability
    c.participant.provoke_times_s.extend(p.provoke_times_s)
    if s.conditions.safety_policy == sc.SafetyPolicy.SSM:
        c.ssm.CopyFrom(ssm_to_proto(s.conditions.ssm))
    return c


def _num(x: float) -> str:
    return f"{x:g}"


def settings_line(participant: str, seed: int, c: pb.TrialConditions) -> str:
    """The thesis-style settings line of log.txt (the thesis logged each robot's LearningRate,
    its speed setting), e.g. ``SETTINGS: anticipation on, safety policy retreat, seed 1; r1 max
    TCP speed 0.5 m/s, r2 ...; participant P01: scripted, reaction_time_s 0.4, ...``."""
    policy = enum_text(pb.SafetyPolicy.DESCRIPTOR, c.safety_policy) or "?"
    robots = ", ".join(
        f"{rid} max TCP speed {_num(c.robots[rid].max_tcp_speed)} m/s" for rid in sorted(c.robots)
    )
    p = c.participant
    who = [enum_text(pb.InputSource.DESCRIPTOR, p.input) or "?"]
    if p.HasField("replay_file"):
        who.append(f"replay_file {p.replay_file}")
    if p.profile:
        who.append(f"profile {enum_text(pb.ParticipantProfile.DESCRIPTOR, p.profile)}")
    for field in p.DESCRIPTOR.fields:
        if field.has_presence and field.name != "replay_file" and p.HasField(field.name):
            value = getattr(p, field.name)
            who.append(
                f"{field.name} {str(value).lower() if isinstance(value, bool) else _num(value)}"
            )
    if p.provoke_times_s:
        who.append("provoke_collisions at " + ", ".join(_num(t) for t in p.provoke_times_s) + " s")
    else:
        who.append(f"provoke_collisions {_num(p.provoke_probability)}")
    return (
        f"SETTINGS: anticipation {'on' if c.anticipation else 'off'}, safety policy {policy}, "
        f"seed {seed}; {robots or 'no robots'}; participant {participant}: {', '.join(who)}."
    )
