"""Tables of a design: terminal text, CSV, JSON and Markdown; files written whole or not at all.

Human-facing tables state their units (lengths in mm or µm, angles in mrad); JSON is SI with the
unit named in each field (``_m``, ``unit``). Tolerances that are free (+∞: the parameter has no
effect at the design point) are ``null`` in JSON and ``+inf`` in tables.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

import pkmtol.values as values
from pkmtol.calibration.study import LINEAR_WARNING
from pkmtol.design.job import DesignResult
from pkmtol.error_model.sweep import Sweep
from pkmtol.exceptions import OutputError
from pkmtol.present.design_tables import (
    claim_json,
    csv_tolerance,
    linear_validity_lines,
    method_lines,
    method_rows,
    verified_tolerances,
)
from pkmtol.present.design_tables import fmt_tolerance as _fmt_tol
from pkmtol.present.headline import headline_lines
from pkmtol.present.hybrid_tables import hybrid_ideal_text, sub_assemblies, sub_assembly_lines
from pkmtol.present.report_tables import SHARE_CSV, SHARE_HEADER, share_cells, signoff_json, signoff_text
from pkmtol.units import DISPLAY_UNITS, display, display_unit


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


def _coord(x_m: float) -> str:
    """A coordinate [m] in mm with one decimal, never ``-0.0``."""
    return f"{round(1e3 * x_m, 1) + 0.0:.1f}"


def _point(p_m: np.ndarray) -> str:
    return "(" + ", ".join(_coord(x) for x in p_m) + ") mm"


def _sens_unit(unit: str) -> str:
    return "µm/µm" if unit == "m" else "µm/µrad"


def _ratio(new: float, old: float) -> float:
    if not math.isfinite(old) and not math.isfinite(new):
        return float("nan")
    if not math.isfinite(new):
        return float("inf")
    return new / old


def to_json_dict(r: DesignResult) -> dict[str, Any]:
    """The design as a JSON-ready dict (SI units, unit named per field)."""
    trad = dict(zip(r.traditional.columns.tolist(), r.traditional.tolerance.tolist(), strict=True))
    params = []
    assembly, groups = r.grid.incompatible(), sub_assemblies(r)  # groups: a hybrid's module/wrist/tool
    for i, p in enumerate(r.pset.parameters):
        tol = r.tolerances[i]
        params.append(
            {
                "name": p.name,
                "unit": p.unit,
                "class": r.classes[i],
                **({} if groups is None else {"sub_assembly": groups[i]}),
                "sensitivity": float(r.sensitivity[i]),
                "sensitivity_unit": f"m/{p.unit}",
                "sensitivity_uncompensated": float(r.sensitivity_uncompensated[i]),
                "tolerance": None if np.all(np.isnan(tol)) else [_num(t) for t in tol],
                "class_in_mode": r.mode_classes[i] if r.mode_classes else r.classes[i],
                "tolerance_from_grid_pose": (
                    int(r.fallback_pose[i])
                    if r.fallback_pose is not None and r.fallback_pose[i] >= 0
                    else None
                ),
                "traditional_tolerance": _num(trad[i]) if i in trad else None,
                "assembly_error": bool(assembly[i]),
            }
        )
    ver = {}
    for name, v in r.verification.items():
        d = _stats(v.linear)
        d["exact"] = None if v.exact is None else _stats(v.exact)
        d["linear_on_exact_subsample"] = None if v.linear_subsample is None else _stats(v.linear_subsample)
        d["max_exact_linear_difference_over_target"] = _num(v.max_relative_difference)
        d["exact_unassembled"] = v.exact_unassembled
        d["linear_gap_m"] = _num(v.linear_gap_m)
        d["linear_valid"] = v.linear_valid
        d["warning"] = None if v.linear_valid else LINEAR_WARNING
        ver[name] = d
    return {
        "mechanism": r.mechanism.name,
        "parameter_set": r.pset.kind,
        "target_m": r.target_m,
        "beta": list(r.betas),
        "reliability": [float(x) for x in r.reliability_fosm],
        "design_beta": r.design_beta,
        "worst_point_m": r.worst_point_m.tolist(),
        "redundancy": r.grid.redundancy,
        "n_allocated": int(np.sum(np.isfinite(r.tolerances[r.uncompensatable, r.design_column]))),
        "parameters": params,
        "sensitive_pose_search": {
            "samples": r.search.samples,
            "points_m": r.grid.points_m.tolist(),
            "sigma_sampled_m": r.search.sigma_sampled_m.tolist(),
            "sigma_analytic_m": r.search.sigma_analytic_m.tolist(),
            "worst_index": r.worst_index,
        },
        "verification": ver,
        "verified_design": "fosm" if r.method_design is None else r.method_design.method,
        "claim": claim_json(r),
        "claimed_vs_true": [
            {
                "beta": c.beta,
                "claimed": c.claimed,
                "exact_gaussian_worst_pose": c.exact_worst,
                "exact_gaussian_task_space_mean": c.exact_task_space,
                "exact_gaussian_task_space_min": c.exact_task_space_min,
                "uniform_sigma_worst_pose": list(c.uniform_sigma_worst),
                "uniform_sqrt3_sigma_worst_pose": list(c.uniform_sqrt3_worst),
                "uniform_sigma_task_space": list(c.uniform_sigma_task_space),
                "uniform_sqrt3_sigma_task_space": list(c.uniform_sqrt3_task_space),
            }
            for c in r.claims
        ],
        "method_design": None
        if r.method_design is None
        else {
            "method": r.method_design.method,
            "criterion": r.method_design.criterion,
            "target_reliability": r.method_design.target_reliability,
            "parameters": [r.pset.names[i] for i in r.uncompensatable],
            "tolerance": r.method_design.sigma.tolist(),
            "reliability_grid": r.method_design.reliability.tolist(),
            "cost": r.method_design.cost,
            "equal_effect_same_true_r_tolerance": r.method_design.reference_sigma.tolist(),
            "equal_effect_same_true_r_cost": r.method_design.reference_cost,
        },
        "compensation": r.compensation,
        "noise_variance_m2": r.noise_variance_m2,
        "calibration_plan": None
        if r.calibration_plan is None
        else {
            "controller": r.calibration_plan.settings.controller_label,
            "poses": r.calibration_plan.poses,
            "selection": r.calibration_plan.settings.selection,
            "noise_m": r.calibration_plan.settings.noise_m,
            "targets_m": r.calibration_plan.targets_m.tolist(),
            "prior": r.calibration_plan.settings.prior,
            "rank": r.calibration_plan.ident.rank,
            "condition": r.calibration_plan.ident.condition,
            "observability_O1": r.calibration_plan.ident.observability,
            "points_m": r.calibration_plan.maps.points_m.tolist(),
        },
        "orientation": None if r.orientation is None else _orientation_json(r),
        "signoff": signoff_json(r),
        "traditional": {
            "design_point_m": r.worst_point_m.tolist(),
            "own_worst_point_m": r.grid.points_m[r.traditional.worst_index].tolist(),
            "n_allocated": int(np.sum(np.isfinite(r.traditional.tolerance))),
        },
    }


def _orientation_json(r: DesignResult) -> dict[str, Any]:
    o = r.orientation
    assert o is not None
    return {
        "tool_axis": o.axis.tolist(),
        "target_rad": o.target_rad,
        "tilt_worst_index": o.worst_index,
        "tilt_sensitivity_rad_per_unit": o.sensitivity.tolist(),
        "tilt_tolerance": None if o.tolerances is None else [[_num(t) for t in row] for row in o.tolerances],
        "tilt_binding": None if o.binding is None else o.binding.tolist(),
        "tilt_mean_at_design_point_rad": o.tilt_mean_rad,
        "tilt_std_at_design_point_rad": o.tilt_std_rad,
        "tilt_mean_grid_rad": o.tilt_grid_mean_rad.tolist(),
        "verification": {
            name: {
                "tilt": None if v.tilt is None else _stats(v.tilt),
                "tilt_exact": None if v.tilt_exact is None else _stats(v.tilt_exact),
                "joint_failure": None if v.joint is None else _stats(v.joint),
            }
            for name, v in r.verification.items()
        },
    }


def _stats(s: Any) -> dict[str, Any]:
    return {
        "mean_m": s.mean_m,
        "std_m": s.std_m,
        "failure_fraction": s.failure_fraction,
        "failure_ci95": list(s.failure_ci95),
        "reliability": s.reliability,
        "samples": s.samples,
    }


def to_json(r: DesignResult) -> str:
    """JSON text (deterministic for a given seed)."""
    values.instance("r", r, DesignResult, "a pkmtol.DesignResult (pkmtol.allocate)")
    return json.dumps(to_json_dict(r), indent=2, ensure_ascii=False) + "\n"


def table_rows(r: DesignResult, units: str = "mm") -> list[list[str]]:
    """Rows of the tolerance table (the paper's Table III) with a header row (``units``: mm or um)."""
    m = r.method_design
    design = [] if m is None else [f"{m.method} design"]  # the verified design's σ, beside the FOSM series
    header = (
        ["No.", "parameter", "unit", "sensitivity"] + [f"β={b:g}" for b in r.betas] + design + SHARE_HEADER
    )
    rows = [header]
    fallback = r.fallback_pose if r.fallback_pose is not None else np.full(len(r.pset), -1)
    share = share_cells(r)  # of the FOSM design at the design β
    for k, i in enumerate(r.uncompensatable, start=1):
        p = r.pset.parameters[i]
        name = p.name + (f" *{fallback[i]}" if fallback[i] >= 0 else "")
        rows.append(
            [str(k), name, display_unit(p.unit, units), f"{r.sensitivity[i]:.4f} {_sens_unit(p.unit)}"]
            + [_fmt_tol(t, p.unit, units) for t in r.tolerances[i]]
            + ([] if m is None else [_fmt_tol(m.sigma[k - 1], p.unit, units)])
            + share[int(i)]
        )
    return rows


_MODE_TITLE = {
    "ideal": "Tolerances of the uncompensatable errors (FOSM, paper Table III)",
    "calibrated": "Tolerances after calibration (FOSM on the post-calibration map L)",
    "none": "Tolerances without compensation (FOSM on J_total, the traditional method)",
}


def compensation_lines(r: DesignResult) -> list[str]:
    """What the compensation mode is, its classes, the plan and noise (calibrated), fallbacks."""
    counts = {c: r.mode_classes.count(c) for c in dict.fromkeys(r.mode_classes)}
    out = [
        f"compensation: {r.compensation} — "
        + {
            "ideal": hybrid_ideal_text(r)
            or "the paper's Eq. 25 (the controller knows the compensatable errors exactly)",
            "calibrated": "a least-squares calibration from tracker measurements",
            "none": "no compensation (the traditional method)",
        }[r.compensation]
        + "; classes: "
        + ", ".join(f"{n} {c}" for c, n in counts.items())
    ]
    plan = r.calibration_plan
    if plan is not None:
        st = plan.settings
        out.append(
            f"calibration plan: controller '{st.controller_label}' ({plan.ident.columns.size} parameters, "
            f"rank {plan.ident.rank}), {plan.poses} {st.selection} poses, {plan.targets_m.shape[0]} "
            f"target(s), tracker noise {1e3 * st.noise_m:.4g} mm per coordinate"
            + (", MAP prior" if st.prior else "")
            + f"; condition number {plan.ident.condition:.4g}, O1 {plan.ident.observability:.4g}"
        )
        out.append(
            f"the tracker noise alone leaves σ = {1e6 * math.sqrt(r.noise_variance_m2):.3f} µm of Δλ's "
            "linear response at the design point (a fixed variance term in FOSM; the floor it sets is "
            f"β·σ = {1e6 * r.design_beta * math.sqrt(r.noise_variance_m2):.3f} µm at the design β)"
        )
    if plan is not None and r.worst_index != r.search.worst_index_analytic:
        out.append(
            f"design pose: grid pose {r.worst_index}, the largest E[Δλ²] of its FOSM design with the "
            f"tracker noise σ_m² ‖N‖² included (grid pose {r.search.worst_index_analytic} has the largest "
            "σ[Δλ] of unit errors alone)"
        )
    fb = r.fallback_pose if r.fallback_pose is not None else np.zeros(0)
    n_fb = int(np.sum(fb >= 0))
    if n_fb:
        out.append(
            f"* {n_fb} allocated parameter(s) have no effect at the design point; each is toleranced "
            "from its own most sensitive grid pose (the number after '*'), never left free"
        )
    return out


def orientation_lines(r: DesignResult) -> list[str]:
    """The tilt Δα of the tool axis: at the design point, and against its target when set."""
    o = r.orientation
    if o is None:
        return []
    ax = ", ".join(f"{x:.4g}" for x in o.axis)
    out = [
        f"tool axis ({ax}) in the platform frame; tilt Δα of the verified design at the design point: "
        f"mean {1e6 * o.tilt_mean_rad:.2f} µrad, σ {1e6 * o.tilt_std_rad:.2f} µrad; largest grid-pose mean "
        f"{1e6 * float(o.tilt_grid_mean_rad.max()):.2f} µrad"
    ]
    if o.target_rad is not None and o.binding is not None:
        out.append(
            f"orientation target Δα* = {1e6 * o.target_rad:.4g} µrad: the tilt's own FOSM tolerance is the "
            f"smaller for {int(o.binding.sum())} of {len(r.uncompensatable)} parameters (tilt-worst grid "
            f"pose {o.worst_index})"
        )
    for name, v in r.verification.items():
        if v.joint is not None:
            f = v.joint
            out.append(
                f"{name}: P(Δλ > Δλ* or Δα > Δα*) = {100 * f.failure_fraction:.2f} % "
                f"[{100 * f.failure_ci95[0]:.2f}, {100 * f.failure_ci95[1]:.2f}] "
                f"(linear, {f.samples} samples)"
                + (
                    ""
                    if v.tilt_exact is None
                    else f"; exact tilt beyond Δα*: {100 * v.tilt_exact.failure_fraction:.2f} % "
                    f"of {v.tilt_exact.samples}"
                )
            )
    return out


def comparison_rows(r: DesignResult, units: str = "mm") -> list[list[str]]:
    """Traditional vs new tolerance at the design β, per non-absorbed parameter."""
    col = r.design_column
    rows = [["parameter", "class", "unit", "new", "traditional", "traditional/new", "new " + SHARE_HEADER[0]]]
    share = share_cells(r)
    for i, t in zip(r.traditional.columns, r.traditional.tolerance, strict=True):
        p = r.pset.parameters[i]
        allocated = i in set(r.uncompensatable.tolist())
        new = r.tolerances[i, col] if allocated else float("inf")
        ratio = _ratio(t, new) if math.isfinite(new) else float("nan")
        rows.append(
            [
                p.name,
                r.mode_classes[i] if r.mode_classes else r.classes[i],
                display_unit(p.unit, units),
                _fmt_tol(new, p.unit, units) if allocated else "compensated",
                _fmt_tol(t, p.unit, units),
                "-" if math.isnan(ratio) else f"{ratio:.3f}",
                share[int(i)][0] if allocated else "-",
            ]
        )
    return rows


def text_table(rows: list[list[str]]) -> str:
    """Rows (header first) as an aligned plain-text table with a rule under the header."""
    widths = [max(len(row[c]) for row in rows) for c in range(len(rows[0]))]
    lines = [
        "  ".join(
            cell.rjust(w) if c else cell.ljust(w) for c, (cell, w) in enumerate(zip(row, widths, strict=True))
        )
        for row in rows
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _md_table(rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    out += ["| " + " | ".join(row) + " |" for row in rows[1:]]
    return "\n".join(out)


def _search_agreement(r: DesignResult) -> str:
    """How the sampled σ[Δλ_j] of the pose search compares with the analytic one, over the grid."""
    s = r.search
    condition = f"W condition number {r.grid.W_condition.min():.3g}–{r.grid.W_condition.max():.3g}"
    m = len(s.sigma_analytic_m)
    if not r.uncompensatable.size:  # σ[Δλ_j] = 0 everywhere: there is nothing to compare
        return (
            f"sampled vs analytic σ[Δλ_j] over the {m} grid points: no toleranced parameter (the mode "
            f"removes every error, so σ[Δλ_j] = 0 for unit errors); {condition}"
        )
    positive = s.sigma_analytic_m > 0
    rel = np.abs(s.sigma_sampled_m - s.sigma_analytic_m)[positive] / s.sigma_analytic_m[positive]
    se = 1.0 / np.sqrt(2.0 * (s.samples - 1))  # relative standard error of a sample std (normal)
    where = f"the {m} grid points"
    if not positive.all():
        where = f"the {rel.size} of {m} grid points with σ[Δλ_j] > 0"
    if not rel.size:
        return f"sampled vs analytic σ[Δλ_j]: 0 at every one of the {m} grid points; {condition}"
    return (
        f"sampled vs analytic σ[Δλ_j] over {where}: largest difference "
        f"{100 * rel.max():.2f} %, median {100 * np.median(rel):.2f} % (sampling error ≈ {100 * se:.2f} %); "
        f"{condition}"
    )


def overconstraint_lines(grid: Sweep, names_all: list[str]) -> list[str]:
    """The redundancy of an over-constrained mechanism and its assembly-error parameters."""
    if not grid.redundancy:
        return []
    names = [names_all[i] for i in np.flatnonzero(grid.incompatible())]
    return [
        f"over-constrained: redundancy {grid.redundancy} (the actuation and constraint wrenches "
        f"exceed their rank 6 by {grid.redundancy}); pose errors are least-squares solutions, and "
        f"{len(names)} parameters have an incompatible part, an assembly error no rigid motion "
        "satisfies: " + ", ".join(names)
    ]


def summary_text(r: DesignResult, markdown: bool = False, units: str = "mm") -> str:
    """The whole report as terminal text or Markdown (tolerances in mm/mrad, or µm/µrad with ``um``)."""
    values.instance("r", r, DesignResult, "a pkmtol.DesignResult (pkmtol.allocate)")
    values.choice("units", units, DISPLAY_UNITS)
    table = _md_table if markdown else text_table
    h = (lambda s: f"\n## {s}\n") if markdown else (lambda s: f"\n{s}\n{'=' * len(s)}")
    col = r.design_column
    counts = {c: r.classes.count(c) for c in ("absorbed", "compensatable", "uncompensatable")}
    out = [
        ("# " if markdown else "") + f"pkmtol allocation — {r.mechanism.name}",
        "",
        f"required accuracy Δλ* = {r.target_m * 1e3:g} mm at {'the TCP' if r.mechanism.tool else 'P'}; "
        f"parameter set '{r.pset.kind}' "
        f"({len(r.pset)} parameters: {counts['uncompensatable']} uncompensatable, "
        f"{counts['compensatable']} compensatable, {counts['absorbed']} absorbed)",
        *overconstraint_lines(r.grid, r.pset.names),
        "most error-sensitive point (analytic σ[Δλ], η_c ~ N(0,1) SI): "
        f"{'TCP' if r.mechanism.tool else 'P'} = {_point(r.worst_point_m)}, "
        f"σ[Δλ] = {r.search.sigma_analytic_m[r.worst_index]:.5g} m per unit error (m or rad) analytic, "
        f"{r.search.sigma_sampled_m[r.worst_index]:.5g} from {r.search.samples} samples "
        f"(sampled worst at grid point {r.search.worst_index}, analytic at {r.search.worst_index_analytic})",
        _search_agreement(r),
        *compensation_lines(r),
        h(
            _MODE_TITLE.get(r.compensation, _MODE_TITLE["ideal"])
            + ("" if r.method_design is None else f"; the verified '{r.method_design.method}' design")
        ),
        "R = Φ(β): "
        + ", ".join(f"β={b:g}: {100 * p:.2f} %" for b, p in zip(r.betas, r.reliability_fosm, strict=True)),
        "",
        table(table_rows(r, units)),
        h(
            f"Verification of the β = {r.design_beta:g} design (Δλ* = {r.target_m * 1e6:g} µm)"
            if r.method_design is None
            else f"Verification of the '{r.method_design.method}' design (Δλ* = {r.target_m * 1e6:g} µm)"
        ),
    ]
    vrows = [
        ["errors", "model", "samples", "mean Δλ [µm]", "std Δλ [µm]", "failures [%]", "95 % CI [%]", "R [%]"]
    ]
    for name, v in r.verification.items():
        flag = "" if v.linear_valid else " (!)"  # linear figures off the exact ones beyond 5 % of Δλ*
        for label, s in (
            ("linear" + flag, v.linear),
            ("exact", v.exact),
            ("linear (same subsample)" + flag, v.linear_subsample),
        ):
            if s is None:
                continue
            vrows.append(
                [
                    name,
                    label,
                    str(s.samples),
                    f"{s.mean_m * 1e6:.3f}",
                    f"{s.std_m * 1e6:.3f}",
                    f"{100 * s.failure_fraction:.2f}",
                    f"{100 * s.failure_ci95[0]:.2f}–{100 * s.failure_ci95[1]:.2f}",
                    f"{100 * s.reliability:.2f}",
                ]
            )
    out += [table(vrows), ""]
    out += linear_validity_lines(r) + headline_lines(r)
    out += [
        f"exact kinematics ({name}): {v.exact_unassembled} sample(s) could not be assembled (the "
        "errors include assembly errors no rigid motion satisfies: over-constrained mechanism) "
        "and are left out of the exact rows"
        for name, v in r.verification.items()
        if v.exact_unassembled
    ]
    if r.orientation is not None and (r.orientation.target_rad is not None or r.compensation != "ideal"):
        out += [h("Orientation of the tool axis"), *orientation_lines(r)]
    out += sub_assembly_lines(r, table, h, units) + signoff_text(r, table, h)  # a hybrid: by sub-assembly
    out += [
        h("Claimed vs true reliability of the FOSM designs (R in %)"),
        table(claim_rows(r)),
        "",
        "exact: Gaussian errors σ_i, exact distribution of Δλ = ‖J η‖ (no sampling); uniform: "
        "Monte Carlo with 95 % interval; task space: random poses uniform in its volume",
    ]
    if r.method_design is not None:
        out += [
            h(f"Design by the '{r.method_design.method}' method"),
            *method_lines(r),
            "",
            table(method_rows(r, units)),
        ]
    t = r.traditional
    fin = np.isfinite(t.tolerance)
    shared = [
        (t.tolerance[k], r.tolerances[i, col])
        for k, i in enumerate(t.columns)
        if i in set(r.uncompensatable.tolist()) and math.isfinite(r.tolerances[i, col])
    ]
    tighter = sum(1 for a, b in shared if a < b)
    compared = "no tolerance to compare (the new method tolerances no parameter)"
    if shared:
        factor = float(np.median([a / b for a, b in shared]))
        compared = (
            f"{tighter} of {len(shared)} shared tolerances are tighter (median traditional/new {factor:.3f})"
        )
    elif r.uncompensatable.size:
        compared = "no finite tolerance is shared"
    out += [
        h("Traditional method (all errors, no compensation), same Δλ*, β and design point"),
        f"{len(t.columns)} parameters allocated ({int(fin.sum())} finite, "
        f"{int((~fin).sum())} free '+inf') vs {len(r.uncompensatable)} by the new method; "
        f"{compared}; traditional's own most sensitive point: " + _point(r.grid.points_m[t.worst_index]),
        "",
        table(comparison_rows(r, units)),
    ]
    return "\n".join(out) + "\n"


def claim_rows(r: DesignResult) -> list[list[str]]:
    """Rows of the claimed-vs-true reliability table."""

    def ci(c: tuple[float, float, float]) -> str:
        return f"{100 * c[0]:.2f} ({100 * c[1]:.2f}–{100 * c[2]:.2f})"

    # every reliability with 2 decimals, as R = Φ(β) above the tolerance table

    rows = [
        [
            "β",
            "claimed Φ(β)",
            "exact, worst pose",
            "exact, task space mean (min)",
            "uniform ±σ, worst",
            "uniform ±√3σ, worst",
            "uniform ±σ, task space",
            "uniform ±√3σ, task space",
        ]
    ]
    for c in r.claims:
        rows.append(
            [
                f"{c.beta:g}",
                f"{100 * c.claimed:.2f}",
                f"{100 * c.exact_worst:.2f}",
                f"{100 * c.exact_task_space:.2f} ({100 * c.exact_task_space_min:.2f})",
                ci(c.uniform_sigma_worst),
                ci(c.uniform_sqrt3_worst),
                ci(c.uniform_sigma_task_space),
                ci(c.uniform_sqrt3_task_space),
            ]
        )
    return rows


def to_csv(r: DesignResult, units: str = "mm") -> str:
    """CSV of every parameter: class, sensitivity, tolerances per β (display units: mm/mrad or µm/µrad)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    trad = dict(zip(r.traditional.columns.tolist(), r.traditional.tolerance.tolist(), strict=True))
    share = share_cells(r, numeric=True)
    w.writerow(
        ["name", "unit", "class", "sensitivity_um_per_unit_um_or_urad"]
        + [f"tolerance_beta_{b:g}" for b in r.betas]
        + [f"traditional_tolerance_beta_{r.design_beta:g}", "design_tolerance", *SHARE_CSV]
    )
    design = {int(i): t for i, t in zip(r.uncompensatable, verified_tolerances(r), strict=True)}
    for i, p in enumerate(r.pset.parameters):
        u = p.unit
        tols = [
            "" if np.isnan(t) else ("inf" if not math.isfinite(t) else f"{display(t, u, units):.6g}")
            for t in r.tolerances[i]
        ]
        tr = trad.get(i)
        w.writerow(
            [p.name, display_unit(u, units), r.classes[i], f"{r.sensitivity[i]:.6g}"]
            + tols
            + ["" if tr is None else ("inf" if not math.isfinite(tr) else f"{display(tr, u, units):.6g}")]
            + [csv_tolerance(design.get(i), u, units)]
            + share.get(i, ["", "", ""])
        )
    return buf.getvalue()


def check_output_folder(out: Path) -> None:
    """Create ``out`` if needed and make sure it is writable (before any long computation).

    Raises:
        OutputError: it cannot be created or written.
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(out, f"{err.strerror}; choose another --out folder") from err
    if not os.access(out, os.W_OK):
        raise OutputError(out, "folder is not writable; choose another --out folder")
