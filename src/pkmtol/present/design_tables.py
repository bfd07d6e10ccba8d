"""The verified design's tables: the method design, its claim as JSON, its tolerances, linear validity.

Beside the FOSM β series of the paper's Table III, the design ``allocate`` verifies (``exact`` or
``cost``, else FOSM at the design β) has its own tolerances (:func:`verified_tolerances`, the
``design_tolerance`` column of allocation.csv), its own table (:func:`method_rows`) and its claim
(:func:`claim_json`, allocation.json's ``claim``); :func:`linear_validity_lines` warns where a
verification's linear figures stray from its exact ones by more than 5 % of Δλ*.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pkmtol.calibration.study import LINEAR_WARNING
from pkmtol.design.job import DesignResult
from pkmtol.present.headline import claim_line
from pkmtol.present.report_tables import SHARE_HEADER, share_cells
from pkmtol.units import display, display_unit


def fmt_tolerance(x: float, unit: str, units: str = "mm") -> str:
    """``±0.0128`` (4 decimals), or 3 significant digits below 0.001 so that it never reads ±0.0000."""
    if math.isnan(x):
        return "noise floor"
    if not math.isfinite(x):
        return "+inf"
    v = display(x, unit, units)
    return f"±{v:.4f}" if abs(v) >= 1e-3 or v == 0 else f"±{v:.3g}"


def linear_validity_lines(r: DesignResult) -> list[str]:
    """A warning per verification whose linear figures are not valid (gap beyond 5 % of Δλ*)."""
    return [
        f"warning: {name} (!): {LINEAR_WARNING} (the exact and linear mean/p95/p99 of Δλ differ by "
        f"{v.linear_gap_m * 1e6:.2f} µm, beyond 5 % of Δλ* = {0.05 * r.target_m * 1e6:.2f} µm)"
        for name, v in r.verification.items()
        if not v.linear_valid
    ]


def claim_json(r: DesignResult) -> dict[str, Any] | None:
    """The claim of the verified design: its scope, the grid reliability, the verification's misses."""
    c = r.claim
    if c is None:
        return None
    return {
        "method": c.method,
        "scope": c.scope,
        "where": c.where,
        "claimed_reliability": c.claimed,
        "text": claim_line(c, r.compensation == "calibrated"),
        "design_grid_pose": c.design_pose,
        "unit_error_grid_pose": r.search.worst_index_analytic,
        "joint_position_and_tilt": c.joint,
        "grid_reliability": c.reliability.tolist(),
        "grid_min_reliability": c.min_reliability,
        "grid_min_pose": c.min_pose,
        "grid_mean_reliability": c.mean_reliability,
        "verification_misses": [
            {
                "distribution": m.distribution,
                "model": m.model,
                "reliability": m.reliability,
                "ci95": list(m.interval),
                "samples": m.samples,
            }
            for m in r.claim_misses
        ],
        "exact_samples_cap": r.exact_samples_cap,
        "option_caps": [
            {"option": o, "asked": asked, "used": used, "why": why} for o, asked, used, why in r.option_caps
        ],
    }


def method_lines(r: DesignResult) -> list[str]:
    """Summary lines of an exact/cost design."""
    m = r.method_design
    assert m is not None
    return [
        f"target R* = Φ({r.design_beta:g}) = {100 * m.target_reliability:.4f} %, criterion '{m.criterion}': "
        f"exact R at the worst pose {100 * m.reliability[r.worst_index]:.4f} %, min over the grid "
        f"{100 * m.reliability.min():.4f} %, mean {100 * m.reliability.mean():.4f} %",
        f"total cost {m.cost:.4g} (cost model of docs/theory.md); the equal-effect design with the same "
        f"true R (min over the grid) costs {m.reference_cost:.4g}",
    ]


def method_rows(r: DesignResult, units: str = "mm") -> list[list[str]]:
    """Per-parameter tolerances of the exact/cost design beside the equal-effect ones."""
    m = r.method_design
    assert m is not None
    rows = [
        [
            "parameter",
            "unit",
            f"{m.method} design",
            "equal effect, same true R",
            "FOSM β=" + f"{r.design_beta:g}",
            *SHARE_HEADER,
        ]
    ]
    share = share_cells(r, method=True)
    for k, i in enumerate(r.uncompensatable):
        p = r.pset.parameters[i]
        rows.append(
            [
                p.name,
                display_unit(p.unit, units),
                fmt_tolerance(m.sigma[k], p.unit, units),
                fmt_tolerance(m.reference_sigma[k], p.unit, units),
                fmt_tolerance(r.tolerances[i, r.design_column], p.unit, units),
                *share[int(i)],
            ]
        )
    return rows


def verified_tolerances(r: DesignResult) -> np.ndarray:
    """The verified design's σ of the toleranced parameters (the method's, else FOSM at the design β)."""
    if r.method_design is not None:
        return r.method_design.sigma
    return r.tolerances[r.uncompensatable, r.design_column]


def csv_tolerance(t: float | None, unit: str, units: str) -> str:
    """A tolerance in display units for the CSV (empty: none; ``inf``: free)."""
    if t is None or np.isnan(t):
        return ""
    return "inf" if not math.isfinite(t) else f"{display(t, unit, units):.6g}"
