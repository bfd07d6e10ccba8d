"""Compare robots: parameter counts and classes, design point, FOSM tolerances at one β (Markdown).

For each robot folder and each parameter set (dh, urdf) this runs :func:`pkmtol.allocate`, the same
function as ``pkmtol allocate``, with ``method="fosm"`` (the paper's Eq. 20, Table III) at the
design β: the classification, the most error-sensitive grid point (largest analytic σ[Δλ], the
first in grid order on a tie) and the tolerances there. A parameter with no effect at the design
point is toleranced from its own most sensitive grid pose, as ``allocate`` does (marked ``*pose``;
none is left free). The samples only feed ``allocate``'s verification, which is not printed, so the
output is deterministic. Prints Markdown: a table of counts, a table of tolerances (min / median /
max per unit), and with ``--appendix`` every allocated parameter.

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

from pkmtol import DesignOptions, DesignResult, allocate, load_mechanism
from pkmtol.error_model.sweep import CLASSES

SCALE = {"m": (1e6, "µm"), "rad": (1e6, "µrad")}
#: allocate's sampling only feeds its verification, which this script does not print
QUICK = {"samples": 200, "exact_samples": 0, "verification_poses": 20, "claim_poses": 20}


def md_table(rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    out += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(out)


def design(mech, kind: str, beta: float) -> DesignResult:
    """``pkmtol allocate`` of ``mech`` with parameter set ``kind``, FOSM, at design β ``beta``."""
    betas = tuple(sorted({*mech.betas, beta}))
    opt = DesignOptions(parameter_set=kind, method="fosm", betas=betas, design_beta=beta, **QUICK)
    return allocate(mech, opt)


def tolerances(r: DesignResult) -> tuple[np.ndarray, np.ndarray]:
    """Allocated parameter indices and their FOSM tolerances at the design β (SI)."""
    col = r.betas.index(r.design_beta)
    return r.uncompensatable, r.tolerances[r.uncompensatable, col]


def spread(values: np.ndarray, unit: str) -> str:
    """``min / median / max`` of the values in display units, and their count."""
    f, name = SCALE[unit]
    if values.size == 0:
        return "–"
    v = values * f
    return f"{v.min():.3g} / {np.median(v):.3g} / {v.max():.3g} {name} ({v.size})"


def fallback(r: DesignResult, i: int) -> str:
    """`` *pose`` when parameter ``i`` is toleranced from its own most sensitive grid pose."""
    fb = r.fallback_pose
    return f" *{int(fb[i])}" if fb is not None and fb[i] >= 0 else ""


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
        kinds = ["dh", "urdf"] if all(lb.dh is not None for lb in mech.limbs) else ["urdf"]
        results.append((mech, {k: design(mech, k, args.beta) for k in kinds}))

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
            "design point P [mm]",
            "allocated n (from their own pose)",
            "length tolerances min / median / max (count)",
            "angle tolerances min / median / max (count)",
        ]
    ]
    for mech, tables in results:
        for k, t in tables.items():
            unc, tol = tolerances(t)
            units = np.array([t.pset.units[i] for i in unc])
            own = sum(bool(fallback(t, i)) for i in unc)
            wp = np.round(t.worst_point_m * 1e3, 1) + 0.0  # no '-0.0'
            rows.append(
                [
                    mech.name,
                    k,
                    f"{mech.target_m * 1e6:g} µm",
                    f"({wp[0]:.1f}, {wp[1]:.1f}, {wp[2]:.1f})",
                    f"{unc.size} ({own})",
                    spread(tol[units == "m"], "m"),
                    spread(tol[units == "rad"], "rad"),
                ]
            )
    print(f"## Design point and FOSM tolerances at β = {beta:g}\n\n{md_table(rows)}\n")

    if args.appendix:
        print(f"## Appendix: every allocated parameter (β = {beta:g})\n")
        for mech, tables in results:
            for k, t in tables.items():
                unc, tol = tolerances(t)
                rows = [["parameter (*own pose)", "sensitivity ω", "tolerance ±σ"]]
                for i, sig in zip(unc, tol, strict=True):
                    unit = t.pset.units[i]
                    f, name = SCALE[unit]
                    w = "µm/µm" if unit == "m" else "µm/µrad"
                    rows.append(
                        [
                            t.pset.names[i] + fallback(t, i),
                            f"{t.sensitivity[i]:.4f} {w}",
                            f"{sig * f:.2f} {name}",
                        ]
                    )
                print(f"### {mech.name}, {k} set\n\n{md_table(rows)}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
