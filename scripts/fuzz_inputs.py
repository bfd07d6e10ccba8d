"""Fuzz robot folders: mutated mechanism.toml and URDF bytes and values, loaded and exercised.

Runs the seeded, bounded fuzzer of ``tests/fuzzing.py`` (the one ``tests/test_fuzz.py`` runs 2,000
cases of) for as many cases as asked and prints a table of outcomes: ``ok`` (the mutant is a valid
robot and its error model runs), each :class:`pkmtol.PkmtolError` subclass raised, and ``BUG`` for
any other exception (with its traceback below the table), with the slowest case and the hangs (over
10 s). Exit code 1 if there is a bug or a hang.

Usage:
    python scripts/fuzz_inputs.py --cases 20000 --seed 0
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fuzzing import HANG_S, fuzz  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=20_000, help="number of cases (default 20000)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the run (default 0)")
    ap.add_argument("--start", type=int, default=0, help="first case index (to resume or split a run)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)  # numpy overflow notes on absurd values
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        report = fuzz(args.cases, args.seed, Path(tmp), args.start)
    wall = time.perf_counter() - t0
    print(
        f"fuzz: {report.cases} cases, seed {args.seed}, cases {args.start}..{args.start + report.cases - 1}"
    )
    width = max(len(k) for k in report.outcomes)
    for outcome, n in sorted(report.outcomes.items(), key=lambda kv: -kv[1]):
        print(f"  {outcome:<{width}}  {n:>6}  {100 * n / report.cases:5.1f} %")
    print(f"slowest case {report.slowest_s:.3f} s; hangs (> {HANG_S:g} s): {len(report.hangs)}")
    print(f"wall time {wall:.1f} s")
    for index, tb in report.bugs:
        print(f"\n---- case {index}\n{tb}")
    return 1 if report.bugs or report.hangs else 0


if __name__ == "__main__":
    sys.exit(main())
