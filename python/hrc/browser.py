"""Headless Debian chromium driven over the DevTools protocol (Playwright for Python).

Used by the browser tests (participant client, rerun web viewer, study report) and by the
benches that time a page. Playwright is pointed at the system chromium with `executable_path`;
it never downloads a browser (nothing but the package registries is reachable here).
WebGL runs in software (SwiftShader): no GPU is needed.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from hrc.paths import project_root

if TYPE_CHECKING:
    from playwright.sync_api import Browser

# Software WebGL; the page's layers composited in software too (SwiftShader's compositing cost
# about a third more CPU per frame: `hrc bench client`); no sandbox (CI runs as root, where the
# sandbox cannot start); and none of chromium's own connections (the network is closed here:
# they fail, many at a time).
CHROMIUM_ARGS = (
    "--no-sandbox",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--disable-gpu-compositing",
    "--autoplay-policy=no-user-gesture-required",
)


class BrowserMissing(RuntimeError):
    """Debian's chromium is not installed."""


def chromium_path() -> str:
    """The system chromium; HRC_CHROMIUM overrides."""
    path = (
        os.environ.get("HRC_CHROMIUM")
        or shutil.which("chromium")
        or shutil.which("chromium-browser")
    )
    if not path:
        raise BrowserMissing(
            "Debian's chromium is missing: scripts/setup.sh installs it (apt install chromium)"
        )
    return path


@contextmanager
def headless_chromium(extra_args: tuple[str, ...] = ()) -> Iterator[Browser]:
    """A headless chromium for the duration of the block (closed on exit, also on errors)."""
    from playwright.sync_api import sync_playwright  # heavy import, only where a browser is used

    os.environ.setdefault("PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD", "1")
    with sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=chromium_path(),
            headless=True,
            args=[*CHROMIUM_ARGS, *extra_args],
        )
        try:
            yield browser
        finally:
            browser.close()


def output_dir(name: str) -> Path:
    """Where a test or bench saves what a person should look at (screenshots, pages):
    `test-output/<name>/` in the project (HRC_TEST_OUTPUT overrides the root). Created."""
    root = Path(os.environ.get("HRC_TEST_OUTPUT") or project_root() / "test-output")
    path = root / name
    path.mkdir(parents=True, exist_ok=True)
    return path
