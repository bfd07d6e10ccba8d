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


def test_a_file_beyond_the_size_limit_is_refused_unread(files, tmp_path, monkeypatch):
    """A measurement file larger than MAX_FILE_BYTES is refused before it is parsed."""
    import pkmtol.calibration.measurement_files as mf

    mech, good, plan, allocation = files
    monkeypatch.setattr(mf, "MAX_FILE_BYTES", 4096)
    big = fz.Case("good", "csv", good * 4, wrong=True)  # 14 kB of rows (duplicated poses)
    code, err, written = fz.run_cli(big, tmp_path, good)
    assert code == 2 and "holds more than 0 MiB" in err and written == []
    alloc = fz.Case("allocation", "allocation", allocation + " " * 5000, wrong=True)
    code, err, written = fz.run_cli(alloc, tmp_path, good)
    assert code == 2 and "not an allocation.json" in err and written == []


@pytest.mark.parametrize("option", ["--measurements", "--tolerances"])
def test_an_endless_device_is_refused_without_running_out_of_memory(files, tmp_path, option):
    """``--measurements /dev/zero`` read until the kernel killed pkmtol (23 GB); now 256 MiB at most.

    Run in a process limited to 2 GB of address space, so that the old behaviour fails the test
    (MemoryError) instead of the machine.
    """
    import resource
    import subprocess

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))

    argv = ["calibrate", str(fz.SEED_ROBOT), "--out", str(tmp_path / "out")]
    if option == "--measurements":
        argv += ["--measurements", "/dev/zero"]
    else:
        (tmp_path / "m.csv").write_text(files[1])
        argv += ["--measurements", str(tmp_path / "m.csv"), "--prior", "--tolerances", "/dev/zero"]
    proc = subprocess.run(
        [sys.executable, "-m", "pkmtol.cli", *argv],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
        env={**__import__("os").environ, "PYTHONPATH": str(ROOT / "src")},
        stdin=subprocess.DEVNULL,
    )
    assert proc.returncode == 2, proc.stderr[-500:]
    assert "/dev/zero" in proc.stderr and "holds more than 256 MiB" in proc.stderr, proc.stderr[-500:]
