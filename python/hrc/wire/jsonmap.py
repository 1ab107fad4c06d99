"""The JSON form of wire messages: plain dicts, walked from the message descriptors.

One rule for every message, so a file written from a message (metrics.json, the metrics records
of events.jsonl) cannot drift from the message's schema:

- keys are the field names, in the order the .proto declares them;
- a field that is not set is null: an unset `optional` scalar or sub-message, an enum at its
  0 value (..._UNSPECIFIED); a number that is NaN or infinite is null too (JSON has none);
- an enum is its value's name without the enum's prefix, in lower case
  (`SAFETY_POLICY_RETREAT_BUTTON` -> "retreat_button", `CLOCK_MODE_LOCKSTEP` -> "lockstep");
- maps are objects with their keys sorted (wire maps keep no order); integers stay integers
  (unlike `json_format`, which writes 64-bit integers as strings).

`dict_to_message` reads that form back (unknown keys are errors).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, TypeVar

from google.protobuf.descriptor import EnumDescriptor, FieldDescriptor
from google.protobuf.message import Message

M = TypeVar("M", bound=Message)

_FLOATS = (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT)


def _enum_prefix(enum: EnumDescriptor) -> str:
    zero = str(enum.values_by_number[0].name)  # e.g. SAFETY_POLICY_UNSPECIFIED
    return zero.removesuffix("UNSPECIFIED")


def enum_text(enum: EnumDescriptor, number: int) -> str | None:
    """The text of an enum value (None for the 0 value, "not set")."""
    if number == 0:
        return None
    value = enum.values_by_number.get(number)
    if value is None:
        raise ValueError(f"{enum.name} has no value {number}")
    return str(value.name).removeprefix(_enum_prefix(enum)).lower()


def enum_number(enum: EnumDescriptor, text: str) -> int:
    """The number of an enum value from its text; ValueError naming the allowed texts."""
    value = enum.values_by_name.get(_enum_prefix(enum) + text.upper())
    if value is None or value.number == 0 or text != text.lower():
        allowed = ", ".join(t for v in enum.values if (t := enum_text(enum, v.number)))
        raise ValueError(f"unknown {enum.name} {text!r}; use one of {allowed}")
    return int(value.number)


def _is_map(field: FieldDescriptor) -> bool:
    return field.message_type is not None and field.message_type.GetOptions().map_entry


def _value(value: Any, field: FieldDescriptor) -> Any:
    if field.type == FieldDescriptor.TYPE_MESSAGE:
        return message_to_dict(value)
    if field.type == FieldDescriptor.TYPE_ENUM:
        return enum_text(field.enum_type, value)
    if field.type in _FLOATS:
        return float(value) if math.isfinite(value) else None
    if isinstance(value, int) and not isinstance(value, bool):
        return int(value)
    return value


def message_to_dict(msg: Message) -> dict[str, Any]:
    """Every field of `msg`, by the rule of this module."""
    out: dict[str, Any] = {}
    for field in msg.DESCRIPTOR.fields:
        value = getattr(msg, field.name)
        if _is_map(field):
            entry = field.message_type.fields_by_name["value"]
            out[field.name] = {k: _value(value[k], entry) for k in sorted(value)}
        elif field.label == FieldDescriptor.LABEL_REPEATED:
            out[field.name] = [_value(v, field) for v in value]
        elif field.has_presence and not msg.HasField(field.name):
            out[field.name] = None
        else:
            out[field.name] = _value(value, field)
    return out


def _scalar(value: Any, field: FieldDescriptor, where: str) -> Any:
    if field.type == FieldDescriptor.TYPE_ENUM:
        if not isinstance(value, str):
            raise ValueError(f"{where}: expected text, got {value!r}")
        return enum_number(field.enum_type, value)
    return value


def dict_to_message(data: Mapping[str, Any], msg: M, where: str = "") -> M:
    """Fill `msg` from its JSON form (null: leave unset) and return it; ValueError naming the
    key of anything that does not fit the schema."""
    fields = msg.DESCRIPTOR.fields_by_name
    for key, value in data.items():
        path = f"{where}.{key}" if where else key
        field = fields.get(key)
        if field is None:
            raise ValueError(f"{path}: no such field in {msg.DESCRIPTOR.name}")
        if value is None:
            continue
        try:
            _fill(msg, field, value, path)
        except (TypeError, AttributeError) as exc:  # a value of the wrong type for its field
            raise ValueError(f"{path}: {exc}") from exc
    return msg


def _fill(msg: Message, field: FieldDescriptor, value: Any, path: str) -> None:
    key = field.name
    target = getattr(msg, key)
    if _is_map(field):
        entry = field.message_type.fields_by_name["value"]
        for k, v in value.items():
            if entry.type == FieldDescriptor.TYPE_MESSAGE:
                dict_to_message(v, target[k], f"{path}.{k}")
            else:
                target[k] = _scalar(v, entry, f"{path}.{k}")
    elif field.label == FieldDescriptor.LABEL_REPEATED:
        for i, v in enumerate(value):
            if field.type == FieldDescriptor.TYPE_MESSAGE:
                dict_to_message(v, target.add(), f"{path}[{i}]")
            else:
                target.append(_scalar(v, field, f"{path}[{i}]"))
    elif field.type == FieldDescriptor.TYPE_MESSAGE:
        target.SetInParent()
        dict_to_message(value, target, path)
    else:
        setattr(msg, key, _scalar(value, field, path))
