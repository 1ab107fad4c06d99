"""The live VR bridge: a WebSocket endpoint for participant clients, and the files of the
participant client, on one port (protocol: docs/client-protocol.md).

Runs an asyncio event loop (websockets 15) in its own thread. The tick thread only reads the
latest accepted sample (:meth:`VrBridge.latest`) and hands over the latest world snapshot
(:meth:`VrBridge.publish`, which never waits on a client). Per client a sender task sends its
events in order and at most ``rate_hz`` frames a second, always of the latest snapshot: a slow
or stalled client only loses frames (counted), never slows the trial.

Why one file of over 600 lines: the roles, the per-client senders and the handshake share one
event loop and one lock; what it shares with a session's page server is in hrc.webpage.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
import socket
import threading
from dataclasses import dataclass, field
from http import HTTPStatus
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, unquote, urlsplit

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from hrc import jsontext
from hrc.participant.sample import Sample, parse_sample
from hrc.scenario.conventions import MAX_HELD_GRIP_CHANGES
from hrc.webpage import (
    HTML,
    NOT_BUILT,
    TEXT,
    built_page,
    content_type,
    key_ok,
    note,
    page_file,
    response,
)

from hrc_human_input.scene import PROTOCOL_VERSION, RobotFiles
from hrc_human_input.stream import ClientView, Snapshot, frame_json
from hrc_human_input.vr_options import (  # noqa: F401  (re-exported: the bridge's options)
    CLIENT_DIST,
    DEFAULT_HOST,
    DEFAULT_PORT,
    DRIVER,
    SPECTATOR,
    BridgeConfigError,
    check_bind,
    is_loopback,
)

log = logging.getLogger(__name__)

MAX_FRAME_BYTES = 64 * 1024
WS_PATHS = ("/ws", "/")
FALLBACK_NOTE = note(NOT_BUILT + b" This is the minimal fallback page.")
DEFAULT_RATE_HZ = 90.0
MAX_RATE_HZ = 240.0
EVENT_QUEUE = 256  # events waiting for one client; beyond that it is disconnected (1013)
# The participant's page gone (driver key): its hands open this long after, unless the same page
# comes back first (a redial after a lost link keeps the part in the hand).
RELEASE_GRACE_S = 3.0
# Bytes waiting for a client before a send waits (websockets' buffer, then the socket's): small,
# so a client that reads late gets the latest state, not a backlog.
WRITE_LIMIT = 16 * 1024
SOCKET_SEND_BUFFER = 64 * 1024
CLOSE_TOO_SLOW = 1013


def fallback_page() -> bytes:
    """The minimal page shipped with the package, with a note that the client is not built."""
    page = resources.files("hrc_human_input").joinpath("web/index.html").read_bytes()
    return page.replace(b"<body>", b"<body>\n" + FALLBACK_NOTE, 1)


def page_html(client_dir: Path | None = CLIENT_DIST) -> bytes:
    """The client's index.html if its bundle is built, else the fallback page."""
    return built_page(client_dir) or fallback_page()


@dataclass
class BridgeStats:
    clients: int = 0
    accepted: int = 0
    rejected: int = 0
    auth_failures: int = 0
    frames_sent: int = 0
    frames_dropped: int = 0
    bytes_sent: int = 0
    too_slow: int = 0  # clients disconnected because their events piled up


@dataclass(eq=False)
class Client:
    ws: ServerConnection
    peer: str
    role: str = SPECTATOR
    rate_hz: float = DEFAULT_RATE_HZ
    view: ClientView = field(default_factory=ClientView)
    outbox: collections.deque[str] = field(default_factory=collections.deque)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    sending: bool = False
    due: float = 0.0  # loop time the next frame may go out
    dropped: int = 0  # frame slots that passed while a send was still waiting on the client
    frames: int = 0
    bytes: int = 0
    task: asyncio.Task[None] | None = None
    closing: bool = False
    page: str = ""  # the page's own id (?page=...): the same page after a redial
    resumed: bool = False  # a driver that is the same page as the one before (nothing released)


class VrBridge:
    """Accepts JSON samples over WebSocket (keeps the latest one) and streams the world."""

    def __init__(
        self,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        token: str | None = None,
        hello: dict[str, Any] | None = None,
        scene: dict[str, Any] | None = None,
        robot_files: RobotFiles | None = None,
        client_dir: Path | None = CLIENT_DIST,
        driver_key: str | None = None,
        origins: tuple[str, ...] = (),
    ) -> None:
        check_bind(host, token)
        # Browsers say which page opens a WebSocket: only this host's pages (any port: a
        # session's page comes from another one) and the origins given may connect; a tool
        # that is not a browser sends none.
        self.origins = frozenset(o.rstrip("/").lower() for o in origins)
        # With a driver key only a page that presents it (?driver=KEY, the participant's link)
        # drives, and gets the role back when it reconnects; every other page spectates. Without
        # one, the first page drives and the longest-connected spectator takes over when it
        # leaves.
        self.driver_key = driver_key or None
        self.host = host
        self.port = port
        self.token = token or None
        self.hello = dict(hello or {})
        self.scene_json = None if scene is None else json.dumps(scene, separators=(",", ":"))
        self.robot_files = robot_files or RobotFiles()
        self.client_dir = client_dir
        self.stats = BridgeStats()
        self._page = page_html(client_dir)
        self.client_built = client_dir is not None and (client_dir / "index.html").is_file()
        self._lock = threading.Lock()
        self._latest: Sample | None = None
        # Samples that open or close a grip, until a tick has taken each: the latest sample wins,
        # but a release sent just before the hand moves away still happens where it was sent.
        self._edges: collections.deque[Sample] = collections.deque(maxlen=MAX_HELD_GRIP_CHANGES)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: Server | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._first_client = threading.Event()
        self._stop: asyncio.Event | None = None
        self._error: BaseException | None = None
        self.bound_port = 0
        # tick thread -> loop hand-over (under _lock)
        self._pending: Snapshot | None = None
        self._pending_events: list[str] = []
        self._wake_scheduled = False
        # loop thread only: the driver page that left, and its pending release
        self._gone_page = ""
        self._release: asyncio.TimerHandle | None = None
        # loop thread -> tick thread (under _lock): who is connected, what changed
        self._presence: list[str] = []
        self._presence_changed = False
        # loop thread only
        self._snapshot: Snapshot | None = None
        self._clients: list[Client] = []  # authenticated, in connection order

    # ------------------------------------------------------------------ lifecycle
    def start(self, timeout: float = 10.0) -> int:
        """Starts serving; returns the bound port (useful with port 0)."""
        self._thread = threading.Thread(target=self._run, name="vr-bridge", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise BridgeConfigError(f"the VR bridge did not start within {timeout:g} s")
        if self._error is not None:
            raise BridgeConfigError(
                f"cannot serve the VR bridge on {self.host}:{self.port}: {self._error}"
            )
        return self.bound_port

    def stop(self) -> None:
        loop, stop = self._loop, self._stop
        if loop is not None and stop is not None and loop.is_running():
            loop.call_soon_threadsafe(stop.set)
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def __enter__(self) -> VrBridge:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def latest(self) -> Sample | None:
        with self._lock:
            return self._latest

    def take(self) -> Sample | None:
        """The sample for this tick: the oldest grip change no tick has taken yet, else the
        latest sample."""
        with self._lock:
            return self._edges.popleft() if self._edges else self._latest

    def presence(self) -> tuple[list[tuple[str, str]], list[str]] | None:
        """The connected clients (peer, role) and the changes since the last call; None when
        nothing changed."""
        with self._lock:
            if not self._presence_changed:
                return None
            changes, self._presence = self._presence, []
            self._presence_changed = False
            clients = [(c.peer, c.role) for c in self._clients if not c.closing]
        return clients, changes

    def _note(self, line: str) -> None:
        """A change of who is connected, for the experimenter's console (and the log)."""
        log.info("%s", line)
        with self._lock:
            self._presence.append(line)
            self._presence_changed = True

    def wait_for_client(self, timeout: float | None) -> bool:
        """True once a client has connected (and authenticated) since the start."""
        return self._first_client.wait(timeout)

    # ------------------------------------------------------------------ tick thread -> clients
    def publish(self, snap: Snapshot, events: list[str]) -> None:
        """Hands the latest world state (and the events since the last one) to the loop; returns
        at once. Snapshots not yet taken by the loop are replaced (events are kept)."""
        loop = self._loop
        with self._lock:
            self._pending = snap
            self._pending_events.extend(events)
            schedule = not self._wake_scheduled and loop is not None
            self._wake_scheduled = self._wake_scheduled or schedule
        if schedule and loop is not None:
            # RuntimeError: the loop has closed, nobody to send to
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._deliver)

    def flush(self, timeout: float = 1.0) -> None:
        """Waits (up to ``timeout``) until every client has been sent what was published: the
        last frame and the run's end reach the page before the bridge closes."""
        loop = self._loop
        if loop is None or not loop.is_running():
            return
        fut = asyncio.run_coroutine_threadsafe(self._drained(timeout), loop)
        with contextlib.suppress(Exception):
            fut.result(timeout + 1.0)

    async def _drained(self, timeout: float) -> None:
        end = asyncio.get_running_loop().time() + timeout
        while asyncio.get_running_loop().time() < end:
            snap = self._snapshot
            pending = self._pending is not None or self._pending_events
            busy = any(
                c.outbox or (snap is not None and c.view.version != snap.version)
                for c in self._clients
                if not c.closing
            )
            if not pending and not busy:
                return
            await asyncio.sleep(0.01)

    # ------------------------------------------------------------------ the loop thread
    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:  # reported to start(); never kill the service silently
            if not self._ready.is_set():
                self._error = exc
                self._ready.set()
            else:
                log.exception("the VR bridge stopped")

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        async with serve(
            self._handler,
            self.host,
            self.port,
            process_request=self._http,
            max_size=MAX_FRAME_BYTES,
            write_limit=WRITE_LIMIT,
            ping_interval=20,
            ping_timeout=20,
            close_timeout=2,
        ) as server:
            self._server = server
            self.bound_port = int(next(iter(server.sockets)).getsockname()[1])
            log.info(
                "VR bridge on ws://%s:%d/ws (page http://%s:%d/)%s%s",
                self.host,
                self.bound_port,
                self.host,
                self.bound_port,
                ", token required" if self.token else "",
                "" if self.client_built else "; participant client not built (fallback page)",
            )
            self._ready.set()
            await self._stop.wait()
            for c in list(self._clients):
                if c.task is not None:
                    c.task.cancel()

    def _deliver(self) -> None:
        """In the loop: takes what the tick thread handed over, queues the events of every
        client, counts the frame slots missed by clients still busy, wakes the senders."""
        with self._lock:
            snap, self._pending = self._pending, None
            events, self._pending_events = self._pending_events, []
            self._wake_scheduled = False
        if snap is not None:
            self._snapshot = snap
        now = asyncio.get_running_loop().time()
        for c in list(self._clients):
            if c.closing:
                continue
            c.outbox.extend(events)
            if len(c.outbox) > EVENT_QUEUE:
                self._kick(c)
                continue
            if c.sending:
                period = 1.0 / c.rate_hz
                while now >= c.due:
                    c.dropped += 1
                    self.stats.frames_dropped += 1
                    c.due += period
            c.wake.set()

    def _kick(self, c: Client) -> None:
        """Events piled up beyond EVENT_QUEUE: the client cannot keep up; disconnect it."""
        c.closing = True
        self.stats.too_slow += 1
        log.warning(
            "VR client %s: %d events waiting, disconnecting it (1013 too slow)",
            c.peer,
            len(c.outbox),
        )
        c.outbox.clear()
        if c.task is not None:
            c.task.cancel()
        asyncio.get_running_loop().create_task(self._close(c.ws, CLOSE_TOO_SLOW, "too slow"))

    @staticmethod
    async def _close(ws: ServerConnection, code: int, reason: str) -> None:
        try:
            await asyncio.wait_for(ws.close(code, reason), 2.0)
        except (TimeoutError, ConnectionClosed, OSError):
            ws.transport.abort()

    async def _sender(self, c: Client) -> None:
        """Sends one client its events (in order) and its frames (latest state, at its rate)."""
        loop = asyncio.get_running_loop()
        try:
            while not c.closing:
                await c.wake.wait()
                c.wake.clear()
                while c.outbox:
                    await self._send(c, c.outbox.popleft())
                snap = self._snapshot
                if snap is None or snap.version == c.view.version:
                    continue
                wait = c.due - loop.time()
                if wait > 0:
                    await asyncio.sleep(wait)
                    while c.outbox:  # what came meanwhile goes first
                        await self._send(c, c.outbox.popleft())
                    snap = self._snapshot or snap
                c.due = max(c.due + 1.0 / c.rate_hz, loop.time())
                c.sending = True
                try:
                    await self._send(c, frame_json(c.view, snap, c.dropped), frame=True)
                finally:
                    c.sending = False
                if self._snapshot is not None and self._snapshot.version != c.view.version:
                    c.wake.set()  # a newer state came while this one was sent
        except ConnectionClosed:
            pass

    async def _send(self, c: Client, text: str, frame: bool = False) -> None:
        await c.ws.send(text)
        n = len(text)
        c.bytes += n
        self.stats.bytes_sent += n
        if frame:
            c.frames += 1
            self.stats.frames_sent += 1

    # ------------------------------------------------------------------ clients and roles
    def _register(self, ws: ServerConnection, peer: str, participant: bool, page: str) -> Client:
        c = Client(ws, peer, page=page)
        current = next((o for o in self._clients if o.role == DRIVER and not o.closing), None)
        if self.driver_key is None:
            c.role = DRIVER if current is None else SPECTATOR
        else:
            c.role = DRIVER if participant else SPECTATOR
            if participant:
                # the same page again (a redial) takes its hands back as they are; another page
                # (a reload, a reopened tab) starts from open hands
                before = current.page if current is not None else self._gone_page
                c.resumed = bool(page) and page == before
                if self._release is not None:
                    self._release.cancel()
                    self._release = None
                    if not c.resumed:
                        self._release_hands()
                elif current is not None and not c.resumed:
                    self._release_hands()
            if participant and current is not None:
                # the participant's page again (a reload, a second tab): the newest one drives
                current.role = SPECTATOR
                current.outbox.append(self._hello_json(SPECTATOR, authed=True))
                current.wake.set()
                self._note(
                    f"VR client {current.peer} is now a spectator (the participant's "
                    f"link was opened again at {peer})"
                )
        c.due = asyncio.get_running_loop().time()
        self._clients.append(c)
        if c.role == DRIVER or self.driver_key is None:
            self._first_client.set()
        self._note(f"VR client {peer} connected as the {c.role}")
        return c

    def _unregister(self, c: Client) -> None:
        if c not in self._clients:
            return
        self._clients.remove(c)
        c.closing = True
        if c.task is not None:
            c.task.cancel()
        self._note(
            f"VR client {c.peer} ({c.role}) left: {c.frames} frames, {c.dropped} dropped, "
            f"{c.bytes} bytes"
        )
        if c.role != DRIVER:
            return
        if self.driver_key is not None:
            # unless the same page is back within RELEASE_GRACE_S (a redial), the hands open
            self._gone_page = c.page
            if self._release is not None:
                self._release.cancel()
            self._release = asyncio.get_running_loop().call_later(
                RELEASE_GRACE_S, self._release_hands
            )
            self._note("no driver: the participant's page is gone (it drives again on reopen)")
            return
        self._release_hands()
        nxt = next((o for o in self._clients if not o.closing), None)
        if nxt is not None:
            nxt.role = DRIVER
            self._note(f"VR client {nxt.peer} is now the driver")
            nxt.outbox.append(self._hello_json(nxt.role, authed=True))
            nxt.wake.set()

    def _release_hands(self) -> None:
        """The hands open where they are: a part held stays where the hand held it (it is let
        go there), never carried off to where the next page starts its hands."""
        self._release = None
        with self._lock:
            held = self._latest is not None and bool(
                self._latest.left_grip or self._latest.right_grip
            )
            if held and self._latest is not None:
                self._latest = self._latest.released()
                self._edges.clear()
        if held:
            self._note("the participant's hands opened where they were")

    def _hello_json(self, role: str | None, authed: bool, resumed: bool = False) -> str:
        return json.dumps(
            {
                "type": "hello",
                "auth_required": not authed,
                **self.hello,
                "protocol": PROTOCOL_VERSION,
                "role": role,
                "resumed": resumed,
            }
        )

    async def _welcome(
        self, ws: ServerConnection, peer: str, participant: bool, page: str
    ) -> Client:
        """An authenticated client: its role, hello, the scene, then its stream."""
        c = self._register(ws, peer, participant, page)
        await self._send(c, self._hello_json(c.role, authed=True, resumed=c.resumed))
        if self.scene_json is not None:
            await self._send(c, self.scene_json)
        c.task = asyncio.get_running_loop().create_task(self._sender(c))
        c.wake.set()
        return c

    # ------------------------------------------------------------------ HTTP (files) and handshake
    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        parts = urlsplit(request.path)
        upgrade = request.headers.get("Upgrade", "").lower() == "websocket"
        if not upgrade:
            return self._file(unquote(parts.path))
        if parts.path not in WS_PATHS:
            return _response(HTTPStatus.NOT_FOUND, b"WebSocket endpoint is /ws\n", TEXT)
        origin = request.headers.get("Origin")
        if origin is not None and not self._origin_ok(origin, request.headers.get("Host", "")):
            self.stats.auth_failures += 1
            log.warning("VR client %s: refused a page from %s", _peer(connection), origin[:200])
            return _response(
                HTTPStatus.FORBIDDEN,
                b"a page from another site may not connect (this host's pages, or the origins "
                b"given with HRC_VR_ORIGINS)\n",
                TEXT,
            )
        given = parse_qs(parts.query).get("token")
        if given is not None and self.token is not None and not self._token_ok(given[0]):
            self.stats.auth_failures += 1
            log.warning("VR client %s: wrong token in the URL", _peer(connection))
            return _response(HTTPStatus.UNAUTHORIZED, b"wrong token\n", TEXT)
        return None

    def _file(self, path: str) -> Response:
        """GET: the page, the client's bundle, the scenario's robot files; nothing else."""
        found = page_file(path, self._page, self.client_dir)
        if isinstance(found, bytes):
            return _response(HTTPStatus.OK, found, HTML)
        if found is None and path.startswith("/robots/"):
            found = self.robot_files.lookup(path.removeprefix("/robots/"))
        if found is None:
            return _response(HTTPStatus.NOT_FOUND, b"not found\n", TEXT)
        try:
            body = found.read_bytes()
        except OSError:
            return _response(HTTPStatus.NOT_FOUND, b"not found\n", TEXT)
        resp = _response(HTTPStatus.OK, body, content_type(found))
        if path.startswith("/robots/"):
            # a session's page (`hrc session`) comes from another port of this host and loads
            # the robots from here: static files, served to anybody already
            resp.headers["Access-Control-Allow-Origin"] = "*"
        return resp

    def _origin_ok(self, origin: str, host_header: str) -> bool:
        if origin.rstrip("/").lower() in self.origins:
            return True
        try:
            page_host = urlsplit(origin).hostname
            own_host = urlsplit("//" + host_header).hostname
        except ValueError:
            return False
        return page_host is not None and page_host == own_host

    def _token_ok(self, given: Any) -> bool:
        """A token was asked for and `given` is it."""
        return isinstance(given, str) and self.token is not None and key_ok(given, self.token)

    # ------------------------------------------------------------------ WebSocket
    async def _handler(self, ws: ServerConnection) -> None:
        peer = _peer(ws)
        query = parse_qs(urlsplit(ws.request.path).query) if ws.request else {}
        authed = self.token is None or self._token_ok(
            query["token"][0] if query.get("token") else None
        )
        given_key = query["driver"][0] if query.get("driver") else None
        page = query["page"][0][:64] if query.get("page") else ""
        participant = self.driver_key is not None and key_ok(given_key, self.driver_key)
        self.stats.clients += 1
        _limit_send_buffer(ws)
        log.info("VR client %s connected%s", peer, "" if authed else " (must authenticate)")
        client: Client | None = None
        try:
            if authed:
                client = await self._welcome(ws, peer, participant, page)
            else:
                await ws.send(self._hello_json(None, authed=False))
            async for message in ws:
                if isinstance(message, bytes):
                    await self._error_reply(ws, ["binary frames are not accepted: send JSON text"])
                    continue
                try:
                    obj = jsontext.loads(message)
                except jsontext.JsonTooDeep as exc:
                    await self._error_reply(ws, [str(exc)])
                    continue
                except json.JSONDecodeError as exc:
                    await self._error_reply(ws, [f"not valid JSON: {exc.msg} (column {exc.colno})"])
                    continue
                if isinstance(obj, dict) and "token" in obj and "type" not in obj:
                    if self.token is None or self._token_ok(obj.get("token")):
                        await ws.send(json.dumps({"type": "auth", "ok": True}))
                        if client is None:
                            client = await self._welcome(ws, peer, participant, page)
                        continue
                    self.stats.auth_failures += 1
                    await self._error_reply(ws, ["wrong token"])
                    await ws.close(1008, "wrong token")
                    return
                if client is None:
                    self.stats.auth_failures += 1
                    await self._error_reply(
                        ws,
                        ['authenticate first: send {"token": "..."} or connect to /ws?token=...'],
                    )
                    await ws.close(1008, "token required")
                    return
                if isinstance(obj, dict) and "type" in obj:
                    await self._command(client, obj)
                    continue
                sample, problems = parse_sample(obj, require_t=False)
                if sample is None:
                    await self._error_reply(ws, problems)
                    continue
                if client.role != DRIVER:
                    await self._error_reply(
                        ws,
                        [
                            "spectator: this page only watches; the participant's link "
                            "(?driver=...) drives the hands"
                            if self.driver_key is not None
                            else "spectator: another client drives the hands; this one only "
                            "watches (it becomes the driver when that one leaves)"
                        ],
                    )
                    continue
                with self._lock:
                    last = self._edges[-1] if self._edges else self._latest
                    if last is not None and last.closed() != sample.closed():
                        self._edges.append(sample)
                    self._latest = sample
                self.stats.accepted += 1
        except ConnectionClosed:
            pass
        finally:
            if client is not None:
                self._unregister(client)
            log.info("VR client %s disconnected", peer)

    async def _command(self, c: Client, obj: dict[str, Any]) -> None:
        """``subscribe`` and ``ping``; anything else is an error and changes nothing."""
        kind = obj.get("type")
        if kind == "subscribe":
            rate = obj.get("rate_hz", DEFAULT_RATE_HZ)
            unknown = sorted(set(obj) - {"type", "rate_hz"})
            if unknown:
                await self._error_reply(c.ws, [f"subscribe: unknown key(s) {', '.join(unknown)}"])
            elif (
                isinstance(rate, bool)
                or not isinstance(rate, int | float)
                or not 1.0 <= rate <= MAX_RATE_HZ
            ):
                await self._error_reply(
                    c.ws,
                    [f"subscribe: rate_hz must be a number in [1, {MAX_RATE_HZ:g}], got {rate!r}"],
                )
            else:
                c.rate_hz = float(rate)
            return
        if kind == "ping":
            await c.ws.send(
                json.dumps(
                    {
                        "type": "pong",
                        "id": obj.get("id"),
                        "client_time_ms": obj.get("client_time_ms"),
                        "tick": self._snapshot.tick if self._snapshot is not None else None,
                    }
                )
            )
            return
        await self._error_reply(
            c.ws, [f"unknown message type {kind!r}: expected subscribe, ping or a sample"]
        )

    async def _error_reply(self, ws: ServerConnection, problems: list[str]) -> None:
        self.stats.rejected += 1
        if self.stats.rejected <= 20 or self.stats.rejected % 1000 == 0:
            log.warning(
                "VR client %s sent a malformed frame (#%d): %s",
                _peer(ws),
                self.stats.rejected,
                "; ".join(problems),
            )
        await ws.send(
            json.dumps({"type": "error", "error": "; ".join(problems), "problems": problems})
        )


def _limit_send_buffer(ws: ServerConnection) -> None:
    """A client that reads late must get the latest state, not seconds of backlog."""
    sock = ws.transport.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SOCKET_SEND_BUFFER)


def _response(status: HTTPStatus, body: bytes, ctype: str) -> Response:
    return response(status, body, ctype, close=True)


def _peer(conn: ServerConnection) -> str:
    try:
        addr = conn.remote_address
        return f"{addr[0]}:{addr[1]}"
    except Exception:
        return "?"
