"""The participant's page over HTTP, for both servers that serve it: a live trial's VR bridge
(services/human_input) and a session's page (`hrc session`). Where the page's files are, how
one is looked up safely and answered, who may bind off loopback, and the options of the
address the page is served on (`--vr-host`, `--vr-port` and their environment defaults)."""

from __future__ import annotations

import argparse
import hmac
import ipaddress
import os
from http import HTTPStatus
from pathlib import Path
from typing import TYPE_CHECKING

from hrc.paths import project_root
from hrc.service_table import VR_DEFAULT_HOST, VR_DEFAULT_PORT

if TYPE_CHECKING:
    from websockets.http11 import Response

CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".mjs": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".json": "application/json",
    ".map": "application/json",
    ".wasm": "application/wasm",
    ".svg": "image/svg+xml",
    ".png": "image/png",
    ".jpg": "image/jpeg",
    ".jpeg": "image/jpeg",
    ".urdf": "application/xml",
    ".xml": "application/xml",
    ".stl": "model/stl",
    ".dae": "model/vnd.collada+xml",
    ".obj": "model/obj",
    ".mtl": "text/plain",
    ".glb": "model/gltf-binary",
    ".gltf": "model/gltf+json",
    ".bin": "application/octet-stream",
    ".txt": "text/plain; charset=utf-8",
}
TEXT = CONTENT_TYPES[".txt"]
HTML = CONTENT_TYPES[".html"]
PAGE_PATHS = ("/", "/index.html")
NOT_BUILT = (
    b"The 3D participant client is not built: run <code>scripts/setup.sh</code> (it bundles "
    b"services/human_input/client/ into client/dist/)."
)


def note(text: bytes) -> bytes:
    """A note at the top of a page that stands in for the client."""
    return b'<p style="background:#fe9;padding:6px">' + text + b"</p>"


def client_dist() -> Path:
    """The participant client's bundle (built by scripts/setup.sh from
    services/human_input/client/); HRC_CLIENT_DIST serves another build (a developer's, built
    with build.mjs --out DIR)."""
    env = os.environ.get("HRC_CLIENT_DIST")
    return Path(env) if env else project_root() / "services" / "human_input" / "client" / "dist"


def built_page(client_dir: Path | None) -> bytes | None:
    """The client's index.html, or None when its bundle is not built there."""
    if client_dir is not None:
        index = client_dir / "index.html"
        if index.is_file():
            return index.read_bytes()
    return None


def not_built_page() -> bytes:
    """What a server shows instead of the client when its bundle is missing."""
    return b"<!doctype html><title>hrc-cosim</title><body>" + note(NOT_BUILT) + b"</body>"


def safe_file(root: Path, rel: str) -> Path | None:
    """``root/rel`` if it is a file inside ``root`` (no ``..``, no way out through a link)."""
    parts = [p for p in rel.split("/") if p]
    if not parts or any(p in (".", "..") or "\\" in p or "\x00" in p for p in parts):
        return None
    base = root.resolve()
    cand = base.joinpath(*parts).resolve()
    return cand if cand.is_relative_to(base) and cand.is_file() else None


def content_type(path: Path) -> str:
    return CONTENT_TYPES.get(path.suffix.lower(), "application/octet-stream")


def response(status: HTTPStatus, body: bytes, ctype: str = TEXT, close: bool = False) -> Response:
    """An HTTP answer that no cache keeps (``close``: the connection ends after it)."""
    # imported here: the CLI reads this module's options at every start, without a server
    from websockets.datastructures import Headers
    from websockets.http11 import Response

    fields = [("Content-Type", ctype), ("Content-Length", str(len(body)))]
    fields.append(("Cache-Control", "no-store"))
    if close:
        fields.append(("Connection", "close"))
    return Response(status.value, status.phrase, Headers(fields), body)


def page_file(path: str, page: bytes, client_dir: Path | None) -> Path | bytes | None:
    """What a GET of `path` asks for among the page's own files: the page itself (its bytes),
    a file of the client's bundle (its path), or None (not one of them)."""
    if path in PAGE_PATHS:
        return page
    if path.startswith("/assets/") and client_dir is not None:
        return safe_file(client_dir / "assets", path.removeprefix("/assets/"))
    return None


def key_ok(given: str | None, expected: str | None) -> bool:
    """`given` matches the key a server expects (in constant time); no key expected: any."""
    if expected is None:
        return True
    return given is not None and hmac.compare_digest(given.encode(), expected.encode())


def is_loopback(host: str) -> bool:
    if host in ("localhost", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False  # a host name other than localhost may resolve to anything


def bind_problem(
    host: str, token: str | None, what: str, harm: str, give: str = "one in HRC_VR_TOKEN"
) -> str:
    """Why serving `what` on `host` is refused ("" when it is not): off loopback, anyone on the
    network could reach it, so a token is needed (`give`: where the user gives one)."""
    if is_loopback(host) or token:
        return ""
    return (
        f"refusing to bind {what} to {host!r} without a token: anyone on the network could "
        f"{harm}. Give {give}, or bind 127.0.0.1"
    )


def default_host() -> str:
    return os.environ.get("HRC_VR_HOST", VR_DEFAULT_HOST)


def add_address_options(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    *,
    host_flag: str = "--vr-host",
    host_help: str,
    port_help: str | None = None,
) -> None:
    """`--vr-host` (or `host_flag`; env HRC_VR_HOST, default loopback) and, unless `port_help`
    is None, `--vr-port` (env HRC_VR_PORT, default VR_DEFAULT_PORT)."""
    parser.add_argument(host_flag, default=default_host(), help=host_help)
    if port_help is not None:
        port = int(os.environ.get("HRC_VR_PORT", VR_DEFAULT_PORT))
        parser.add_argument("--vr-port", type=int, default=port, help=port_help)
