"""docs/instruments.md: its comparison table is the rendering of what compare_instruments.py measured."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location(
        "compare_instruments", ROOT / "scripts" / "compare_instruments.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_table_is_the_scripts_output():
    mod = _script()
    doc = json.loads(mod.DATA.read_text(encoding="utf-8"))
    assert set(doc["robots"]) == set(mod.ROBOTS)
    assert all(len(rows) == len(mod.ROWS) for rows in doc["robots"].values())
    assert mod.page_with(mod.render(doc)) == mod.PAGE.read_text(encoding="utf-8")
