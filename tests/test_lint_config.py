"""The linter configurations say what scripts/lint.sh promises: 100 columns, the import sections,
every --strict flag on python/hrc, one C++ naming style. Each tool runs on a small snippet."""

from __future__ import annotations

import configparser
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hrc.paths import project_root

ROOT = project_root()
VENV_BIN = Path(sys.executable).parent


def _tool(name: str, where: str) -> str:
    path = shutil.which(name, path=str(VENV_BIN)) or shutil.which(name)
    if path is None:
        pytest.fail(f"{name} is missing: scripts/setup.sh installs it ({where})")
    return path


def _ruff(tmp_path: Path, text: str) -> subprocess.CompletedProcess[str]:
    src = tmp_path / "snippet.py"
    src.write_text(text)
    return subprocess.run(
        [
            _tool("ruff", "requirements.lock"),
            "check",
            "--no-cache",
            "--config",
            str(ROOT / "ruff.toml"),
            "--output-format",
            "concise",
            str(src),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )


def test_ruff_accepts_the_house_import_order_and_100_columns(tmp_path: Path) -> None:
    text = (
        "import json\n\nimport numpy as np\n\nfrom hrc.wire import pb\n\n"
        "from hrc_physics.world import World\n\n"
        f"X = [{', '.join(['1'] * 30)}, 1234]\n"  # exactly 100 columns
        "print(json, np, pb, World, X)\n"
    )
    assert max(len(line) for line in text.splitlines()) == 100
    proc = _ruff(tmp_path, text)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_ruff_flags_101_columns_and_a_service_import_among_the_library(tmp_path: Path) -> None:
    text = (
        "import json\n\nfrom hrc_physics.world import World\nfrom hrc.wire import pb\n\n"
        f"X = [{', '.join(['1'] * 30)}, 12345]\n"
        "print(json, pb, World, X)\n"
    )
    proc = _ruff(tmp_path, text)
    assert proc.returncode == 1
    assert "E501" in proc.stdout and "I001" in proc.stdout, proc.stdout


def test_mypy_sets_every_strict_flag_on_python_hrc() -> None:
    helptext = subprocess.run(
        [_tool("mypy", "requirements.lock"), "--help"], capture_output=True, text=True, check=True
    ).stdout
    block = re.search(
        r"--strict\s+Strict mode; enables the following flags:(.*?)\n  --", helptext, re.S
    )
    assert block, "mypy --help no longer lists the --strict flags"
    flags = re.findall(r"--([a-z]+(?:-\s*[a-z]+)*)", block.group(1))
    ini = configparser.ConfigParser()
    ini.read(ROOT / "mypy.ini")
    for flag in flags:
        key = re.sub(r"-\s*", "_", flag)
        on = any(ini.get(section, key, fallback="") == "True" for section in ("mypy", "mypy-hrc.*"))
        assert on, f"mypy.ini does not set {key} for python/hrc (part of --strict)"


def test_clang_format_wraps_at_100_columns_and_keeps_short_forms() -> None:
    kept = (
        "int twice(int x) { return 2 * x; }\n"
        "void check(int v) {\n"
        '  if (v < 0) throw std::invalid_argument("negative");\n'
        "}\n"
    )
    long_call = (
        "void f() {\n  call_something(argument_number_one, argument_number_two, "
        "argument_number_three, argument_number_four);\n}\n"
    )  # 104 columns
    fmt = _tool("clang-format", "Debian package clang-format")
    for text in (kept, long_call):
        out = subprocess.run(
            [fmt, "--style=file", "--assume-filename", str(ROOT / "services/ik_cpp/src/x.cpp")],
            input=text,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        assert max(len(line) for line in out.splitlines()) <= 100
        if text is kept:
            assert out == kept
        else:
            assert out != text


def test_clang_tidy_naming_style(tmp_path: Path) -> None:
    src = tmp_path / "naming.cpp"
    src.write_text(
        "constexpr double kDegToRad = 0.0174533;\n"
        "class GoodType {\n public:\n  int public_count = 0;\n  int do_work(int world_T_base);\n"
        " private:\n  int count_ = 0;\n  int badMember = 0;\n};\n"
        "int badFunction(int R) { return R; }\n"
        "int good_function(int camelParam) { return camelParam; }\n"
    )
    tidy = _tool("clang-tidy", "Debian package clang-tidy")
    proc = subprocess.run(
        [
            tidy,
            "--quiet",
            f"--config-file={ROOT / 'services/ik_cpp/.clang-tidy'}",
            str(src),
            "--",
            "-std=c++17",
        ],
        capture_output=True,
        text=True,
    )
    named = set(re.findall(r"invalid case style for [a-z ]+ '(\w+)'", proc.stdout))
    assert named == {"badMember", "badFunction", "camelParam"}, proc.stdout + proc.stderr
