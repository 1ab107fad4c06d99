"""The live VR bridge: a WebSocket endpoint taking samples from any headset application, and the
small WebXR page served on the same port (see the service README for the protocol).

Runs an asyncio event loop (websockets 15) in its own thread; the tick thread only reads the
latest accepted sample.
"""

from __future__ import annotations

import asyncio
import hmac
import ipaddress
import json
import logging
import threading
from dataclasses import dataclass
from http import HTTPStatus
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from hrc_human_input.sample import Sample, parse_sample

log = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
MAX_FRAME_BYTES = 64 * 1024
WS_PATHS = ("/ws", "/")
PAGE_PATHS = ("/", "/index.html")


class BridgeConfigError(ValueError):
    """The bridge would be unsafe or cannot start as configured."""


def is_loopback(host: str) -> bool:
    if host in ("localhost", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False  # a host name other than localhost may resolve to anything


def check_bind(host: str, token: str | None) -> None:
    """A bridge reachable from other machines must require a token."""
    if not is_loopback(host) and not token:
        raise BridgeConfigError(
            f"refusing to bind the VR bridge to {host!r} without a token: anyone on the network "
            "could drive the participant's hands. Give --vr-token (or HRC_VR_TOKEN), or bind "
            "127.0.0.1"
        )


def page_html() -> bytes:
    return resources.files("hrc_human_input").joinpath("web/index.html").read_bytes()


@dataclass
class BridgeStats:
    clients: int = 0
    accepted: int = 0
    rejected: int = 0
    auth_failures: int = 0


class VrBridge:
    """Accepts JSON samples over WebSocket and keeps the latest one."""

    def __init__(
        self,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        token: str | None = None,
        hello: dict[str, Any] | None = None,
    ) -> None:
        check_bind(host, token)
        self.host = host
        self.port = port
        self.token = token or None
        self.hello = dict(hello or {})
        self.stats = BridgeStats()
        self._page = page_html()
        self._lock = threading.Lock()
        self._latest: Sample | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: Server | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._error: BaseException | None = None
        self.bound_port = 0

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
            ping_interval=20,
            ping_timeout=20,
        ) as server:
            self._server = server
            self.bound_port = int(next(iter(server.sockets)).getsockname()[1])
            log.info(
                "VR bridge on ws://%s:%d/ws (page http://%s:%d/)%s",
                self.host,
                self.bound_port,
                self.host,
                self.bound_port,
                ", token required" if self.token else "",
            )
            self._ready.set()
            await self._stop.wait()

    # ------------------------------------------------------------------ HTTP (page) and handshake
    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        parts = urlsplit(request.path)
        upgrade = request.headers.get("Upgrade", "").lower() == "websocket"
        if not upgrade:
            if parts.path in PAGE_PATHS:
                return _response(HTTPStatus.OK, self._page, "text/html; charset=utf-8")
            return _response(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain; charset=utf-8")
        if parts.path not in WS_PATHS:
            return _response(
                HTTPStatus.NOT_FOUND, b"WebSocket endpoint is /ws\n", "text/plain; charset=utf-8"
            )
        given = parse_qs(parts.query).get("token")
        if given is not None and self.token is not None and not self._token_ok(given[0]):
            self.stats.auth_failures += 1
            log.warning("VR client %s: wrong token in the URL", _peer(connection))
            return _response(HTTPStatus.UNAUTHORIZED, b"wrong token\n", "text/plain; charset=utf-8")
        return None

    def _token_ok(self, given: Any) -> bool:
        return (
            isinstance(given, str)
            and self.token is not None
            and hmac.compare_digest(given.encode(), self.token.encode())
        )

    # ------------------------------------------------------------------ WebSocket
    async def _handler(self, ws: ServerConnection) -> None:
        peer = _peer(ws)
        query = parse_qs(urlsplit(ws.request.path).query) if ws.request else {}
        authed = self.token is None or self._token_ok(
            query["token"][0] if query.get("token") else None
        )
        self.stats.clients += 1
        log.info("VR client %s connected%s", peer, "" if authed else " (must authenticate)")
        try:
            await ws.send(json.dumps({"type": "hello", "auth_required": not authed, **self.hello}))
            async for message in ws:
                if isinstance(message, bytes):
                    await self._error_reply(ws, ["binary frames are not accepted: send JSON text"])
                    continue
                try:
                    obj = json.loads(message)
                except json.JSONDecodeError as exc:
                    await self._error_reply(ws, [f"not valid JSON: {exc.msg} (column {exc.colno})"])
                    continue
                if isinstance(obj, dict) and "token" in obj:
                    if self.token is None or self._token_ok(obj.get("token")):
                        authed = True
                        await ws.send(json.dumps({"type": "auth", "ok": True}))
                        continue
                    self.stats.auth_failures += 1
                    await self._error_reply(ws, ["wrong token"])
                    await ws.close(1008, "wrong token")
                    return
                if not authed:
                    self.stats.auth_failures += 1
                    await self._error_reply(
                        ws,
                        ['authenticate first: send {"token": "..."} or connect to /ws?token=...'],
                    )
                    await ws.close(1008, "token required")
                    return
                sample, problems = parse_sample(obj, require_t=False)
                if sample is None:
                    await self._error_reply(ws, problems)
                    continue
                with self._lock:
                    self._latest = sample
                self.stats.accepted += 1
        except ConnectionClosed:
            pass
        finally:
            log.info("VR client %s disconnected", peer)

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


def _response(status: HTTPStatus, body: bytes, content_type: str) -> Response:
    headers = Headers(
        [
            ("Content-Type", content_type),
            ("Content-Length", str(len(body))),
            ("Cache-Control", "no-store"),
            ("Connection", "close"),
        ]
    )
    return Response(status.value, status.phrase, headers, body)


def _peer(conn: ServerConnection) -> str:
    try:
        addr = conn.remote_address
        return f"{addr[0]}:{addr[1]}"
    except Exception:
        return "?"
