"""The session's web server: the participant's page (the same client as a live trial's) and
one WebSocket, `/session`, through which the page shows the screens between trials and sends
back what the participant did (docs/client-protocol.md, "Sessions").

An asyncio loop in its own thread; the session's main thread calls `show` and reads `inbox`.
Only the page that presents the participant's key (`?driver=KEY`) talks to the session; a
newer page with the key replaces an older one (a reopened tab).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import queue
import threading
from http import HTTPStatus
from typing import Any
from urllib.parse import parse_qs, unquote, urlsplit

from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from hrc import jsontext
from hrc.webpage import (
    HTML,
    bind_problem,
    built_page,
    client_dist,
    content_type,
    key_ok,
    not_built_page,
    page_file,
    response,
)

log = logging.getLogger(__name__)

MAX_MESSAGE_BYTES = 256 * 1024  # a questionnaire's answers with free text


def check_bind(host: str, token: str | None) -> str:
    """A problem with serving the session on `host` ("" if none): off loopback, anyone on
    the network could answer for the participant without a token."""
    return bind_problem(host, token, "the session's page", "take the participant's place")


def _first(query: dict[str, list[str]], key: str) -> str | None:
    values = query.get(key)
    return values[0] if values else None


class SessionServer:
    def __init__(self, host: str, port: int, driver_key: str, token: str | None = None) -> None:
        self.host, self.port = host, port
        self.driver_key = driver_key
        self.token = token
        self.inbox: queue.Queue[tuple[str, dict[str, Any]]] = queue.Queue()
        self._screen: dict[str, Any] | None = None
        self._page: ServerConnection | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        self.bound_port = 0
        self.client_dir = client_dist()
        self._html = built_page(self.client_dir) or not_built_page()

    # ------------------------------------------------------------------ main thread
    def start(self, timeout: float = 10.0) -> int:
        self._thread = threading.Thread(target=self._run, name="session-web", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout) or self._error is not None:
            raise OSError(
                f"cannot serve the session page on {self.host}:{self.port}: {self._error}"
            )
        return self.bound_port

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(timeout=5)

    def __enter__(self) -> SessionServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def show(self, screen: dict[str, Any]) -> None:
        """What the page shows now (kept: a page that (re)connects gets it first)."""
        self.keep(screen)
        text = json.dumps(self._screen)
        loop = self._loop
        if loop is not None:
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._send_current, text)

    def keep(self, screen: dict[str, Any]) -> None:
        """What a page that (re)connects gets, without sending it to the page showing it now
        (a questionnaire's answers so far, which that page holds already)."""
        self._screen = json.loads(json.dumps({"type": "screen", **screen}))

    def connected(self) -> bool:
        return self._page is not None

    # ------------------------------------------------------------------ loop thread
    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:
            self._error = exc
            self._ready.set()

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        async with serve(
            self._handler,
            self.host,
            self.port,
            process_request=self._http,
            max_size=MAX_MESSAGE_BYTES,
            ping_interval=5,
            ping_timeout=10,
        ) as server:
            self.bound_port = int(next(iter(server.sockets)).getsockname()[1])
            self._ready.set()
            await self._stop.wait()

    def _send_current(self, text: str) -> None:
        page = self._page
        if page is not None:
            asyncio.get_running_loop().create_task(self._send(page, text))

    @staticmethod
    async def _send(ws: ServerConnection, text: str) -> None:
        with contextlib.suppress(ConnectionClosed):
            await ws.send(text)

    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        parts = urlsplit(request.path)
        query = parse_qs(parts.query)
        if parts.path == "/session" and request.headers.get("Upgrade", "").lower() != "websocket":
            # a page whose link drops asks whether its key still opens the session (204) or
            # not (403: the session was begun anew), to say so in words (session.js)
            if not key_ok(_first(query, "token"), self.token):
                return response(HTTPStatus.UNAUTHORIZED, b"wrong token\n")
            if not key_ok(_first(query, "driver"), self.driver_key):
                return response(HTTPStatus.FORBIDDEN, b"not this session's link\n")
            return response(HTTPStatus.NO_CONTENT, b"")
        if request.headers.get("Upgrade", "").lower() != "websocket":
            found = page_file(unquote(parts.path), self._html, self.client_dir)
            if isinstance(found, bytes):
                return response(HTTPStatus.OK, found, HTML)
            if found is None:
                return response(HTTPStatus.NOT_FOUND, b"not found\n")
            return response(HTTPStatus.OK, found.read_bytes(), content_type(found))
        if parts.path != "/session":
            return response(HTTPStatus.NOT_FOUND, b"the session's endpoint is /session\n")
        if not key_ok(_first(query, "token"), self.token):
            return response(HTTPStatus.UNAUTHORIZED, b"wrong token\n")
        if not key_ok(_first(query, "driver"), self.driver_key):
            return response(
                HTTPStatus.FORBIDDEN,
                b"only the participant's page (its link's driver key) takes part in the session\n",
            )
        return None

    async def _handler(self, ws: ServerConnection) -> None:
        old, self._page = self._page, ws
        if old is not None:  # a reopened tab: the newest page is the participant's
            with contextlib.suppress(ConnectionClosed):
                await old.close(4000, "another page of the participant took over")
        self.inbox.put(("connected", {}))
        if self._screen is not None:
            await self._send(ws, json.dumps(self._screen))
        try:
            async for raw in ws:
                if isinstance(raw, bytes):
                    continue
                try:
                    msg = jsontext.loads(raw)
                except ValueError:  # not JSON, or nested deeper than a page ever sends
                    continue
                if isinstance(msg, dict) and isinstance(msg.get("type"), str):
                    self.inbox.put(("page", msg))
        except ConnectionClosed:
            pass
        finally:
            if self._page is ws:
                self._page = None
                self.inbox.put(("gone", {}))
