"""Compare robots: parameter counts and classes, worst point, FOSM tolerances at one β (Markdown).

For each robot folder and each parameter set (dh, urdf): the error model over the task-space
grid, the classification, the most error-sensitive grid point (largest analytic σ[Δλ] with
η_c ~ N(0, 1), as ``pkmtol errors`` and ``pkmtol allocate``) and the FOSM tolerances
``σ_i = Δλ*/(√n ω_i β)`` there (the paper's Eq. 20, no sampling: deterministic). Prints Markdown:
a table of counts, a table of tolerances (min / median / max per unit), and with ``--appendix``
every allocated parameter.

Usage:
    python scripts/compare_machines.py robots/r2rps_ups robots/tricept robots/exechon robots/sprint_z3
    python scripts/compare_machines.py robots/* --beta 2 --appendix
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from pkmtol.design.fosm import fosm_tolerances
from pkmtol.error_model.sweep import CLASSES
from pkmtol.error_model.table import ErrorTable, error_table
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

SCALE = {"m": (1e6, "µm"), "rad": (1e6, "µrad")}


def md_table(rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    out += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(out)


def tolerances(t: ErrorTable, target_m: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Allocated parameter indices and their FOSM tolerances at ``beta`` (SI; inf = free)."""
    unc = np.array([i for i, c in enumerate(t.classes) if c == "uncompensatable"], dtype=int)
    if unc.size == 0:
        return unc, np.zeros(0)
    return unc, fosm_tolerances(t.sensitivity[unc], target_m, np.array([beta]))[:, 0]


def spread(values: np.ndarray, unit: str) -> str:
    """``min / median / max`` of the finite values in display units, and the count of free ones."""
    f, name = SCALE[unit]
    fin = values[np.isfinite(values)] * f
    free = int(np.sum(~np.isfinite(values)))
    if fin.size == 0:
        return "–" if not free else f"all {free} free"
    s = f"{fin.min():.3g} / {np.median(fin):.3g} / {fin.max():.3g} {name} ({fin.size})"
    return s + (f", {free} free" if free else "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("robots", nargs="+", type=Path, help="robot folders")
    ap.add_argument("--beta", type=float, default=2.0, help="reliability index of the tolerances (default 2)")
    ap.add_argument("--appendix", action="store_true", help="also list every allocated parameter")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")  # quadrature warnings of the σ[Δλ] search (values unaffected)

    results = []
    for folder in args.robots:
        mech = load_mechanism(folder)
        chain = ClosedChain(mech)
        kinds = ["dh", "urdf"] if all(lb.dh is not None for lb in mech.limbs) else ["urdf"]
        results.append((mech, {k: error_table(mech, k, chain) for k in kinds}))

    beta = args.beta
    rows = [
        [
            "machine",
            "limbs: constraint wrenches",
            "redundancy",
            "dh: n (absorbed / compensatable / uncompensatable)",
            "urdf: n (absorbed / compensatable / uncompensatable)",
            "assembly-error parameters (dh / urdf)",
        ]
    ]
    for mech, tables in results:
        any_t = next(iter(tables.values()))
        sep = any_t.grid.separations[0]
        cons = ", ".join(
            f"{lb.name} {int(np.sum(sep.constraint_limb == i))}" for i, lb in enumerate(mech.limbs)
        )
        cells = []
        for k in ("dh", "urdf"):
            t = tables.get(k)
            if t is None:
                cells.append("–")
                continue
            n = {c: t.classes.count(c) for c in CLASSES}
            cells.append(f"{len(t.pset)} ({n['absorbed']} / {n['compensatable']} / {n['uncompensatable']})")
        asm = " / ".join(str(int(t.grid.incompatible().sum())) for t in tables.values())
        rows.append([mech.name, cons, str(any_t.grid.redundancy), *cells, asm])
    print(f"## Parameters and their classes\n\n{md_table(rows)}\n")

    rows = [
        [
            "machine",
            "set",
            "Δλ*",
            "worst point P [mm]",
            "allocated n",
            "length tolerances min / median / max (count)",
            "angle tolerances min / median / max (count)",
        ]
    ]
    for mech, tables in results:
        for k, t in tables.items():
            unc, tol = tolerances(t, mech.target_m, beta)
            units = np.array([t.pset.units[i] for i in unc])
            wp = np.round(t.worst_point_m * 1e3, 1) + 0.0  # no '-0.0'
            rows.append(
                [
                    mech.name,
                    k,
                    f"{mech.target_m * 1e6:g} µm",
                    f"({wp[0]:.1f}, {wp[1]:.1f}, {wp[2]:.1f})",
                    str(int(np.sum(np.isfinite(tol)))),
                    spread(tol[units == "m"], "m"),
                    spread(tol[units == "rad"], "rad"),
                ]
            )
    print(f"## Worst point and FOSM tolerances at β = {beta:g}\n\n{md_table(rows)}\n")

    if args.appendix:
        print(f"## Appendix: every allocated parameter (β = {beta:g})\n")
        for mech, tables in results:
            for k, t in tables.items():
                unc, tol = tolerances(t, mech.target_m, beta)
                rows = [["parameter", "sensitivity ω", "tolerance ±σ"]]
                for i, s in zip(unc, tol, strict=True):
                    unit = t.pset.units[i]
                    f, name = SCALE[unit]
                    w = "µm/µm" if unit == "m" else "µm/µrad"
                    rows.append(
                        [
                            t.pset.names[i],
                            f"{t.sensitivity[i]:.4f} {w}",
                            "free (ω = 0)" if not np.isfinite(s) else f"{s * f:.2f} {name}",
                        ]
                    )
                print(f"### {mech.name}, {k} set\n\n{md_table(rows)}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
