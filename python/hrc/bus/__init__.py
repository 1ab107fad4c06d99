"""The Zenoh bus as every Python service uses it.

- :class:`Keys` builds the key expressions of a session (the only place they are spelled).
- :class:`BusConfig` / :func:`add_bus_arguments` configure the session (peer on loopback, multicast
  scouting off, explicit endpoints, router mode for several hosts).
- :class:`Bus` opens it: typed publishers and subscribers (malformed payloads are counted and
  logged, never raised), liveliness tokens, queryables.
- :class:`LockstepParticipant` and :class:`ClockMaster` implement the tick protocol.
"""

from hrc.bus.bus import Bus, InputStats, Publisher
from hrc.bus.clock import ClockMaster, ClockSettings, RunFailed
from hrc.bus.config import BusConfig, add_bus_arguments, bus_config_from_args
from hrc.bus.inbox import Inbox
from hrc.bus.keys import Keys
from hrc.bus.lockstep import LockstepParticipant, Outcome, watch_clock_master

__all__ = [
    "Bus", "BusConfig", "ClockMaster", "ClockSettings", "Inbox", "InputStats",
    "Keys", "LockstepParticipant", "Outcome", "Publisher", "RunFailed", "add_bus_arguments",
    "bus_config_from_args", "watch_clock_master",
]
