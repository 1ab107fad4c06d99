"""Key expressions of one session: the only place Python spells them (C++ twin: hrc/keys.hpp)."""

from __future__ import annotations

import re

_SESSION_RE = re.compile(r"^[A-Za-z0-9_\-]{1,64}$")
_NAME_RE = re.compile(r"^[A-Za-z0-9_\-]{1,64}$")

ROOT = "hrc"


def check_name(kind: str, value: str) -> str:
    """Reject ids that would break or widen a key expression (``*``, ``/``, ``$``...)."""
    if not _NAME_RE.match(value):
        raise ValueError(f"invalid {kind} {value!r}: use 1-64 characters of A-Z a-z 0-9 _ -")
    return value


class Keys:
    """Builds every key expression under ``hrc/<session>/`` (see docs/ARCHITECTURE.md)."""

    def __init__(self, session: str) -> None:
        if not _SESSION_RE.match(session):
            raise ValueError(
                f"invalid session id {session!r}: use 1-64 characters of A-Z a-z 0-9 _ -"
            )
        self.session = session
        self.prefix = f"{ROOT}/{session}"

    def _k(self, *parts: str) -> str:
        return "/".join((self.prefix, *parts))

    def all(self) -> str:
        return self._k("**")

    def clock(self) -> str:
        return self._k("clock")

    def clock_ack(self, participant: str) -> str:
        return self._k("clock", "ack", check_name("participant", participant))

    def clock_acks(self) -> str:
        return self._k("clock", "ack", "*")

    def run_control(self, sender: str) -> str:
        """``run/control/<sender>``: each sender has a key of its own, which the router's access
        control keeps to that sender alone, so the key proves who sent a stop or an abort."""
        return self._k("run", "control", check_name("sender", sender))

    def run_controls(self) -> str:
        return self._k("run", "control", "*")

    def run_end(self) -> str:
        return self._k("run", "end")

    def alive(self, service: str) -> str:
        return self._k("alive", check_name("service", service))

    def alive_all(self) -> str:
        return self._k("alive", "*")

    def stats(self, service: str) -> str:
        return self._k("stats", check_name("service", service))

    def replay(self, service: str) -> str:
        """Where ``service`` answers for messages it published that a receiver lacks."""
        return self._k("replay", check_name("service", service))

    def scenario(self) -> str:
        return self._k("scenario")

    def robot_command(self, robot: str) -> str:
        return self._k("robot", check_name("robot id", robot), "command")

    def robot_commands(self) -> str:
        return self._k("robot", "*", "command")

    def robot_state(self, robot: str) -> str:
        return self._k("robot", check_name("robot id", robot), "state")

    def robot_states(self) -> str:
        return self._k("robot", "*", "state")

    def robot_reach(self) -> str:
        return self._k("robot", "reach")

    def human_clients(self) -> str:
        return self._k("human", "clients")

    def human_state(self) -> str:
        return self._k("human", "state")

    def world_objects(self) -> str:
        return self._k("world", "objects")

    def world_contacts(self) -> str:
        return self._k("world", "contacts")

    def world_separation(self) -> str:
        """Separations (physics, only under safety_policy = ssm)."""
        return self._k("world", "separation")

    def world_commands(self) -> str:
        return self._k("world", "commands")

    def task_events(self) -> str:
        return self._k("task", "events")

    def task_indicators(self) -> str:
        return self._k("task", "indicators")

    def task_metrics(self) -> str:
        return self._k("task", "metrics")

    def bench(self, name: str) -> str:
        return self._k("bench", check_name("bench key", name))

    def last_segment(self, key: str) -> str:
        """The final segment of a concrete key, e.g. the service of ``alive/<service>``."""
        return key.rsplit("/", 1)[-1]

    def robot_of(self, key: str) -> str:
        """The robot id in ``hrc/<s>/robot/<id>/...``."""
        parts = key.split("/")
        return parts[3] if len(parts) > 3 else ""
