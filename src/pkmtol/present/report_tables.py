"""The sign-off tables: contributions, stack-ups, capability and drawing tolerances (text, Markdown, JSON).

Numbers come from :func:`pkmtol.design.signoff.sign_off`; human-facing cells state their unit in the
header (µm, mm, mrad, %). A share is each error's part of E[Δλ²] (E[Δα²] for the tilt) at the
design point; "worst" is its largest share over the task-space grid and the grid pose where it
occurs. The share column of the other tolerance tables (:func:`share_cells`) is that of the design
each table lists.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from pkmtol.design.contributions import NOISE, Contributions, contributions
from pkmtol.design.job import DesignResult
from pkmtol.design.signoff import result_maps, sign_off, tilt_reported
from pkmtol.error_model.accuracy import first_max
from pkmtol.units import display, display_unit

#: Header cells of the share columns (:func:`share_cells`).
SHARE_HEADER = ["share [%]", "worst share [%] (pose)"]
#: CSV header of the numeric share cells.
SHARE_CSV = ["share_percent", "worst_share_percent", "worst_share_pose"]


def percent(x: float) -> str:
    """A share (fraction) in % with one decimal; ``<0.1`` for a small non-zero one."""
    v = 100.0 * float(x)
    if not math.isfinite(v) or v == 0.0:
        return "0"
    return "<0.1" if v < 0.05 else f"{v:.1f}"


def _t(x: float, unit: str) -> str:
    return "+inf" if not math.isfinite(x) else f"±{display(x, unit):.4f}"


def share_cells(
    r: DesignResult,
    sigma: np.ndarray | None = None,
    tilt: bool = False,
    method: bool = False,
    numeric: bool = False,
) -> dict[int, list[str]]:
    """Share cells (design point, worst over the grid) of each toleranced error, by parameter index.

    Args:
        r: The design.
        sigma: Shape (n_params,): the σ whose shares are shown (None: FOSM at the design β).
        tilt: Shares of E[Δα²] at the tilt's most sensitive pose instead of E[Δλ²].
        method: The ``--method`` design's σ (``r.method_design``).
        numeric: Plain numbers for a CSV: share [%], worst share [%], its grid pose.
    """
    if method and r.method_design is not None:
        sigma = np.full(len(r.pset), np.nan)
        sigma[r.uncompensatable] = r.method_design.sigma
    elif sigma is None:
        sigma = r.tolerances[:, r.design_column]
    c = _contributions(r, sigma, tilt)
    if numeric:
        return {
            int(i): [f"{100 * c.at_design[k]:.6g}", f"{100 * c.worst[k]:.6g}", str(c.worst_pose[k])]
            for k, i in enumerate(c.columns)
        }
    return {
        int(i): [percent(c.at_design[k]), f"{percent(c.worst[k])} ({c.worst_pose[k]})"]
        for k, i in enumerate(c.columns)
    }


def _contributions(r: DesignResult, sigma: np.ndarray, tilt: bool) -> Contributions:
    maps = result_maps(r)
    s = np.where(np.isfinite(sigma), sigma, 0.0)
    if tilt and r.orientation is not None:
        t_map, t_noise = maps.tilt_maps(r.orientation.axis)
        return contributions(t_map, s, r.uncompensatable, r.orientation.worst_index, t_noise, maps.noise_m)
    return contributions(
        maps.position, s, r.uncompensatable, r.worst_index, maps.position_noise, maps.noise_m
    )


def contribution_rows(r: DesignResult, tilt: bool = False) -> list[list[str]]:
    """Pareto table of the verified design: shares of E[Δλ²] (or E[Δα²]), largest first, cumulative."""
    so = sign_off(r)
    c = so.tilt_contributions if tilt else so.contributions
    assert c is not None
    rows = [["rank", "parameter", "unit", "σ", "±t", *SHARE_HEADER[:1], "cumulative [%]", SHARE_HEADER[1]]]
    lines = [(c.at_design[k], k) for k in c.order()]
    if c.noise_share.any():
        lines.append((c.noise_at_design, -1))
        lines.sort(key=lambda x: -x[0])
    cum = 0.0
    for rank, (share, k) in enumerate(lines, start=1):
        cum += share
        if k < 0:
            worst = f"{percent(c.noise_share.max())} ({first_max(c.noise_share)})"
            rows.append([str(rank), NOISE, "mm", "-", "-", percent(share), percent(cum), worst])
            continue
        i = int(c.columns[k])
        p = r.pset.parameters[i]
        rows.append(
            [
                str(rank),
                p.name,
                display_unit(p.unit),
                f"{display(so.sigma[i], p.unit):.4f}",
                _t(so.tolerance[i], p.unit),
                percent(share),
                percent(cum),
                f"{percent(c.worst[k])} ({c.worst_pose[k]})",
            ]
        )
    return rows


def stackup_rows(r: DesignResult) -> list[list[str]]:
    """Worst case, arithmetic, RSS, FOSM and exact Δλ of the drawing tolerances (design point, grid max)."""
    so = sign_off(r)
    st, cap, w = so.stackup, so.capability, so.design_index
    beta = f"{r.design_beta:g}"
    r_pct = f"{100 * so.reliability_target:.2f} %"
    rows: list[list[str]] = [
        ["stack-up of the drawing tolerances ±t", "design point [µm]", "task space max [µm] (pose)"]
    ]
    for label, v in (
        ("worst case over the tolerance box (exact, zonotope vertices)", st.worst_case_m),
        ("arithmetic Σ ω_i t_i (upper bound of the worst case)", st.arithmetic_m),
        ("RSS √Σ (ω_i t_i)² (lower bound of the worst case)", st.rss_m),
        (f"FOSM β·√E[Δλ²], β = {beta} (claimed at R = {r_pct})", so.fosm_m),
        (f"exact {r_pct} quantile of Δλ (Gaussian σ_i)", cap.quantile),
        ("exact mean E[Δλ]", cap.mean),
    ):
        k = first_max(np.where(np.isnan(v), -np.inf, v))
        rows.append([label, f"{1e6 * v[w]:.2f}", f"{1e6 * v[k]:.2f} ({k})"])
    rows.append(["required Δλ*", f"{1e6 * r.target_m:.2f}", f"{1e6 * r.target_m:.2f}"])
    return rows


def capability_rows(r: DesignResult) -> list[list[str]]:
    """Cpk, exact PPM, the PPM Cpk implies for a normal Δλ, and the sigma level."""
    so = sign_off(r)
    out = [["index", "where", "pose", "μ", "σ", "Cpk", "PPM (exact)", "PPM if normal", "sigma level Z"]]
    caps = [("Δλ [µm]", so.capability, so.design_index, 1e6)]
    if so.tilt_capability is not None and r.orientation is not None:
        caps.append(("Δα [µrad]", so.tilt_capability, r.orientation.worst_index, 1e6))
    for name, cap, design, scale in caps:
        for where, k in (
            ("design point", design),
            ("lowest Cpk on the grid", cap.worst_cpk_index),
            ("most PPM on the grid", cap.worst_ppm_index),
        ):
            out.append(
                [
                    name,
                    where,
                    str(k),
                    f"{scale * cap.mean[k]:.2f}",
                    f"{scale * cap.std[k]:.2f}",
                    f"{cap.cpk[k]:.3f}",
                    _ppm(cap.ppm[k]),
                    _ppm(cap.ppm_normal[k]),
                    _z(cap.sigma_level[k], cap.ppm[k]),
                ]
            )
        mean_ppm = float(cap.ppm.mean())
        out.append([name, "mean over the grid", "-", "-", "-", "-", _ppm(mean_ppm), "-", _z(None, mean_ppm)])
    return out


def _ppm(x: float) -> str:
    if x < 1e-3:
        return "< 0.001"
    return f"{x:.4g}" if x < 1000 else f"{x:.0f}"


def _z(z: float | None, ppm: float) -> str:
    from scipy import special

    if ppm < 1e-3:
        return "> 6.1"
    value = float(-special.ndtri(ppm / 1e6)) if z is None else z  # Φ⁻¹(1 − p), as scipy.stats.norm.isf
    return f"{value:.2f}"


def drawing_rows(r: DesignResult) -> list[list[str]]:
    """One row per toleranced error: σ, ±t, shares, callout kind, nominal, zone, IT grade, the callout."""
    so = sign_off(r)
    rows = [
        [
            "parameter",
            "unit",
            "σ",
            "±t",
            *SHARE_HEADER,
            "callout",
            "nominal",
            "zone [mm]",
            "ISO 286",
            "on the drawing",
        ]
    ]
    c = so.contributions
    shares = {
        int(i): [percent(c.at_design[k]), f"{percent(c.worst[k])} ({c.worst_pose[k]})"]
        for k, i in enumerate(c.columns)
    }
    for d in so.drawings:
        if d.nominal_m is not None:
            nominal = f"{1e3 * d.nominal_m:.6g} mm"
        elif d.nominal_angle_rad is not None:
            nominal = f"{math.degrees(d.nominal_angle_rad):.1f}°"
        else:
            nominal = "-"
        rows.append(
            [
                d.name,
                display_unit(d.unit),
                f"{display(d.sigma, d.unit):.4f}",
                _t(d.tolerance, d.unit),
                *shares.get(d.index, ["-", "-"]),
                d.kind,
                nominal,
                "-" if d.zone_m is None else f"{1e3 * d.zone_m:.4f}",
                d.it.label if d.it is not None else "-",
                d.callout,
            ]
        )
    return rows


def signoff_text(
    r: DesignResult, table: Callable[[list[list[str]]], str], heading: Callable[[str], str]
) -> list[str]:
    """The sign-off sections of the report, rendered with the report's ``table`` and ``heading``."""
    so = sign_off(r)
    design = "FOSM at the design β" if r.method_design is None else f"the '{r.method_design.method}' design"
    c = so.contributions
    top = np.argsort(-c.worst)[:3]
    names = r.pset.names
    largest = ", ".join(f"{names[c.columns[k]]} {percent(c.worst[k])} % ({c.worst_pose[k]})" for k in top)
    out = [
        heading("Contributions to E[Δλ²] (percent contribution, Pareto)"),
        f"design: {design}; design point = grid pose {so.design_index}; the shares sum to 100 % there"
        + (" (equal: the equal-effect shape of Eq. 19)" if _equal(c.at_design) else "")
        + ". 'worst': each error's largest share over the task-space grid (its pose); largest: "
        + (largest or "no toleranced parameter (what is left is the tracker noise's)"),
        "",
        table(contribution_rows(r)),
    ]
    if so.tilt_contributions is not None:
        out += [
            heading("Contributions to E[Δα²] (tilt of the tool axis)"),
            f"at the tilt's most sensitive grid pose {so.tilt_design_index}",
            "",
            table(contribution_rows(r, tilt=True)),
        ]
    out += [
        heading(f"Stack-up of the drawing tolerances ({so.drawing.short_label})"),
        f"convention: {so.drawing.label}; worst case: the exact largest Δλ over the box |η_i| ≤ t_i "
        "(toleranced errors only; the tracker noise is Gaussian and unbounded, so it is in the FOSM "
        "and exact rows only)",
        "",
        table(stackup_rows(r)),
        heading("Process capability (Gaussian errors at the design σ_i, one-sided limit Δλ*)"),
        "Cpk = (Δλ* − μ)/(3σ); PPM (exact): 10⁶ P(Δλ > Δλ*) from the exact distribution of Δλ; PPM if "
        "normal: what Cpk implies for a normal Δλ, 10⁶ Φ(−3 Cpk); Z = Φ⁻¹(1 − PPM/10⁶), no 1.5σ shift",
        "",
        table(capability_rows(r)),
        heading(f"Drawing tolerances ({so.drawing.short_label})"),
        f"convention: {so.drawing.label}; size: ISO 286-1 grade of the zone 2t for the nominal "
        "(the coarsest IT ≤ 2t); position: nominal 0, zone 2t; perpendicularity/parallelism/angularity: "
        "zone L·tan δ over the feature length L "
        f"(default {1e3 * so.drawing.feature_length_m:g} mm, [drawing] in mechanism.toml)",
        "",
        table(drawing_rows(r)),
    ]
    return out


def _equal(shares: np.ndarray) -> bool:
    """Whether the non-zero shares are all equal (to 1e-6)."""
    nz = shares[shares > 0]
    return bool(nz.size > 1 and np.allclose(nz, nz.max(), rtol=1e-6))


def signoff_json(r: DesignResult) -> dict[str, Any]:
    """The sign-off numbers as a JSON-ready dict (SI, unit named per field; shares as fractions)."""
    so = sign_off(r)
    c, st, cap = so.contributions, so.stackup, so.capability
    w = so.design_index

    def contrib(x: Contributions | None) -> dict[str, Any] | None:
        if x is None:
            return None
        return {
            "design_index": x.design_index,
            "parameters": [r.pset.names[i] for i in x.columns],
            "share_design_point": x.at_design.tolist(),
            "share_worst": x.worst.tolist(),
            "share_worst_pose": x.worst_pose.tolist(),
            "noise_share_design_point": x.noise_at_design,
            "mean_square_design_point": float(x.mean_square[x.design_index]),
        }

    def capab(x: Any) -> dict[str, Any] | None:
        if x is None:
            return None
        return {
            "target": x.target,
            "mean": x.mean.tolist(),
            "std": x.std.tolist(),
            "cpk": [_finite(v) for v in x.cpk],
            "ppm_exact": x.ppm.tolist(),
            "ppm_if_normal": x.ppm_normal.tolist(),
            "sigma_level": x.sigma_level.tolist(),
            "lowest_cpk_pose": x.worst_cpk_index,
            "most_ppm_pose": x.worst_ppm_index,
        }

    return {
        "convention": {"kind": so.drawing.convention, "factor": so.drawing.factor, "text": so.drawing.label},
        "design_index": w,
        "contributions": contrib(c),
        "tilt_contributions": contrib(so.tilt_contributions) if tilt_reported(r) else None,
        "stackup_m": {
            "worst_case": st.worst_case_m.tolist(),
            "arithmetic": st.arithmetic_m.tolist(),
            "rss": st.rss_m.tolist(),
            "fosm": so.fosm_m.tolist(),
            "exact_quantile": cap.quantile.tolist(),
            "quantile_probability": so.reliability_target,
            "worst_case_signs_design_point": st.worst_signs[w].tolist(),
        },
        "capability": capab(cap),
        "tilt_capability": capab(so.tilt_capability),
        "drawing": [_drawing_json(d) for d in so.drawings],
    }


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _drawing_json(d: Any) -> dict[str, Any]:
    return {
        "name": d.name,
        "unit": d.unit,
        "sigma": d.sigma,
        "tolerance": d.tolerance,
        "kind": d.kind,
        "feature": d.feature,
        "datum": d.datum,
        "about_datum": d.about_datum,
        "nominal_m": d.nominal_m,
        "nominal_angle_rad": d.nominal_angle_rad,
        "zone_m": d.zone_m,
        "feature_length_m": d.feature_length_m,
        "it_grade": None if d.it is None else d.it.grade,
        "it_um": None if d.it is None else d.it.it_um,
        "callout": d.callout,
    }
