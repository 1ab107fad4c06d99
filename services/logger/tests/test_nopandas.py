"""The logger's process keeps pandas out (hrc_logger.nopandas) and still writes its view."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = """
import sys
from hrc_logger.nopandas import block_pandas
block_pandas()
import rerun as rr
from hrc_logger.entities import CLEAR
from hrc_logger.view import View, open_recording
view = View(open_recording(sys.argv[1], "nopandas"))
view.setup(None)
view._log("events", rr.TextLog("hello"))
view._log("world/x", rr.Points3D([[1.0, 2.0, 3.0]], colors=[(1, 2, 3)], labels=["x"]))
view._log("world/x", CLEAR)
view.close()
assert "pandas" not in sys.modules, "pandas was imported"
try:
    import pandas  # noqa: F401
except ModuleNotFoundError as exc:
    print("refused:", exc)
"""


def test_view_works_without_pandas(tmp_path: Path) -> None:
    rrd = tmp_path / "x.rrd"
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(rrd)], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert "refused: pandas is kept out of the logger's process" in out.stdout
    assert "Warning" not in out.stderr, out.stderr  # rerun warns instead of raising
    assert rrd.stat().st_size > 0
