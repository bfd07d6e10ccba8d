"""Sweep the seed robot's wrist offset l (P = O' + (0, 0, l)) and watch the accuracy budget move.

For every l the error model is rebuilt over the task-space grid (the mechanism is the same; only
the reference point P changes, through ``dataclasses.replace(mech, reference_point_m=...)``) and
two tables are printed:

1. per l: the most error-sensitive grid point, the paper's pose-search quantity σ[Δλ] there
   (every uncompensatable D–H error ~ N(0, 1 m or 1 rad), so σ is in metres per unit error), and
   σ[Δλ] at the worst grid point when the tolerances of the reference design (l = --reference,
   β = --beta) are kept — how much accuracy a longer wrist costs if nothing is re-toleranced;
2. the FOSM tolerance of every uncompensatable error at β = --beta, one column per l.

Usage:
    python scripts/sweep_wrist_offset.py                          # l = 0.1 ... 0.5 m
    python scripts/sweep_wrist_offset.py --l 0.2 0.4 --beta 2    # a shorter sweep
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings
from pathlib import Path

import numpy as np

from pkmtol import KinematicsError, error_table, fosm_tolerances, load_mechanism, norm_moments
from pkmtol.error_model.accuracy import covariance_eigenvalues
from pkmtol.present.tables import text_table
from pkmtol.units import display_unit

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


def sweep_offsets(robot: Path, offsets_m: list[float], beta: float, reference_m: float) -> tuple[str, str]:
    """The two tables (plain text) of the sweep."""
    mech = load_mechanism(robot)
    rows = [["l [mm]", "worst P [mm]", "σ[Δλ], unit errors [m/unit]", "σ[Δλ], reference tolerances [µm]"]]
    tol_rows: list[list[str]] = []
    results = {}
    unreachable = {}
    for l_m in sorted({*offsets_m, reference_m}):
        variant = dataclasses.replace(mech, reference_point_m=np.array([0.0, 0.0, l_m]))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # scipy's round-off notes from the σ quadrature
                table = error_table(variant, "dh")
        except KinematicsError as err:  # the platform sinks as l grows: a leg may leave its stroke
            unreachable[l_m] = err
            continue
        unc = [i for i, c in enumerate(table.classes) if c == "uncompensatable"]
        tol = fosm_tolerances(table.sensitivity[unc], variant.target_m, np.array([beta]))[:, 0]
        results[l_m] = (table, unc, tol)
    if reference_m in unreachable:
        raise SystemExit(
            f"the reference design l = {reference_m} m is unreachable: {unreachable[reference_m]}"
        )
    ref_table, ref_unc, ref_tol = results[reference_m]
    for l_m in offsets_m:
        if l_m in unreachable:
            err = unreachable[l_m]
            joint = getattr(err, "joint", None)
            why = f"joint {joint} out of its limits" if joint else type(err).__name__
            rows.append([f"{l_m * 1e3:.0f}", "task space unreachable", why, "-"])
            continue
        table, unc, tol = results[l_m]
        assert unc == ref_unc, "the uncompensatable set does not depend on l"
        J = table.grid.J[:, :, unc]
        sigma_unit = norm_moments(covariance_eigenvalues(J[table.worst_index]))[1]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sigma_ref = max(norm_moments(covariance_eigenvalues(Jk, ref_tol))[1] for Jk in J)
        p = table.worst_point_m * 1e3
        rows.append(
            [
                f"{l_m * 1e3:.0f}",
                f"({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f})",
                f"{sigma_unit:.4f}",
                f"{sigma_ref * 1e6:.2f}",
            ]
        )
    header = ["No.", "parameter", "unit"] + [f"l={l_m * 1e3:.0f} mm" for l_m in offsets_m]
    tol_rows.append(header)
    for k, i in enumerate(ref_unc, start=1):
        param = ref_table.pset.parameters[i]
        scale = 1e3  # m → mm, rad → mrad
        cells = []
        for l_m in offsets_m:
            if l_m in unreachable:
                cells.append("-")
                continue
            t = results[l_m][2][k - 1]
            cells.append("free" if not np.isfinite(t) else f"±{t * scale:.4f}")
        tol_rows.append([str(k), param.name, display_unit(param.unit)] + cells)
    return text_table(rows), text_table(tol_rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", type=Path, default=ROBOT, help="robot folder (default: the seed robot)")
    ap.add_argument(
        "--l",
        type=float,
        nargs="+",
        default=[0.1, 0.2, 0.3, 0.4, 0.5],
        dest="offsets",
        help="wrist offsets l [m] (default 0.1 0.2 0.3 0.4 0.5)",
    )
    ap.add_argument("--beta", type=float, default=2.0, help="reliability index of the tolerances (default 2)")
    ap.add_argument(
        "--reference", type=float, default=0.3, help="l [m] of the reference design (default 0.3)"
    )
    args = ap.parse_args(argv)
    summary, tolerances = sweep_offsets(args.robot, args.offsets, args.beta, args.reference)
    print(
        f"wrist offset sweep of {args.robot.name}: Δλ* from mechanism.toml, β = {args.beta:g}, "
        f"reference design at l = {args.reference * 1e3:.0f} mm"
    )
    print()
    print(summary)
    print()
    print(f"tolerances at β = {args.beta:g} (mm, mrad):")
    print(tolerances)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
