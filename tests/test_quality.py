"""Quality gates, run in the suite so that CI enforces them: ruff on src/ scripts/ tests/, mypy on src/."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _tool(name: str) -> str:
    found = BIN / name
    return str(found) if found.exists() else (shutil.which(name) or name)


def test_ruff_clean_on_src_scripts_and_tests():
    proc = subprocess.run(
        [_tool("ruff"), "check", "src", "scripts", "tests"], cwd=ROOT, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_mypy_clean_on_src():
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "src/pkmtol"], cwd=ROOT, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
