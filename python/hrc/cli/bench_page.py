"""The participant page's frame time, a figure of ``hrc bench client``.

The page (services/human_input/client, as the bridge serves it) runs in headless Debian
chromium with software WebGL (:mod:`hrc.browser`) as a spectator of the bench's live trial,
desktop view, 1280 x 800. It records, per rendered frame, the interval since the previous one and
its own work (scene update and the render call); the figures are their p50 / p95 over a window
while the robots move. Without a GPU the interval is mostly SwiftShader's rasterisation, and on a
loaded machine mostly waiting for a core: the CPU time chromium's processes spent per frame
(`cpu_ms_per_frame`: GPU process, page's renderer, all) is the figure that load changes least.
It says how heavy the scene is, not what a headset would show.
"""

from __future__ import annotations

import logging
import math
import os
import time
from typing import TYPE_CHECKING, Any

from hrc.browser import headless_chromium

if TYPE_CHECKING:
    from playwright.sync_api import ViewportSize

    from hrc.cli.bench_client import BenchContext

log = logging.getLogger(__name__)
VIEWPORT: ViewportSize = {"width": 1280, "height": 800}


def _pct(xs: list[float], q: float) -> float:
    if not xs:
        return math.nan
    s = sorted(xs)
    return s[max(0, min(len(s) - 1, math.ceil(q / 100 * len(s)) - 1))]


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            kids = [int(x) for x in f.read().split()]
    except OSError:
        return []
    return kids + [g for k in kids for g in _children(k)]


def _chromium_cpu_s() -> dict[str, float]:
    """CPU seconds (user + system) so far of this process's chromium descendants, by kind."""
    tick = os.sysconf("SC_CLK_TCK")
    out = {"gpu": 0.0, "renderer": 0.0, "all": 0.0}
    for pid in _children(os.getpid()):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmd = f.read().decode(errors="replace")
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if "chrom" not in cmd:
            continue
        cpu = (int(fields[11]) + int(fields[12])) / tick  # utime, stime
        out["all"] += cpu
        if "--type=gpu-process" in cmd:
            out["gpu"] += cpu
        elif "--type=renderer" in cmd:
            out["renderer"] += cpu
    return out


def page_frame_time(url: str, seconds: float = 5.0, warmup_s: float = 2.0) -> dict[str, Any]:
    """Opens the page at ``url`` (a running live trial's bridge) and measures its frame times
    for ``seconds`` after ``warmup_s``; p50 / p95 in ms and the frame count."""
    with headless_chromium() as browser:
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(url + "?mode=desktop")
        page.wait_for_function("window.hrcTest && window.hrcTest.ready()", timeout=120_000)
        time.sleep(warmup_s)
        page.evaluate("window.hrcTest.frameTimes(true)")
        cpu0 = _chromium_cpu_s()
        time.sleep(seconds)
        times = page.evaluate("window.hrcTest.frameTimes(true)")
        cpu1 = _chromium_cpu_s()
    intervals: list[float] = times["intervals"]
    work: list[float] = times["work"]
    n = max(1, len(intervals))
    return {
        "frames": len(intervals),
        "cpu_ms_per_frame": {k: round(1000 * (cpu1[k] - cpu0[k]) / n, 1) for k in cpu0},
        "interval_ms": {"p50": round(_pct(intervals, 50), 1), "p95": round(_pct(intervals, 95), 1)},
        "work_ms": {"p50": round(_pct(work, 50), 1), "p95": round(_pct(work, 95), 1)},
        "viewport": f"{VIEWPORT['width']}x{VIEWPORT['height']}",
    }


def page_figures(ctx: BenchContext) -> dict[str, Any]:
    """For :data:`hrc.cli.bench_client.EXTRA_FIGURES`; a page that fails (no chromium, not
    ready in time) is reported as the figure's error, not the end of the whole bench."""
    try:
        return {"page_frame_ms": page_frame_time(ctx.url)}
    except Exception as exc:  # playwright's errors, BrowserMissing, ...
        log.warning("page frame time not measured: %s", exc)
        return {"page_frame_ms": {"error": str(exc).splitlines()[0]}}
