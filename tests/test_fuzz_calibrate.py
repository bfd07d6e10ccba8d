"""The calibrate fuzzer in CI (scripts/fuzz_calibrate.py): 0 tracebacks, 0 exit-0 runs on wrong data.

1,000 seeded mutations go through the readers (measurement CSV, allocation.json), about 5 ms each.
A command-line case costs 1–4 s (the fit on exact kinematics), so the CLI gets the first case of
every mutation kind of a second seed (22 kinds), not 1,000: ``python scripts/fuzz_calibrate.py
--cases 20000 --cli-every N`` runs more.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

import fuzz_calibrate as fz  # noqa: E402


@pytest.fixture(scope="module")
def files():
    return fz.session()


def test_a_thousand_mutated_files_give_no_traceback_in_the_readers(files, tmp_path):
    mech, good, plan, allocation = files
    rng = np.random.default_rng(25)
    outcomes = {"refused": 0, "read": 0}
    escapes = []
    for i in range(1000):
        case = fz.mutate(rng, good, plan, allocation)
        got = fz.run_reader(case, mech, tmp_path)
        if got.startswith("ESCAPE"):
            escapes.append(f"case {i} ({case.mutation}): {got}")
        else:
            outcomes[got] += 1
    assert escapes == []
    assert outcomes["refused"] > 300 and outcomes["read"] > 300  # both paths exercised


def test_every_mutation_through_the_command_line(files, tmp_path):
    mech, good, plan, allocation = files
    rng = np.random.default_rng(26)
    first: dict[str, fz.Case] = {}
    for _ in range(600):
        case = fz.mutate(rng, good, plan, allocation)
        first.setdefault(case.mutation, case)
    assert len(first) >= 20
    problems = []
    for name, case in sorted(first.items()):
        code, err = fz.run_cli(case, tmp_path)
        if not isinstance(code, int) or "Traceback" in err:
            problems.append(f"{name}: {code} {err[-300:]}")
        elif code == 0 and case.wrong:
            problems.append(f"{name}: exit 0 on data that cannot be right")
        elif code not in (0, 2):
            problems.append(f"{name}: exit {code}")
    assert problems == []
