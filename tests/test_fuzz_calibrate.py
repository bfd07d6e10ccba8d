"""The calibrate fuzzer in CI (scripts/fuzz_calibrate.py): 0 tracebacks, 0 exit-0 runs on wrong data.

1,000 seeded mutations go through the readers (measurement CSV, allocation.json), about 5 ms each,
and 1,000 through the command line (``pkmtol.cli.main`` in process: the real parser, loader, fit,
fit check and run folder; the process keeps each loaded robot and its grid sweep, as any caller of
``main`` does, :mod:`pkmtol.cli.robot_cache`), about 0.1 s each. A few run as subprocesses
(``python -m pkmtol.cli``), as a user runs them. ``python scripts/fuzz_calibrate.py --cases 20000
--cli-every 1`` runs more.
"""

from __future__ import annotations

import sys
from collections import Counter
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


def test_a_thousand_mutated_files_through_the_command_line(files, tmp_path):
    mech, good, plan, allocation = files
    rng = np.random.default_rng(26)
    exits: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    problems = []
    for i in range(1000):
        case = fz.mutate(rng, good, plan, allocation)
        code, err, written = fz.run_cli(case, tmp_path, good)
        problem = fz.cli_problem(case, code, err, written)
        if problem is not None:
            problems.append(f"case {i} ({case.mutation}): {problem}")
        exits[str(code)] += 1
        kinds[case.mutation] += 1
    assert problems == []
    assert len(kinds) == 22  # every mutation
    assert exits["0"] > 100 and exits["2"] > 500  # good files calibrate, wrong ones are refused


@pytest.mark.parametrize("mutation", ["good", "units", "allocation row"])
def test_cases_as_a_user_runs_them(files, tmp_path, mutation):
    mech, good, plan, allocation = files
    rng = np.random.default_rng(27)
    case = next(
        c for c in (fz.mutate(rng, good, plan, allocation) for _ in range(500)) if c.mutation == mutation
    )
    code, err, written = fz.run_cli_subprocess(case, tmp_path, good)
    assert fz.cli_problem(case, code, err, written) is None
    assert code == (0 if mutation == "good" else 2)


def test_a_second_target_column_is_refused(files, tmp_path):
    """Found by the fuzzer (seed 5): a header ``target,…,target`` read the last one silently."""
    mech, good, plan, allocation = files
    text = good.replace("pose,", "target,", 1)
    case = fz.Case("header cell", "csv", text, wrong=True)
    assert fz.run_reader(case, mech, tmp_path) == "refused"
    code, err, written = fz.run_cli(case, tmp_path, good)
    assert code == 2 and "'target': column given twice" in err and written == []
