"""Tables of a calibration from an instrument's data: identified machine, identified nuisance, residuals.

The nuisance parameters (a tracker's frame, the ballbar's table balls, a probed artifact's pose)
are written beside the machine's estimate; a tracker frame or an artifact pose is also given as the
transform it stands for (translation in mm, rotation vector in deg). Units in every header; JSON
is SI with the unit named per field.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.calibration.instrument_data import InstrumentCalibration
from pkmtol.present.calibration_tables import (
    identifiability_json,
    identifiability_lines,
    markdown_table,
    unseen_lines,
)
from pkmtol.present.tables import text_table


def _scaled(value: float, unit: str) -> str:
    return f"{1e6 * value:+.4g}"


def _transform(cal: InstrumentCalibration) -> pin.SE3 | None:
    """The identified frame or artifact pose as a transform, or None for other instruments."""
    inst, pi = cal.result.instrument, cal.result.nuisance
    if inst is None:
        return None
    frame = getattr(inst, "frame", None)
    if frame is not None and frame.identify:
        return frame.transform(pi)
    if hasattr(inst, "pose") and inst.nuisance_count == 6:
        return inst.pose(pi)
    return None


def instrument_text(cal: InstrumentCalibration, markdown: bool = False) -> str:
    """What was identified, how well the data fit, and the identifiability."""
    r, m, inst = cal.result, cal.measurements, cal.instrument
    table = markdown_table if markdown else text_table
    out = [
        f"identified from {len(m.commands)} poses of the {inst.name} "
        f"({cal.system.effective.shape[0]} values): {r.method}, {r.iterations} Gauss–Newton iterations"
        + ("" if r.converged else " — NOT CONVERGED: the result is the last iterate; check the data"),
        "instrument " + inst.describe(),
        f"residual RMS: before {1e6 * r.rms_before_m:.2f} µm (nominal model), "
        f"after {1e6 * r.rms_after_m:.2f} µm; "
        f"after, in units of each value's σ: {r.weighted_rms:.3g} (≈ 1 when the fit reaches the noise)",
        "",
    ]
    rows = [["identified quantity", "estimate", "σ", "unit"]]
    units = dict(zip(cal.ident.names, cal.ident.units, strict=True))
    for name, v, s in zip(r.names, r.identified, r.std, strict=True):
        unit = "µm" if units[name] == "m" else "µrad"
        rows.append([name, _scaled(v, unit), f"{1e6 * s:.3g}", unit])
    out += [table(rows), ""]
    if inst.nuisance_count:
        rows = [["nuisance parameter (identified with the machine)", "estimate", "σ", "unit"]]
        for name, unit, v, s in zip(
            inst.nuisance_names, inst.nuisance_units, r.nuisance, r.nuisance_std, strict=True
        ):
            rows.append([name, _scaled(v, unit), f"{1e6 * s:.3g}", "µm" if unit == "m" else "µrad"])
        out += [table(rows), ""]
        T = _transform(cal)
        if T is not None:
            what = (
                "tracker frame → base K" if getattr(inst, "frame", None) is not None else "artifact → base K"
            )
            t, w = 1e3 * T.translation, np.rad2deg(pin.log3(T.rotation))
            out += [
                f"identified transform ({what}): translation [{t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}] mm, "
                f"rotation vector [{w[0]:.6f}, {w[1]:.6f}, {w[2]:.6f}] deg",
                "",
            ]
    out += unseen_lines(inst, cal.system.nuisance)
    out += identifiability_lines(cal.ident, markdown)
    res = np.abs(r.residuals_m).reshape(len(m.commands), -1).max(axis=1)
    worst = np.argsort(-res)[:5]
    out.append("largest residuals after calibration (pose label: largest |residual| µm or µrad):")
    out += [f"  {m.labels[k]} (line {m.lines[k]}): {1e6 * res[k]:.3f}" for k in worst]
    return "\n".join(out) + "\n"


def instrument_json(cal: InstrumentCalibration, names: list[str]) -> dict[str, Any]:
    """The identification as a JSON-ready dict (SI)."""
    r, inst = cal.result, cal.instrument
    T = _transform(cal)
    return {
        "instrument": inst.name,
        "method": r.method,
        "iterations": r.iterations,
        "converged": r.converged,
        "rms_before_m": r.rms_before_m,
        "rms_after_m": r.rms_after_m,
        "rms_after_in_sigma": r.weighted_rms,
        "identified": [
            {"name": n, "value": float(v), "std": float(s)}
            for n, v, s in zip(r.names, r.identified, r.std, strict=True)
        ],
        "covariance": r.covariance.tolist(),
        "estimate": dict(zip(names, [float(x) for x in r.estimate], strict=True)),
        "nuisance": inst.nuisance_report(r.nuisance, r.nuisance_std),
        "transform": None
        if T is None
        else {"translation_m": T.translation.tolist(), "rotation": T.rotation.tolist()},
        "identifiability": identifiability_json(cal.ident),
        "pool_rank": cal.pool_rank,
    }


def instrument_identified_csv(cal: InstrumentCalibration) -> str:
    """Identified quantities (machine, then nuisance) as CSV: name, value, σ, unit (SI)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["name", "value", "std", "unit"])
    r, inst = cal.result, cal.instrument
    units = dict(zip(cal.ident.names, cal.ident.units, strict=True))
    for n, v, s in zip(r.names, r.identified, r.std, strict=True):
        w.writerow([n, repr(float(v)), repr(float(s)), units[n]])
    for n, u, v, s in zip(inst.nuisance_names, inst.nuisance_units, r.nuisance, r.nuisance_std, strict=True):
        w.writerow([n, repr(float(v)), repr(float(s)), u])
    return buf.getvalue()


def instrument_residuals_csv(cal: InstrumentCalibration) -> str:
    """Per pose and value: residual before and after calibration [mm or mrad]."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    inst, r, m = cal.instrument, cal.result, cal.measurements
    head = ["pose", "line", "station"]
    for n, u in zip(inst.value_names, inst.value_units, strict=True):
        head.append(f"before_{n} [{'mm' if u == 'm' else 'mrad'}]")
    for n, u in zip(inst.value_names, inst.value_units, strict=True):
        head.append(f"after_{n} [{'mm' if u == 'm' else 'mrad'}]")
    w.writerow(head)
    before = r.residuals_before_m.reshape(len(m.commands), -1)
    after = r.residuals_m.reshape(len(m.commands), -1)
    for k in range(len(m.commands)):
        w.writerow(
            [m.labels[k], int(m.lines[k]), int(m.stations[k])]
            + [f"{1e3 * x:.6f}" if math.isfinite(x) else "nan" for x in before[k]]
            + [f"{1e3 * x:.6f}" if math.isfinite(x) else "nan" for x in after[k]]
        )
    return buf.getvalue()
