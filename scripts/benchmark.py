"""Benchmarks of pkmtol, printed as a table (never run as timed tests).

Usage:
    python scripts/benchmark.py [robots/r2rps_ups] [--repeat 3]

Rows (targets from the issues, on one core of the 2-core CI machine):
    * inverse kinematics over the task-space grid, warm-started          target ≥ 2,000 poses/s
    * inverse kinematics + error model + separation + J over the grid     target ≥ 1,000 poses/s
    * `pkmtol allocate` main job with defaults, per stage and in total    target ≤ 10 s
    * exact reliability of the linear model at one pose                   target ≤ 1 ms
    * cost-optimal design over the 147 grid poses                         target ≤ 20 s
The best of ``--repeat-fast`` (sub-second rows) or ``--repeat`` runs is reported: this machine is a
shared VM whose speed varies by up to ±40 % from one process to the next; the best run is the least
disturbed one.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

# one BLAS thread: the matrices are 6×6 to 21×21; threads only add synchronisation
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from pkmtol.design.job import DesignOptions, allocate, method_design_for  # noqa: E402
from pkmtol.design.reliability import exact_reliability  # noqa: E402
from pkmtol.error_model.parameters import default_set, parameter_set  # noqa: E402
from pkmtol.error_model.sweep import sweep  # noqa: E402
from pkmtol.kinematics.closed_chain import ClosedChain  # noqa: E402
from pkmtol.model.loader import load_mechanism  # noqa: E402


def best_of(repeat: int, fn) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("robot", nargs="?", default="robots/r2rps_ups", type=Path)
    ap.add_argument("--repeat", type=int, default=3, help="runs of the slow rows (allocate, cost)")
    ap.add_argument("--repeat-fast", type=int, default=20, help="runs of the sub-second rows")
    args = ap.parse_args()
    mech = load_mechanism(args.robot)
    grid = mech.task_space.grid()
    chain = ClosedChain(mech)
    pset = parameter_set(mech, default_set(mech))

    def ik_grid() -> None:
        pose = chain.inverse(grid[0], chain.home())
        for p in grid[1:]:
            pose = chain.inverse(p, chain.predict(pose, p))

    # the fast rows are interleaved, run after run, so that a slow spell of the VM hits all of them
    fast = {"ik": ik_grid, "sweep": lambda: sweep(mech, pset, grid, chain)}
    best = dict.fromkeys(fast, float("inf"))
    for _ in range(args.repeat_fast):
        for key, fn in fast.items():
            best[key] = min(best[key], best_of(1, fn))
    rows = [
        (
            "inverse kinematics, grid",
            f"{len(grid)} poses",
            best["ik"],
            f"{len(grid) / best['ik']:,.0f} poses/s",
            "≥ 2,000 poses/s",
        ),
        (
            f"IK + error model + separation + J ({pset.kind})",
            f"{len(grid)} poses",
            best["sweep"],
            f"{len(grid) / best['sweep']:,.0f} poses/s",
            "≥ 1,000 poses/s",
        ),
    ]

    results = []
    t = best_of(args.repeat, lambda: results.append(allocate(mech, DesignOptions())))
    stages = min(results, key=lambda r: sum(r.timings_s.values())).timings_s
    for name, secs in stages.items():
        rows.append((f"  allocate: {name}", "", secs, "", ""))
    rows.append(("allocate (defaults), total", "", t, f"{t:.2f} s", "≤ 10 s"))

    res = min(results, key=lambda r: sum(r.timings_s.values()))
    unc = res.uncompensatable
    J = res.grid.J[res.worst_index][:, unc] * res.tolerances[unc, res.design_column]
    cov = J @ J.T
    n_calls = 1000
    t = best_of(args.repeat_fast, lambda: [exact_reliability(cov, res.target_m) for _ in range(n_calls)])
    rows.append(
        ("exact reliability, one pose", f"{n_calls} calls", t, f"{1e3 * t / n_calls:.3f} ms/call", "≤ 1 ms")
    )
    t = best_of(
        args.repeat,
        lambda: method_design_for(
            mech,
            res.pset,
            res.grid,
            unc,
            res.tolerances[unc, res.design_column],
            res.target_m,
            res.design_beta,
            res.worst_index,
            DesignOptions(method="cost"),
        ),
    )
    rows.append(("cost-optimal design (incl. reference)", f"{len(grid)} poses", t, f"{t:.2f} s", "≤ 20 s"))

    w = max(len(r[0]) for r in rows)
    print(
        f"pkmtol benchmark — {mech.name}, best of {args.repeat_fast} (fast rows) / {args.repeat} runs, "
        f"numpy {np.__version__}"
    )
    print(f"{'stage'.ljust(w)}  {'size':>11}  {'time [s]':>9}  {'rate':>16}  target")
    print("-" * (w + 60))
    for name, size, secs, rate, target in rows:
        print(f"{name.ljust(w)}  {size:>11}  {secs:9.3f}  {rate:>16}  {target}")


if __name__ == "__main__":
    main()
