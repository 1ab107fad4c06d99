"""Turns the contacts present at each tick into begin / end events (one each per contact).

A contact is identified by (kind, a, b): a hand touching a robot is one contact however many of
the robot's links it touches (the reported link is the deepest one when it begins), so a hand
sliding along an arm is one collision, not several. The end event repeats the begin's link,
point and distance.
"""

from __future__ import annotations

from typing import NamedTuple

from hrc.geometry import Vec3
from hrc.wire import pb


class ContactKey(NamedTuple):
    kind: pb.ContactKind.ValueType
    a: str
    b: str


class Touch(NamedTuple):
    """Where a present contact is: the link(s), a point, the distance (<= 0: penetration)."""

    link: str = ""
    point: Vec3 = (0.0, 0.0, 0.0)
    distance: float = 0.0


def _contact(key: ContactKey, touch: Touch, begin: bool) -> pb.Contact:
    x, y, z = touch.point
    return pb.Contact(
        kind=key.kind,
        begin=begin,
        a=key.a,
        b=key.b,
        link=touch.link,
        point=pb.Vec3(x=x, y=y, z=z),
        distance=touch.distance,
    )


class ContactTracker:
    """Remembers the active contacts; :meth:`update` returns what began and ended."""

    def __init__(self) -> None:
        self.active: dict[ContactKey, Touch] = {}

    def update(self, present: dict[ContactKey, Touch]) -> list[pb.Contact]:
        """Ends first, then begins, each sorted by (kind, a, b): the same order on any run."""
        if present.keys() == self.active.keys():
            return []  # the common case: nothing began or ended
        events: list[pb.Contact] = []
        for key in sorted(self.active.keys() - present.keys()):
            events.append(_contact(key, self.active.pop(key), False))
        for key in sorted(present.keys() - self.active.keys()):
            touch = present[key]
            self.active[key] = touch
            events.append(_contact(key, touch, True))
        return events
