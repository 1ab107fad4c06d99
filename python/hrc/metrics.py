"""A trial's metrics. `pb.Metrics` (proto/hrc/v2/hrc.proto) is their one schema; every field is
described in docs/metrics.md.

metrics.json, the metrics records of events.jsonl and the run summary are all this JSON form of
the message (`to_dict`; `from_dict` reads it back), by the rule of `hrc.wire.jsonmap`: keys and
nesting as the message declares them, null for what is not set.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hrc.wire import pb
from hrc.wire.jsonmap import dict_to_message, message_to_dict


def to_dict(metrics: pb.Metrics) -> dict[str, Any]:
    return message_to_dict(metrics)


def from_dict(data: Mapping[str, Any]) -> pb.Metrics:
    """ValueError when a key is not in the schema or a value does not fit its field."""
    return dict_to_message(data, pb.Metrics())
