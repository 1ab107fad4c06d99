"""Typed publish/subscribe over one Zenoh session.

Every payload is a message of the wire contract (``hrc.wire.pb``). Every put carries the sender's
service name as the Zenoh attachment, so a payload that fails to decode can still be attributed:
it is counted per key, logged with key and sender, and never reaches service code.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from typing import Any, Generic, TypeVar

import zenoh
from google.protobuf.message import DecodeError, Message

from hrc.bus import access
from hrc.bus.config import BusConfig
from hrc.bus.keys import Keys, check_name
from hrc.wire import pb

log = logging.getLogger(__name__)

M = TypeVar("M", bound=Message)
R = TypeVar("R", bound=Message)

# The attachment of an ExchangeBatch is the sender's name and this suffix (names cannot hold '+').
BATCH_SUFFIX = b"+batch"
# Zenoh's low-latency transport does not fragment: a message (with its key, attachment and
# framing) must fit one 65,535-byte batch, or the link it goes out on breaks. The standard
# transport fragments; a cap still keeps one put from flooding every receiver.
MAX_LOWLATENCY_BYTES = 63 * 1024
MAX_STANDARD_BYTES = 16 * 1024 * 1024
# What a publisher holds of what it sent, to answer a replay (docs/ARCHITECTURE.md, "Lost
# messages"): a receiver asks only for what the last ack or clock tick vouched for, so two
# exchanges of the longest span suffice; this is several times that.
REPLAY_KEEP = 2048


class MessageTooLarge(ValueError):
    """A message above its transport's limit: refused before it is sent."""


class InputStats:
    """Thread-safe counters of what a service received."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.decode_errors: Counter[str] = Counter()
        self.subscribed: list[str] = []
        self.ticks_seen = 0
        self.last_tick = 0

    def count_error(self, key: str) -> int:
        with self._lock:
            self.decode_errors[key] += 1
            return self.decode_errors[key]

    def tick(self, k: int) -> None:
        with self._lock:
            self.ticks_seen += 1
            self.last_tick = k

    def to_proto(self, service: str) -> pb.ServiceStats:
        with self._lock:
            msg = pb.ServiceStats(
                service=service,
                subscribed=list(self.subscribed),
                ticks_seen=self.ticks_seen,
                last_tick=self.last_tick,
            )
            for k, v in self.decode_errors.items():
                msg.decode_errors[k] = v
        return msg


class Publisher(Generic[M]):
    """Publishes one message type on one key.

    Fills the header: session, tick, time, sender, seq.
    """

    def __init__(self, bus: Bus, key: str, *, express: bool, block: bool) -> None:
        self.key = key
        self._bus = bus
        self.seq = 0
        self.reported = 0  # the seq last listed by Bus.new_marks
        self._lock = threading.Lock()
        self._held: list[bytes] = []  # serialized messages held back while the bus batches
        self._recent: deque[tuple[int, bytes]] = deque(maxlen=REPLAY_KEEP)  # (seq, message)
        self._pub = bus.session.declare_publisher(
            key,
            congestion_control=zenoh.CongestionControl.BLOCK
            if block
            else zenoh.CongestionControl.DROP,
            express=express,
        )

    def put(self, msg: M, tick: int = 0, sim_time: float = 0.0) -> int:
        """Publishes ``msg`` (header filled); raises MessageTooLarge, sending nothing, if it is
        above the transport's limit."""
        with self._lock:
            h = msg.header  # type: ignore[attr-defined]
            h.session = self._bus.keys.session
            h.tick = tick
            h.sim_time = sim_time
            h.sender = self._bus.sender
            h.seq = self.seq + 1
            data = msg.SerializeToString()
            self._check_size(len(data))
            self.seq += 1
            self._recent.append((self.seq, data))
            if self._bus.batching:
                self._held.append(data)
            else:
                self._pub.put(data, attachment=self._bus.sender_bytes)
            return self.seq

    def sent_after(self, seq: int) -> list[bytes]:
        """The messages after ``seq``, oldest first; none unless it still holds seq + 1 (a
        replay with a hole would not help)."""
        with self._lock:
            if not self._recent or self._recent[0][0] > seq + 1:
                return []
            return [data for n, data in self._recent if n > seq]

    def _check_size(self, size: int) -> None:
        limit = self._bus.max_message_bytes
        if size > limit:
            transport = "low-latency" if self._bus.config.lowlatency else "standard"
            raise MessageTooLarge(
                f"a {size}-byte message on {self.key}: above the {limit}-byte limit of Zenoh's "
                f"{transport} transport (docs/ARCHITECTURE.md); not sent"
            )

    def flush(self) -> None:
        """Puts what was held back while the bus batched: one message as it is, several as
        ExchangeBatch messages (attachment ``<sender>+batch``), as few as the limit allows."""
        with self._lock:
            held, self._held = self._held, []
            # an item costs its bytes plus a few of framing (tag, length)
            limit = self._bus.max_message_bytes - 64
            chunk: list[bytes] = []
            size = 0
            for item in held:
                if chunk and size + len(item) + 8 > limit:
                    self._put_batch(chunk)
                    chunk, size = [], 0
                chunk.append(item)
                size += len(item) + 8
            if chunk:
                self._put_batch(chunk)

    def _put_batch(self, items: list[bytes]) -> None:
        if len(items) == 1:
            self._pub.put(items[0], attachment=self._bus.sender_bytes)
            return
        batch = pb.ExchangeBatch(items=items).SerializeToString()
        self._pub.put(batch, attachment=self._bus.sender_bytes + BATCH_SUFFIX)

    def undeclare(self) -> None:
        self._pub.undeclare()


Validator = Callable[[Message], "str | None"]
# Hands a serialized message of a subscription's key to its handler: (key, the sample it came in,
# or for a replay the sender's name, payload).
Feed = Callable[[str, "zenoh.Sample | str", bytes], None]


class Bus:
    """One service's Zenoh session: typed publishers and subscribers, liveliness, queryables.

    Use as a context manager; everything declared through it is undeclared on exit.
    """

    def __init__(self, config: BusConfig, sender: str) -> None:
        self.config = config
        self.keys = Keys(config.session)
        self.sender = check_name("service name", sender)
        self.sender_bytes = sender.encode()
        self.stats = InputStats()
        # While set, puts are held back per publisher until flush_batches() (one put per key).
        self.batching = False
        self._declared: list[object] = []
        self._publishers: dict[str, Publisher[Any]] = {}
        self.max_message_bytes = MAX_LOWLATENCY_BYTES if config.lowlatency else MAX_STANDARD_BYTES
        # Zenoh's errors into the service's log; a router's refused links too, to be counted
        access.init_zenoh_log(router=config.mode == "router")
        self.session = zenoh.open(config.to_zenoh())

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for d in reversed(self._declared):
            # Already gone with the session: nothing to release.
            with contextlib.suppress(Exception):
                d.undeclare()  # type: ignore[attr-defined]
        self._declared.clear()
        with contextlib.suppress(Exception):
            self.session.close()

    # ------------------------------------------------------------------ publish
    def publisher(self, key: str, *, express: bool = False, block: bool = True) -> Publisher[Any]:
        """A publisher for ``key`` (one per key and service; asking twice returns the same one).

        Not express by default: Zenoh puts the message into the session's current batch, and the
        next express put (the exchange's ack, or the clock tick) sends the batch at once, this
        message first: one write and one wake-up at each receiver for all of an exchange's
        outputs. Messages that move the protocol on (clock, acks, run control and end) are
        ``express=True``: sent at once, and the batch before them with them (docs/ARCHITECTURE.md).
        """
        pub = self._publishers.get(key)
        if pub is None:
            pub = Publisher(self, key, express=express, block=block)
            self._publishers[key] = pub
            self._declared.append(pub)
        return pub

    def begin_batch(self) -> None:
        """From now on every put is held back (per publisher) until :meth:`flush_batches`:
        what one exchange publishes on a key goes out in one put (docs/ARCHITECTURE.md)."""
        self.batching = True

    def flush_batches(self) -> None:
        """Ends batching and puts everything held back."""
        self.batching = False
        for pub in list(self._publishers.values()):
            pub.flush()

    def published_marks(self) -> list[pb.PublishedMark]:
        """The last seq of every key this service has published on (for the tick protocol)."""
        return [
            pb.PublishedMark(key=k, sender=self.sender, seq=p.seq)
            for k, p in self._publishers.items()
            if p.seq > 0
        ]

    def new_marks(self, exclude: str = "") -> list[pb.PublishedMark]:
        """The marks that moved since the previous call (keys other than ``exclude``).

        Tick-protocol messages list only these: a receiver keeps the highest seq per key and
        sender, so repeating an unchanged mark every tick would only cost decoding.
        """
        out = []
        for k, p in self._publishers.items():
            if p.seq > p.reported and k != exclude:
                p.reported = p.seq
                out.append(pb.PublishedMark(key=k, sender=self.sender, seq=p.seq))
        return out

    # ------------------------------------------------------------------ subscribe
    def subscribe(
        self,
        key: str,
        msg_type: type[M],
        callback: Callable[[str, M], None],
        validate: Callable[[M], str | None] | None = None,
    ) -> Feed:
        """Calls ``callback(key, msg)`` for each well-formed message on ``key``.

        A payload is malformed when it does not decode as ``msg_type``, carries another session's
        header, or fails ``validate``; it is counted, logged with key and sender, and dropped.
        Exceptions raised by the callback are logged, never propagated into Zenoh. Returns
        ``feed(key, sender, payload)``, which handles a serialized message got another way (a
        replay) as one that came on the subscription.
        """
        self.stats.subscribed.append(key)
        session = self.keys.session

        def one(k: str, sample: zenoh.Sample | str, payload: bytes) -> None:
            try:
                msg = msg_type()
                msg.ParseFromString(payload)
                problem = None
                header = getattr(msg, "header", None)
                if header is not None and header.session != session:
                    problem = f"header session {header.session!r} is not {session!r}"
                elif validate is not None:
                    problem = validate(msg)
            except (DecodeError, ValueError, RuntimeError) as exc:
                problem = f"does not decode as {msg_type.DESCRIPTOR.name}: {exc}"
            if problem is not None:
                self._malformed(k, sample, problem)
                return
            try:
                callback(k, msg)
            except Exception:
                log.exception("handler for %s failed", k)

        def on_sample(sample: zenoh.Sample) -> None:
            k = str(sample.key_expr)
            payload = sample.payload.to_bytes()
            if len(payload) > MAX_STANDARD_BYTES:
                # no service sends this (Publisher refuses it): refused unread, and counted
                self._malformed(
                    k, sample, f"{len(payload)} bytes, above the {MAX_STANDARD_BYTES}-byte limit"
                )
                return
            att = sample.attachment
            if att is None or not att.to_bytes().endswith(BATCH_SUFFIX):
                one(k, sample, payload)
                return
            batch = pb.ExchangeBatch()
            try:
                batch.ParseFromString(payload)
            except DecodeError as exc:
                self._malformed(k, sample, f"does not decode as ExchangeBatch: {exc}")
                return
            for item in batch.items:
                one(k, sample, item)

        self._declared.append(self.session.declare_subscriber(key, on_sample))
        return one

    def _malformed(self, key: str, sample: zenoh.Sample | str, problem: str) -> None:
        if isinstance(sample, str):  # a replayed message: its sender is the one asked
            self.reject(key, sample, problem)
            return
        att = sample.attachment
        raw = att.to_bytes().removesuffix(BATCH_SUFFIX) if att is not None else b"?"
        self.reject(key, raw.decode(errors="replace"), problem)

    def reject(self, key: str, sender: str, problem: str) -> None:
        """Counts and logs a malformed message (also for checks done after decoding). The
        sender is what the message claims; the log adds who the router admits on the key
        (hrc.bus.access), which is who sent it on a trial with access control."""
        n = self.stats.count_error(key)
        owners = self._owners(key)
        said = f" (as it claims; the router admits only {', '.join(owners)} on this key)"
        log.warning(
            "malformed message #%d on %s from sender %r%s: %s",
            n,
            key,
            sender,
            said if owners else " (as it claims)",
            problem,
        )

    def _owners(self, key: str) -> list[str]:
        """Who may put on ``key`` under a trial's access control (empty: unknown)."""
        try:
            ke = zenoh.KeyExpr(key)
        except zenoh.ZError:
            return []
        return sorted(
            {
                who
                for expr, owners in access.publishers(self.keys).items()
                if zenoh.KeyExpr(expr).intersects(ke)
                for who in owners
            }
        )

    # ------------------------------------------------------------------ liveliness
    def declare_token(self, service: str | None = None) -> None:
        """Announce ``alive/<service>``; declare it after all subscriptions ("ready")."""
        self._declared.append(
            self.session.liveliness().declare_token(self.keys.alive(service or self.sender))
        )

    def watch_liveliness(self, on_change: Callable[[str, bool], None]) -> None:
        """Calls ``on_change(service, alive)`` for every service token of this session, past and
        future."""

        def on_sample(sample: zenoh.Sample) -> None:
            service = self.keys.last_segment(str(sample.key_expr))
            on_change(service, sample.kind == zenoh.SampleKind.PUT)

        self._declared.append(
            self.session.liveliness().declare_subscriber(
                self.keys.alive_all(), on_sample, history=True
            )
        )

    def alive_services(self, timeout: float = 1.0) -> set[str]:
        found: set[str] = set()
        for reply in self.session.liveliness().get(self.keys.alive_all(), timeout=timeout):
            if reply.ok is not None:
                found.add(self.keys.last_segment(str(reply.ok.key_expr)))
        return found

    # ------------------------------------------------------------------ queries
    def queryable(
        self, key: str, request_type: type[M] | None, handler: Callable[[M | None], Message]
    ) -> None:
        """Answers queries on ``key`` with ``handler(request)``; a malformed request gets an
        error."""

        def on_query(query: zenoh.Query) -> None:
            req = None
            if request_type is not None:
                req = request_type()
                try:
                    payload = query.payload
                    req.ParseFromString(payload.to_bytes() if payload is not None else b"")
                except DecodeError as exc:
                    n = self.stats.count_error(key)
                    log.warning("malformed query #%d on %s: %s", n, key, exc)
                    query.reply_err(f"request does not decode as {request_type.DESCRIPTOR.name}")
                    return
            try:
                reply = handler(req)
            except Exception as exc:
                log.exception("query handler for %s failed", key)
                query.reply_err(f"{type(exc).__name__}: {exc}")
                return
            query.reply(key, reply.SerializeToString(), attachment=self.sender_bytes)

        self._declared.append(self.session.declare_queryable(key, on_query))

    def get(
        self, key: str, reply_type: type[R], request: Message | None = None, timeout: float = 2.0
    ) -> list[R]:
        """Query ``key``; returns every decodable reply (errors are logged)."""
        payload = request.SerializeToString() if request is not None else None
        out: list[R] = []
        for reply in self.session.get(key, payload=payload, timeout=timeout):
            if reply.ok is None:
                err = reply.err
                log.warning(
                    "query %s answered with an error: %s",
                    key,
                    err.payload.to_bytes().decode(errors="replace") if err is not None else "?",
                )
                continue
            msg = reply_type()
            try:
                msg.ParseFromString(reply.ok.payload.to_bytes())
            except DecodeError:
                log.warning("reply on %s does not decode as %s", key, reply_type.DESCRIPTOR.name)
                continue
            out.append(msg)
        return out

    def get_one(
        self,
        key: str,
        reply_type: type[R],
        request: Message | None = None,
        timeout: float = 10.0,
        retry_every: float = 0.05,
    ) -> R:
        """Query until one reply arrives (the server may still be starting) or ``timeout``.

        A query that reached no server yet may only end at its own timeout: the first tries are
        short (0.2 s, doubling up to 1 s) so a server that comes up meanwhile is asked again
        soon; the longer ones leave a slow reply under load time to come."""
        deadline = time.monotonic() + timeout
        attempt_s = 0.2
        while True:
            left = deadline - time.monotonic()
            replies = self.get(key, reply_type, request, timeout=max(0.05, min(attempt_s, left)))
            if replies:
                return replies[0]
            if time.monotonic() >= deadline:
                raise TimeoutError(f"no reply on {key} within {timeout:g} s")
            attempt_s = min(1.0, attempt_s * 2)
            time.sleep(retry_every)

    def serve_replay(self) -> None:
        """``replay/<service>``: the messages this service published on a key after a seq, as
        far as it still holds them (docs/ARCHITECTURE.md, "Lost messages")."""

        def answer(req: pb.ReplayRequest | None) -> pb.ExchangeBatch:
            pub = self._publishers.get(req.key) if req is not None else None
            if req is None or pub is None:  # (a key it never published on)
                return pb.ExchangeBatch()
            return pb.ExchangeBatch(items=pub.sent_after(req.after_seq))

        self.queryable(self.keys.replay(self.sender), pb.ReplayRequest, answer)

    def replay(self, key: str, sender: str, after_seq: int, timeout: float) -> list[bytes]:
        """What ``sender`` still holds of its messages on ``key`` after ``after_seq`` (empty if
        it does not answer within ``timeout``)."""
        request = pb.ReplayRequest(key=key, after_seq=after_seq)
        replies = self.get(self.keys.replay(sender), pb.ExchangeBatch, request, timeout=timeout)
        return list(replies[0].items) if replies else []

    def serve_stats(self) -> None:
        """``stats/<service>``: what this service subscribed to and how much garbage it saw."""
        self.queryable(
            self.keys.stats(self.sender), None, lambda _req: self.stats.to_proto(self.sender)
        )
