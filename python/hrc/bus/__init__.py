"""The Zenoh bus as every Python service uses it.

- :class:`Keys` builds the key expressions of a session (the only place they are spelled).
- :class:`BusConfig` / :func:`add_bus_arguments` configure the session (peer on loopback, multicast
  scouting off, explicit endpoints, router mode for several hosts).
- :class:`Bus` opens it: typed publishers and subscribers (malformed payloads are counted and
  logged, never raised), liveliness tokens, queryables.
- The roles of the tick protocol: :class:`ClockMaster` drives the clock,
  :class:`LockstepParticipant` takes part in the barrier, :class:`Observer` follows it without
  acking.
"""

from hrc.bus.bus import Bus, InputStats, Publisher
from hrc.bus.clock import ClockMaster, ClockSettings, RunFailed
from hrc.bus.config import BusConfig, add_bus_arguments, bus_config_from_args
from hrc.bus.inbox import Inbox
from hrc.bus.keys import Keys
from hrc.bus.lockstep import ClockFollower, LockstepParticipant, Outcome, watch_clock_master
from hrc.bus.observer import LagStats, Observer
from hrc.bus.sequence import SeqChecker

__all__ = [
    "Bus",
    "BusConfig",
    "ClockFollower",
    "ClockMaster",
    "ClockSettings",
    "Inbox",
    "InputStats",
    "Keys",
    "LagStats",
    "LockstepParticipant",
    "Observer",
    "Outcome",
    "Publisher",
    "RunFailed",
    "SeqChecker",
    "add_bus_arguments",
    "bus_config_from_args",
    "watch_clock_master",
]
