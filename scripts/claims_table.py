"""The claims of the seed robot's designs, per mode and method, checked on exact kinematics (docs/claims.md).

For each compensation mode (ideal, calibrated, none) and method (fosm, exact): the design's claim,
the exact Gaussian reliability of the linear model at every grid pose (its minimum and where), and
at that worst grid pose a Monte Carlo on exact kinematics: machines drawn at the design's σ
(Gaussian; under ``calibrated`` the identified errors at their manufacturing σ and the tracker
noise too), compensated as the mode says (Eq. 25; a simulated calibration on exact kinematics;
nothing) and solved exactly, with a Wilson 95 % interval over machines (one pose per machine).
Then the CPU time of ``allocate`` with its default sample counts and the tolerances' cost under
the robot's ``[cost]`` model, and where the exact design is tighter than FOSM.

Runs on this checkout's code or an older one (``PYTHONPATH``): what it needs of the result it
computes itself. ``--machines`` and ``--calibrated-machines`` set the Monte Carlo sizes.

    PYTHONPATH=src python scripts/claims_table.py --machines 1000 --calibrated-machines 400
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pkmtol.calibration.maps import pose_maps
from pkmtol.design.cost import cost_model
from pkmtol.design.exact import grid_reliability
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.design.mode_verification import calibrated_exact, ideal_exact
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism
from pkmtol.statistics import wilson_interval

ROOT = Path(__file__).resolve().parents[1]


def _sigma(r) -> np.ndarray:  # noqa: ANN001
    unc = r.uncompensatable
    return r.method_design.sigma if r.method_design is not None else r.tolerances[unc, r.design_column]


def _noise_cov(maps) -> np.ndarray | None:  # noqa: ANN001
    if not maps.position_noise.shape[2] or maps.noise_m <= 0:
        return None
    N = maps.position_noise
    return maps.noise_m**2 * (N @ np.swapaxes(N, 1, 2))


def _claim_text(r) -> str:  # noqa: ANN001
    claim = getattr(r, "claim", None)
    if claim is None:  # the code before the scoped claim printed this line
        return f"claimed by FOSM: R = {100 * r.reliability_fosm[r.design_column]:.2f} %"
    from pkmtol.present.headline import claim_line

    return claim_line(claim, r.compensation == "calibrated")


def _exact_at(mech, r, k: int, machines: int, seed: int) -> tuple[int, int, float]:  # noqa: ANN001
    """Failures, machines solved and seconds of the exact Monte Carlo at grid pose ``k``."""
    unc, sigma = r.uncompensatable, np.where(np.isfinite(_sigma(r)), _sigma(r), 0.0)
    rng = np.random.default_rng(seed)
    if r.compensation == "calibrated":
        chain = ClosedChain(mech)
        poses = pose_maps(r.grid, chain.actuated_idx, mech.reference_point_m, mech.task_projection)
        error = calibrated_exact(mech, r.pset, r.calibration_plan, poses)
        bg = [i for i, c in enumerate(r.mode_classes) if c == "identified"]
        bg_sigma = r.calibration_plan.settings.manufacturing_sigma(r.pset)[bg]
        M, noise_m = r.maps.position_noise.shape[2], r.maps.noise_m
    else:
        error = ideal_exact(mech, r.pset, r.grid, corrected=r.compensation == "ideal")
        bg, bg_sigma, M, noise_m = [], np.zeros(0), 0, 0.0
    fails = solved = 0
    t0 = time.perf_counter()
    for _ in range(machines):
        delta = np.zeros(len(r.pset))
        delta[unc] = rng.standard_normal(unc.size) * sigma
        if bg:
            delta[bg] = rng.standard_normal(len(bg)) * bg_sigma
        got = error(k, delta, rng.standard_normal(M) * noise_m)
        if got is None:
            continue
        solved += 1
        fails += int(float(np.linalg.norm(got[0])) > r.target_m)
    return fails, solved, time.perf_counter() - t0


def main() -> None:
    """Print the tables (Markdown)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--machines", type=int, default=1000)
    ap.add_argument("--calibrated-machines", type=int, default=400)
    ap.add_argument("--modes", nargs="+", default=["ideal", "calibrated", "none"])
    ap.add_argument("--no-timing", action="store_true", help="skip the CPU-time runs at default samples")
    ap.add_argument("--set", dest="pset", choices=["dh", "urdf"], default=None, help="parameter set")
    args = ap.parse_args()
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    rows, costs = [], []
    for mode in args.modes:
        results = {}
        for method in ("fosm", "exact"):
            r = allocate(
                mech,
                DesignOptions(
                    samples=2000,
                    exact_samples=0,
                    verification_poses=200,
                    claim_poses=20,
                    method=method,
                    compensation=mode,
                    parameter_set=args.pset,
                ),
            )
            results[method] = r
            unc = r.uncompensatable
            sigma = np.where(np.isfinite(_sigma(r)), _sigma(r), 0.0)
            rel = grid_reliability(r.maps.position[:, :, unc], sigma, r.target_m, _noise_cov(r.maps))
            k = int(np.argmin(rel))
            n = args.calibrated_machines if mode == "calibrated" else args.machines
            fails, solved, secs = _exact_at(mech, r, k, n, seed=29)
            lo, hi = wilson_interval(fails, solved)
            rows.append(
                f"| {mode} | {method} | design pose {r.worst_index} | {_claim_text(r)} | {k} | "
                f"{100 * rel[k]:.2f} | {100 * (1 - fails / solved):.2f} [{100 * (1 - hi):.2f}, "
                f"{100 * (1 - lo):.2f}] ({solved} machines, {secs:.0f} s) | {100 * rel.mean():.2f} |"
            )
        f, e = results["fosm"], results["exact"]
        unc = f.uncompensatable
        model = cost_model([f.pset.parameters[i] for i in unc], mech.extra.get("cost"))
        sf, se = _sigma(f), _sigma(e)
        ratio = se / sf
        order = np.argsort(ratio)
        names = [f.pset.names[i] for i in unc]
        cpu = {}
        if not args.no_timing:
            for method in ("fosm", "exact"):
                t0 = time.process_time()
                allocate(mech, DesignOptions(method=method, compensation=mode, parameter_set=args.pset))
                cpu[method] = time.process_time() - t0
        costs.append(
            f"| {mode} | {model.cost(sf):.4g} | {model.cost(se):.4g} | "
            f"{np.min(ratio):.3f} ({names[order[0]]}) | {np.median(ratio):.3f} | "
            f"{np.max(ratio):.3f} ({names[order[-1]]}) | "
            + (f"{cpu['fosm']:.1f} | {cpu['exact']:.1f} |" if cpu else "- | - |")
        )
    print(
        "| mode | method | design pose | printed claim | worst grid pose | linear R there [%] | "
        "exact kinematics R there [%] [95 % CI] | grid mean linear R [%] |"
    )
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print()
    print(
        "| mode | cost, FOSM | cost, exact every | exact/FOSM σ, min | median | max | "
        "CPU s, FOSM default samples | CPU s, exact |"
    )
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(costs))


if __name__ == "__main__":
    main()
