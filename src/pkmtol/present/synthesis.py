"""The tables and the figure of ``pkmtol sweep``: one row per design variant (text, CSV, JSON, PNG/SVG)."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.design.synthesis import Synthesis, Variant
from pkmtol.exceptions import OutputError
from pkmtol.files import write_atomic
from pkmtol.present.tables import text_table
from pkmtol.units import display, display_unit

#: Columns of the summary table after the varied keys.
SUMMARY = (
    "reachable",
    "worst P [mm]",
    "σ[Δλ], unit errors [m/unit]",
    "σ[Δλ], reference tolerances [µm]",
    "cost",
)


def _value(x: float) -> str:
    return f"{x:.6g}"


def _point(p: np.ndarray) -> str:
    if not np.isfinite(p).all():
        return "-"
    return "(" + ", ".join(f"{round(1e3 * x, 1) + 0.0:.1f}" for x in p) + ")"


def summary_rows(s: Synthesis) -> list[list[str]]:
    """Header and one row per variant: the varied values, reachability, worst P, σ[Δλ], cost."""
    rows = [[v.key for v in s.varies] + list(SUMMARY)]
    for var in s.variants:
        keys = [_value(var.values[v.key]) for v in s.varies]
        if not var.reachable:
            rows.append(keys + [f"no: {var.reason}", "-", "-", "-", "-"])
            continue
        ref = "-" if math.isnan(var.sigma_reference_m) else f"{var.sigma_reference_m * 1e6:.2f}"
        rows.append(
            keys + ["yes", _point(var.worst_point_m), f"{var.sigma_unit_m:.4f}", ref, f"{var.cost:.1f}"]
        )
    return rows


def tolerance_rows(s: Synthesis) -> list[list[str]]:
    """The design-β tolerances of the reference's η_c (mm, mrad), one column per variant."""
    head = ["No.", "parameter", "unit"] + [
        ", ".join(f"{v.key.rsplit('.', 1)[-1]}={_value(var.values[v.key])}" for v in s.varies) or "-"
        for var in s.variants
    ]
    rows = [head]
    ref = s.reference
    for k, (name, unit) in enumerate(zip(ref.names, ref.units, strict=True)):
        cells = []
        for var in s.variants:
            if not var.reachable or name not in var.names:
                cells.append("-")
                continue
            t = var.tolerances[var.names.index(name)]
            cells.append("free" if not np.isfinite(t) else f"±{display(t, unit):.4f}")
        rows.append([str(k + 1), name, display_unit(unit)] + cells)
    return rows


def summary_text(s: Synthesis) -> str:
    """What ``pkmtol sweep`` prints."""
    ref = s.reference
    lines = [
        f"pkmtol sweep — {s.robot}: {len(s.variants)} variants, parameter set '{s.parameter_set}', "
        f"β = {s.design_beta:g}, {s.executor}",
        f"reference (mechanism.toml as given): worst P = {_point(ref.worst_point_m)} mm, "
        f"σ[Δλ] = {ref.sigma_unit_m:.4f} m/unit, {len(ref.names)} uncompensatable errors, "
        f"cost {ref.cost:.1f}",
        "",
        text_table(summary_rows(s)),
    ]
    if len(s.variants) <= 12:
        how = s.method + (f", criterion {s.criterion}" if s.method == "exact" else "")
        lines += [
            "",
            f"tolerances at β = {s.design_beta:g} (mm, mrad), the '{how}' design of allocate:",
            text_table(tolerance_rows(s)),
        ]
    return "\n".join(lines) + "\n"


def _variant_dict(s: Synthesis, var: Variant) -> dict[str, Any]:
    return {
        "values": var.values,
        "reachable": var.reachable,
        "reason": var.reason,
        "worst_point_m": [float(x) for x in var.worst_point_m] if var.reachable else None,
        "sigma_unit_errors_m": var.sigma_unit_m if var.reachable else None,
        "sigma_reference_tolerances_m": None if math.isnan(var.sigma_reference_m) else var.sigma_reference_m,
        "tolerances_si": {
            n: (float(t) if np.isfinite(t) else None) for n, t in zip(var.names, var.tolerances, strict=True)
        },
        "cost": var.cost if var.reachable else None,
        "seconds": var.seconds,
    }


def to_json(s: Synthesis) -> str:
    """JSON of the sweep: SI units (m, rad), free tolerances as null, the reference first."""
    doc = {
        "robot": s.robot,
        "parameter_set": s.parameter_set,
        "design_beta": s.design_beta,
        "method": s.method,
        "criterion": s.criterion,
        "varied": {v.key: list(v.values) for v in s.varies},
        "units": "tolerances in m or rad (their parameter's unit); σ in m; free tolerance = null",
        "reference": _variant_dict(s, s.reference),
        "variants": [_variant_dict(s, var) for var in s.variants],
    }
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def to_csv(s: Synthesis) -> str:
    """CSV: one row per variant; tolerances of the reference's η_c in mm or mrad (empty: free)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    names = s.reference.names
    w.writerow(
        [v.key for v in s.varies]
        + [
            "reachable",
            "reason",
            "worst_x_mm",
            "worst_y_mm",
            "worst_z_mm",
            "sigma_unit_m",
            "sigma_reference_um",
            "cost",
        ]
        + [f"{n} [{display_unit(u)}]" for n, u in zip(names, s.reference.units, strict=True)]
    )
    for var in s.variants:
        row: list[Any] = [var.values[v.key] for v in s.varies] + [int(var.reachable), var.reason]
        if var.reachable:
            row += [f"{1e3 * x:.6g}" for x in var.worst_point_m]
            row += [
                f"{var.sigma_unit_m:.8g}",
                "" if math.isnan(var.sigma_reference_m) else f"{var.sigma_reference_m * 1e6:.6g}",
            ]
            row += [f"{var.cost:.8g}"]
            for n, u in zip(names, s.reference.units, strict=True):
                t = var.tolerances[var.names.index(n)] if n in var.names else math.nan
                row.append(f"{display(t, u):.6g}" if np.isfinite(t) else "")
        w.writerow(row)
    return buf.getvalue()


def sweep_figure(s: Synthesis) -> Any:
    """σ[Δλ] (unit errors) and the cost against the first varied key, one line per other combination."""
    from pkmtol.present.plotting import new_figure

    fig = new_figure((7.0, 4.0))
    ax = fig.add_subplot()
    ax2 = ax.twinx()
    first = s.varies[0]
    groups: dict[tuple[float, ...], list[Variant]] = {}
    for var in s.variants:
        groups.setdefault(tuple(var.values[v.key] for v in s.varies[1:]), []).append(var)
    for label, vs in groups.items():
        x = np.array([v.values[first.key] for v in vs])
        ok = np.array([v.reachable for v in vs])
        sig = np.array([v.sigma_unit_m for v in vs])
        cost = np.array([v.cost for v in vs])
        name = ", ".join(f"{v.key}={_value(x)}" for v, x in zip(s.varies[1:], label, strict=True))
        line = ax.plot(x[ok], sig[ok], "o-", label=f"σ[Δλ] {name}".strip())[0]
        ax2.plot(x[ok], cost[ok], "s--", color=line.get_color(), alpha=0.6)
        if (~ok).any():
            ax.plot(
                x[~ok],
                np.zeros((~ok).sum()),
                "x",
                color="#d62728",
                label="unreachable" if label == next(iter(groups)) else None,
            )
    ax.set_xlabel(first.key)
    ax.set_ylabel("worst σ[Δλ], unit errors [m/unit] (solid)")
    ax2.set_ylabel(f"cost of the β = {s.design_beta:g} tolerances (dashed)")
    ax.set_title(f"{s.robot}: accuracy budget over {len(s.variants)} variants", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def write_sweep(s: Synthesis, out_dir: Path | str, figures: bool = True) -> list[Path]:
    """Write ``sweep.csv``, ``sweep.json`` (and ``sweep.png``, ``sweep.svg``) into ``out_dir``.

    Raises:
        OutputError: the folder cannot be made or written.
        FiguresError: figures asked for and matplotlib is missing.
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(out, err.strerror or str(err)) from err
    files = {"sweep.csv": to_csv(s).encode(), "sweep.json": to_json(s).encode()}
    if figures:
        from pkmtol.present.plotting import render

        fig = sweep_figure(s)
        files.update({f"sweep.{fmt}": render(fig, fmt, 150) for fmt in ("png", "svg")})
    for name, data in files.items():
        write_atomic(out / name, data)
    return [out / name for name in files]
