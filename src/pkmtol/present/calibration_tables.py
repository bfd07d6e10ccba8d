"""Tables of a calibration: the plan and its identifiability, the simulated study, identified parameters.

Human-facing tables state their units (µm, µrad); JSON is SI with the unit named in each field.
"""

from __future__ import annotations

import csv
import io
import json
import math
from typing import Any

import numpy as np

from pkmtol.calibration.identifiability import Identifiability
from pkmtol.calibration.instruments.base import Instrument, unseen_nuisance
from pkmtol.calibration.real_data import RealCalibration
from pkmtol.calibration.study import LINEAR_WARNING, ErrorSummary
from pkmtol.calibration.workflow import PlanReport, PlanSummary, StudyReport
from pkmtol.present.tables import text_table


def _um(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{1e6 * x:.2f}"


def _urad(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{1e6 * x:.1f}"


def _si_unit(unit: str) -> tuple[float, str]:
    return (1e6, "µm") if unit == "m" else (1e6, "µrad")


def markdown_table(rows: list[list[str]]) -> str:
    """Rows (header first) as a Markdown table."""
    out = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    out += ["| " + " | ".join(row) + " |" for row in rows[1:]]
    return "\n".join(out)


def _table(rows: list[list[str]], markdown: bool) -> str:
    return markdown_table(rows) if markdown else text_table(rows)


# --- the plan ----------------------------------------------------------------------------------


def identifiability_lines(ident: Identifiability, markdown: bool = False, limit: int = 40) -> list[str]:
    """Rank, conditioning, base parameters with their σ, unidentifiable combinations, correlations."""
    kept = ident.pivots[ident.rank - 1]
    dropped = ident.pivots[ident.rank] if ident.rank < ident.pivots.size else float("nan")
    out = [
        f"identifiable combinations: rank {ident.rank} of {ident.columns.size} parameters "
        f"(rank tolerance {ident.rank_tolerance:g}: smallest kept pivot {kept:.3g}, largest dropped "
        f"{dropped:.3g}, relative to the largest)",
        f"condition number {ident.condition:.4g}, observability index O1 {ident.observability:.4g} "
        "(scaled columns; larger O1 is better)",
        "",
    ]
    rows = [["base parameter (identified combination)", "σ of estimate", "unit"]]
    for comb, sd, b in zip(ident.identified_combinations(), ident.std, ident.base, strict=True):
        f, unit = _si_unit(ident.units[b])
        rows.append([comb if len(comb) < 100 else comb[:97] + "...", f"{f * sd:.3g}", unit])
    out += [_table(rows, markdown), ""]
    un = ident.unidentifiable_combinations()
    if un:
        out.append(f"unidentifiable directions ({len(un)}; invisible to these measurements):")
        out += [f"  {u}" for u in un[:limit]]
        if len(un) > limit:
            out.append(f"  ... and {len(un) - limit} more (see the JSON)")
        out.append("")
    if ident.correlated:
        out.append(f"base estimates correlated above |ρ| = 0.9 ({len(ident.correlated)}):")
        out += [f"  {a} ~ {b}: ρ = {rho:+.3f}" for a, b, rho in ident.correlated[:limit]]
        out.append("")
    return out


def _plan_row(s: PlanSummary) -> list[str]:
    p = s.prediction
    return [
        s.label,
        str(s.rank),
        f"{s.condition:.3g}",
        f"{s.observability:.3g}",
        f"{s.log_det:.2f}",
        _um(p.mean_m),
        _um(p.p99_m),
        f"{100 * p.beyond:.2f}",
        _urad(p.tilt_p99_rad),
    ]


def unseen_lines(inst: Instrument, rows: np.ndarray | None) -> list[str]:
    """A line naming the instrument's nuisance directions the poses do not fix (none: no line)."""
    unseen = [] if rows is None or not inst.nuisance_count else unseen_nuisance(inst, rows)
    if not unseen:
        return []
    return [
        f"the poses do not fix {len(unseen)} of the {inst.name}'s {inst.nuisance_count} nuisance "
        f"directions: {'; '.join(unseen)}; the machine's rigid motion along them is not identified either"
    ]


def plan_text(report: PlanReport, markdown: bool = False) -> str:
    """The plan, its identifiability, and how it compares with random plans of its size."""
    plan, st = report.plan, report.plan.settings
    head = [
        f"calibration plan: controller '{st.controller_label}' ({plan.ident.columns.size} parameters), "
        f"{plan.poses} {st.selection} poses, {plan.targets_m.shape[0]} target(s), tracker noise "
        f"{1e3 * st.noise_m:.4g} mm per coordinate" + (", MAP prior" if st.prior else ", least squares"),
        "",
    ]
    if plan.instrument is not None and (plan.instrument.name != "tracker" or plan.instrument.nuisance_count):
        head = [
            f"calibration plan: controller '{st.controller_label}' ({plan.ident.columns.size} parameters), "
            f"{plan.poses} {st.selection} poses"
            + (f" on {np.unique(plan.stations).size} circles" if plan.instrument.name == "ballbar" else "")
            + (", MAP prior" if st.prior else ", least squares"),
            "instrument " + plan.instrument.describe(),
            f"rank over the whole candidate pool: {plan.pool_rank}",
            *unseen_lines(plan.instrument, plan.system.nuisance if plan.system is not None else None),
            "",
        ]
    out = head + identifiability_lines(plan.ident, markdown)
    rows = [
        [
            "plan",
            "rank",
            "condition",
            "O1",
            "log det",
            "mean Δλ [µm]",
            "p99 Δλ [µm]",
            "beyond Δλ* [%]",
            "p99 tilt [µrad]",
        ],
        _plan_row(report.summary),
    ]
    rows += [_plan_row(r) for r in report.random]
    n = len(report.holdout.maps)
    out += [
        f"predicted after calibration (linear model, {n} held-out random poses, machines drawn at the "
        f"manufacturing σ / allocated tolerances; Δλ* = {1e3 * report.target_m:g} mm):",
        _table(rows, markdown),
        "",
    ]
    if report.random:
        better = sum(report.summary.prediction.p99_m < r.prediction.p99_m for r in report.random)
        out.append(
            f"the {st.selection} plan has a lower predicted p99 than {better} of {len(report.random)} "
            "random plans"
        )
        out.append("")
    if report.curve:
        rows = [["poses N", "d-optimal p99 Δλ [µm]", "random p99 Δλ [µm] (median of 3)"]]
        rows += [[str(n), _um(d), _um(r)] for n, d, r in report.curve]
        out += ["predicted p99 against the number of poses:", _table(rows, markdown), ""]
    return "\n".join(out) + "\n"


def plan_json(report: PlanReport, names: list[str]) -> dict[str, Any]:
    """The plan report as a JSON-ready dict (SI units)."""
    plan, ident = report.plan, report.plan.ident

    def summ(s: PlanSummary) -> dict[str, Any]:
        p = s.prediction
        return {
            "label": s.label,
            "poses": s.poses,
            "rank": s.rank,
            "condition": s.condition,
            "observability_O1": s.observability,
            "log_det": s.log_det,
            "predicted_mean_dlambda_m": p.mean_m,
            "predicted_p95_dlambda_m": p.p95_m,
            "predicted_p99_dlambda_m": p.p99_m,
            "predicted_beyond_target": p.beyond,
            "predicted_mean_tilt_rad": p.tilt_mean_rad,
            "predicted_p99_tilt_rad": p.tilt_p99_rad,
            "prediction_samples": p.samples,
        }

    return {
        "instrument": plan.settings.instrument,
        "tracker_frame": plan.settings.tracker_frame,
        "nuisance_parameters": list(plan.instrument.nuisance_names) if plan.instrument else [],
        "pool_rank": plan.pool_rank,
        "controller": plan.settings.controller_label,
        "controller_parameters": list(ident.names),
        "targets_m": plan.targets_m.tolist(),
        "noise_m": plan.settings.noise_m,
        "selection": plan.settings.selection,
        "poses": {
            "points_m": plan.maps.points_m.tolist(),
            "commands_si": plan.maps.commands.tolist(),
            "stations": plan.stations.tolist(),
        },
        "identifiability": identifiability_json(ident),
        "plan": summ(report.summary),
        "random_plans": [summ(r) for r in report.random],
        "p99_against_poses": [
            {"poses": n, "d_optimal_p99_m": d, "random_median_p99_m": r} for n, d, r in report.curve
        ],
        "sigma": dict(zip(names, [float(x) for x in report.sigma], strict=True)),
        "target_m": report.target_m,
    }


def identifiability_json(ident: Identifiability) -> dict[str, Any]:
    """Identifiability as a JSON-ready dict (SI)."""
    return {
        "rank": ident.rank,
        "parameters": ident.columns.size,
        "rank_tolerance": ident.rank_tolerance,
        "pivots_relative": ident.pivots.tolist(),
        "condition": ident.condition,
        "observability_O1": ident.observability,
        "base_parameters": [
            {"name": n, "identified_combination": c, "std": float(s), "unit": ident.units[b]}
            for n, c, s, b in zip(
                ident.base_names, ident.identified_combinations(), ident.std, ident.base, strict=True
            )
        ],
        "unidentifiable_directions": ident.unidentifiable_combinations(),
        "correlated_pairs": [{"a": a, "b": b, "rho": r} for a, b, r in ident.correlated],
    }


# --- the study ---------------------------------------------------------------------------------


def _study_row(s: ErrorSummary) -> list[str]:
    f, lo, hi = s.beyond
    has_tilt = np.isfinite(s.tilt_rad).any()
    return [
        s.label,
        _um(s.mean_m),
        _um(s.quantile_m(0.95)),
        _um(s.quantile_m(0.99)),
        _um(s.max_m),
        f"{100 * f:.2f} [{100 * lo:.2f}, {100 * hi:.2f}]",
        _urad(float(np.nanmean(s.tilt_rad))) if has_tilt else "-",
        _urad(float(np.nanmax(s.tilt_rad))) if has_tilt else "-",
        _urad(float(np.nanmean(s.angle_rad))) if has_tilt else "-",
    ]


def study_text(report: StudyReport, markdown: bool = False) -> str:
    """The study's table: before, Eq. 25, after each calibration (exact and its linear prediction)."""
    st, study = report.settings, report.study
    n_ho = len(study.holdout_points_m)
    inst = study.cases[0].plan.instrument if study.cases else None
    what = (
        f"tracker noise {1e3 * st.noise_m:.4g} mm per coordinate"
        if inst is None or (inst.name == "tracker" and not inst.nuisance_count)
        else "instrument " + inst.describe()
    )
    out = [
        f"calibration study on exact kinematics: {study.machines} machines × {n_ho} held-out random poses "
        f"(Δλ* = {1e3 * study.target_m:g} mm; {what}; "
        f"{st.poses} {'circles' if st.instrument == 'ballbar' else 'poses'} per calibration"
        + ("; a new plan per machine" if study.plans_per_machine else "")
        + f"; tool axis {np.round(study.tool_axis, 4).tolist()} in the platform frame)",
        "intervals: 95 % bootstrap over machines (2000 resamples; no failure at all: the bound "
        "1 − 0.05^(1/K))",
        "",
    ]
    rows = [
        [
            "",
            "mean Δλ [µm]",
            "p95 [µm]",
            "p99 [µm]",
            "max [µm]",
            "beyond Δλ* [%] (95 % CI)",
            "mean tilt [µrad]",
            "max tilt [µrad]",
            "mean angle [µrad]",
        ],
        _study_row(study.before),
        _study_row(study.ideal),
        _study_row(study.ideal_linear),
    ]
    blind = inst is not None and inst.nuisance_count > 0  # placement in K unseen (docs/instruments.md)
    for c in study.cases:
        rows += [_study_row(c.exact), _study_row(c.linear)]
        if blind and c.registered is not None:
            rows.append(_study_row(c.registered))
    out += [_table(rows, markdown), ""]
    rows = [
        [
            "case",
            "rank",
            "condition",
            "O1",
            "GN iterations (mean, max)",
            "max |Δλ exact − linear| [µm]",
            "row gap exact − linear [µm]",
            "machines left out (not converged)",
        ]
    ]
    for c in study.cases:
        rows.append(
            [
                c.case.label,
                str(c.plan.ident.rank),
                f"{c.plan.ident.condition:.3g}",
                f"{c.plan.ident.observability:.3g}",
                f"{c.iterations.mean():.1f}, {c.iterations.max()}",
                _um(c.linear_exact_difference_m),
                _um(c.linear_gap_m) + ("" if c.linear_valid else " (!)"),
                str(len(c.unconverged)),
            ]
        )
    out += [_table(rows, markdown), ""]
    if not study.ideal_linear_valid:
        out.append(f"warning: Eq. 25 rows: {LINEAR_WARNING} (gap beyond 5 % of Δλ*)")
    for c in study.cases:
        if not c.linear_valid:
            out.append(
                f"warning: '{c.case.label}': {LINEAR_WARNING} (the exact and linear mean/p95/p99 differ "
                f"by {_um(c.linear_gap_m)} µm, beyond 5 % of Δλ* = {_um(0.05 * study.target_m)} µm)"
            )
        if c.unconverged:
            names = ", ".join(f"#{k}" for k, _ in c.unconverged[:20]) + (
                " …" if len(c.unconverged) > 20 else ""
            )
            out.append(
                f"'{c.case.label}': {len(c.unconverged)} of {study.machines} machines left out of its rows, "
                f"their identification did not converge ({names}; {c.unconverged[0][1]})"
            )
    spread = [c for c in study.cases if c.plan_spread]
    if spread:
        rows = [
            [
                "case (one plan per machine)",
                "mean Δλ [µm]: 5 % / median / 95 % of plans",
                "beyond Δλ* [%]: 5 % / median / 95 % of plans",
                "worst plan: beyond [%]",
            ]
        ]
        for c in spread:
            m = np.array([x[0] for x in c.plan_spread])
            b = np.array([x[1] for x in c.plan_spread])
            qm, qb = np.nanquantile(m, (0.05, 0.5, 0.95)), np.nanquantile(b, (0.05, 0.5, 0.95))
            rows.append(
                [
                    c.case.label,
                    " / ".join(_um(x) for x in qm),
                    " / ".join(f"{100 * x:.2f}" for x in qb),
                    f"{100 * np.nanmax(b):.2f}",
                ]
            )
        out += ["plan-to-plan spread (each machine calibrated by its own plan):", _table(rows, markdown), ""]
    if report.holdout_skipped:
        out.append(f"({report.holdout_skipped} random held-out draws were unreachable and left out)")
    out.append("stage times: " + ", ".join(f"{k} {v:.2f} s" for k, v in report.timings_s.items()))
    return "\n".join(out) + "\n"


def _summary_json(s: ErrorSummary) -> dict[str, Any]:
    f, lo, hi = s.beyond
    finite_tilt = np.isfinite(s.tilt_rad).any()
    return {
        "label": s.label,
        "samples": s.samples,
        "mean_dlambda_m": s.mean_m,
        "p95_dlambda_m": s.quantile_m(0.95),
        "p99_dlambda_m": s.quantile_m(0.99),
        "max_dlambda_m": s.max_m,
        "beyond_target": f,
        "beyond_target_ci95": [lo, hi],
        "machines": s.machines,
        "mean_tilt_rad": float(np.nanmean(s.tilt_rad)) if finite_tilt else None,
        "max_tilt_rad": float(np.nanmax(s.tilt_rad)) if finite_tilt else None,
        "mean_angle_rad": float(np.nanmean(s.angle_rad)) if finite_tilt else None,
        "max_angle_rad": float(np.nanmax(s.angle_rad)) if finite_tilt else None,
    }


def study_json(report: StudyReport) -> dict[str, Any]:
    """The study as a JSON-ready dict (SI)."""
    s = report.study
    return {
        "machines": s.machines,
        "instrument": report.settings.instrument,
        "tracker_frame": report.settings.tracker_frame,
        "plans_per_machine": s.plans_per_machine,
        "intervals": "95 % bootstrap over machines",
        "eq25_linear_model_valid": s.ideal_linear_valid,
        "holdout_poses": len(s.holdout_points_m),
        "target_m": s.target_m,
        "noise_m": report.settings.noise_m,
        "poses_per_calibration": report.settings.poses,
        "tool_axis": s.tool_axis.tolist(),
        "before_calibration": _summary_json(s.before),
        "eq25_ideal_exact": _summary_json(s.ideal),
        "eq25_ideal_linear": _summary_json(s.ideal_linear),
        "cases": [
            {
                "controller": c.case.controller
                if isinstance(c.case.controller, str)
                else list(c.case.controller),
                "selection": c.case.selection,
                "poses": c.case.poses,
                "rank": c.plan.ident.rank,
                "condition": c.plan.ident.condition,
                "observability_O1": c.plan.ident.observability,
                "exact": _summary_json(c.exact),
                "linear_prediction": _summary_json(c.linear),
                "max_exact_linear_difference_m": c.linear_exact_difference_m,
                "row_gap_exact_linear_m": c.linear_gap_m,
                "linear_model_valid": c.linear_valid,
                "warning": None if c.linear_valid else LINEAR_WARNING,
                "gauss_newton_iterations_mean": float(c.iterations.mean()),
                "unconverged_machines": [{"machine": k, "why": why} for k, why in c.unconverged],
                "machines_in_rows": s.machines - len(c.unconverged),
                "plan_spread": [{"mean_dlambda_m": a, "beyond_target": b} for a, b in c.plan_spread],
            }
            for c in s.cases
        ],
        "timings_s": report.timings_s,
    }


# --- real data ---------------------------------------------------------------------------------


def identified_text(cal: RealCalibration, markdown: bool = False) -> str:
    """Identified parameters with their σ, residuals before and after, identifiability."""
    r = cal.result
    m = cal.measurements
    out = [
        f"identified from {m.commands.shape[0]} poses × {m.measured_m.shape[1]} target(s) "
        f"({cal.H.shape[0]} coordinates): {r.method}, {r.iterations} Gauss–Newton iterations"
        + ("" if r.converged else " — NOT CONVERGED: the result is the last iterate; check the data"),
        f"residual RMS per coordinate: before {_um(r.rms_before_m)} µm (nominal model), "
        f"after {_um(r.rms_after_m)} µm"
        f" (tracker noise assumed {1e3 * cal.ident.noise_m:.4g} mm)",
        "",
    ]
    rows = [["identified quantity", "estimate", "σ", "unit"]]
    units = dict(zip(cal.ident.names, cal.ident.units, strict=True))
    for name, v, s in zip(r.names, r.identified, r.std, strict=True):
        f, unit = _si_unit(units[name])
        rows.append([name, f"{f * v:+.4g}", f"{f * s:.3g}", unit])
    out += [_table(rows, markdown), ""]
    out += identifiability_lines(cal.ident, markdown)
    worst = np.argsort(-np.linalg.norm(r.residuals_m, axis=2).max(axis=1))[:5]
    out.append("largest residuals after calibration (pose label: |residual| µm):")
    out += [
        f"  {m.labels[k]} (line {m.lines[k]}): {_um(float(np.linalg.norm(r.residuals_m[k], axis=1).max()))}"
        for k in worst
    ]
    return "\n".join(out) + "\n"


def identified_json(cal: RealCalibration, names: list[str]) -> dict[str, Any]:
    """The identification as a JSON-ready dict (SI)."""
    r = cal.result
    return {
        "method": r.method,
        "iterations": r.iterations,
        "converged": r.converged,
        "rms_before_m": r.rms_before_m,
        "rms_after_m": r.rms_after_m,
        "identified": [
            {"name": n, "value": float(v), "std": float(s)}
            for n, v, s in zip(r.names, r.identified, r.std, strict=True)
        ],
        "covariance": r.covariance.tolist(),
        "estimate": dict(zip(names, [float(x) for x in r.estimate], strict=True)),
        "identifiability": identifiability_json(cal.ident),
        "pool_rank": cal.pool_rank,
    }


def identified_csv(cal: RealCalibration) -> str:
    """Identified quantities as CSV: name, value, σ, unit (SI)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["name", "value", "std", "unit"])
    units = dict(zip(cal.ident.names, cal.ident.units, strict=True))
    for n, v, s in zip(cal.result.names, cal.result.identified, cal.result.std, strict=True):
        w.writerow([n, repr(float(v)), repr(float(s)), units[n]])
    return buf.getvalue()


def residuals_csv(cal: RealCalibration) -> str:
    """Per measured target: residual before and after calibration [mm]."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["pose", "line", "target"] + [f"before_{a} [mm]" for a in "xyz"] + [f"after_{a} [mm]" for a in "xyz"]
    )
    r, m = cal.result, cal.measurements
    for k in range(m.commands.shape[0]):
        for t in range(m.measured_m.shape[1]):
            w.writerow(
                [m.labels[k], int(m.lines[k]), t]
                + [f"{1e3 * x:.6f}" for x in r.residuals_before_m[k, t]]
                + [f"{1e3 * x:.6f}" for x in r.residuals_m[k, t]]
            )
    return buf.getvalue()


def dumps(doc: dict[str, Any]) -> str:
    """JSON text (UTF-8, indented, NaN/inf as null)."""

    def clean(x: Any) -> Any:
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, list | tuple):
            return [clean(v) for v in x]
        if isinstance(x, np.integer):
            return int(x)
        if isinstance(x, np.floating):
            return clean(float(x))
        return x

    return json.dumps(clean(doc), indent=2, ensure_ascii=False) + "\n"
