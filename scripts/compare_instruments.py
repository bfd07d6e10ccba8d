"""The buyer's comparison of docs/instruments.md: one row per instrument, from the study on exact kinematics.

For each robot and instrument: the plan (size, rank of the controller model, rank over the whole
candidate pool), the study on exact kinematics (machines at the manufacturing σ and the FOSM
tolerances of a quick allocation, calibrated by the instrument's D-optimal plan with the
compensatable controller (or the full one where the row says so), held-out random poses: p99 of
Δλ and of the tool-axis tilt in K, and p99 of Δλ once the workpiece is registered to each machine,
:mod:`pkmtol.calibration.registration`), and the calibrated-mode allocation against the same instrument
(`pkmtol allocate --compensation calibrated --instrument …`): the number of toleranced parameters
and their cost under the default [cost] model, or the noise floor that makes any tolerance
impossible.

Usage::

    python scripts/compare_instruments.py            # writes docs/data/instruments.json and the table
    python scripts/compare_instruments.py --check    # re-renders the table from the JSON, compares

The table sits in docs/instruments.md between the two ``instruments-table`` markers; the docs test
(tests/test_instruments_doc.py) checks that it is the rendering of docs/data/instruments.json.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.calibration.workflow import design_sigma, grid_classes, simulate
from pkmtol.design.cost import cost_model
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.error_model.parameters import default_set, parameter_set
from pkmtol.exceptions import PkmtolError
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "instruments.md"
DATA = ROOT / "docs" / "data" / "instruments.json"
ROBOTS = ("r2rps_ups", "tricept")
#: (row label, settings overrides)
ROWS = (
    ("tracker (P), frame registered", {}),
    ("tracker (P), frame identified", {"tracker_frame": "identify"}),
    ("tracker-multi (3 reflectors)", {"instrument": "tracker-multi"}),
    ("tracker-multi, full controller", {"instrument": "tracker-multi", "controller": "full"}),
    ("tracker-6d", {"instrument": "tracker-6d"}),
    ("tracker-6d, full controller", {"instrument": "tracker-6d", "controller": "full"}),
    ("ballbar (ISO 230-4 circles)", {"instrument": "ballbar"}),
    ("probe (sphere artifact)", {"instrument": "probe"}),
    ("probe (plane artifact: 5 faces of a block)", {"instrument": "probe", "artifact": "plane"}),
)
MACHINES, HOLDOUT, SEED = 20, 100, 0
BEGIN, END = "<!-- instruments-table:begin -->", "<!-- instruments-table:end -->"


def run() -> dict:
    """Every robot × instrument row (SI units)."""
    out: dict = {"machines": MACHINES, "holdout": HOLDOUT, "seed": SEED, "robots": {}}
    for robot in ROBOTS:
        mech = load_mechanism(ROOT / "robots" / robot)
        pset = parameter_set(mech, default_set(mech))
        classes = grid_classes(mech, pset)
        quick = allocate(
            mech,
            DesignOptions(
                parameter_set=pset.kind, samples=2000, verification_poses=200, exact_samples=0, claim_poses=50
            ),
        )
        tol = quick.tolerances[:, quick.design_column]
        rows = []
        for label, kw in ROWS:
            t0 = time.process_time()
            settings = CalibrationSettings(**kw)
            sigma = design_sigma(pset, classes, settings, tol)
            row: dict = {"label": label, "settings": kw}
            try:
                rep = simulate(
                    mech,
                    pset,
                    classes,
                    settings,
                    sigma,
                    mech.target_m,
                    machines=MACHINES,
                    holdout=HOLDOUT,
                    controllers=(settings.controller,),
                    selections=("d-optimal",),
                )
                case = rep.study.cases[0]
                plan = case.plan
                row.update(
                    plan_poses=plan.poses,
                    plan_size=f"{settings.poses} circles ({plan.poses} readings)"
                    if settings.instrument == "ballbar"
                    else f"{plan.poses} poses",
                    values=int(plan.H.shape[0]),
                    nuisance=plan.instrument.nuisance_count if plan.instrument else 0,
                    rank=plan.ident.rank,
                    parameters=int(plan.ident.columns.size),
                    pool_rank=plan.pool_rank,
                    p99_dlambda_m=case.exact.quantile_m(0.99),
                    p99_tilt_rad=float(np.nanquantile(case.exact.tilt_rad, 0.99)),
                    p99_registered_m=case.registered.quantile_m(0.99) if case.registered else None,
                    p99_registered_tilt_rad=float(np.nanquantile(case.registered.tilt_rad, 0.99))
                    if case.registered
                    else None,
                    linear_valid=case.linear_valid,
                    unconverged=len(case.unconverged),
                    before_p99_m=rep.study.before.quantile_m(0.99),
                )
            except PkmtolError as err:
                row["study_error"] = str(err)
            try:
                res = allocate(
                    mech,
                    DesignOptions(
                        parameter_set=pset.kind,
                        compensation="calibrated",
                        calibration=replace(settings, seed=SEED),
                        samples=2000,
                        verification_poses=200,
                        exact_samples=0,
                        claim_poses=50,
                    ),
                )
                col = res.design_column
                idx = [i for i in range(len(pset)) if np.isfinite(res.tolerances[i, col])]
                model = cost_model([pset.parameters[i] for i in idx], mech.extra.get("cost"))
                row.update(
                    toleranced=len(idx),
                    cost=model.cost(res.tolerances[idx, col]),
                    tightest_m=float(np.min(res.tolerances[idx, col])) if idx else float("nan"),
                )
            except PkmtolError as err:
                row["allocation_error"] = type(err).__name__ + ": " + str(err)
            row["cpu_s"] = time.process_time() - t0
            rows.append(row)
            print(robot, label, {k: v for k, v in row.items() if k != "settings"}, flush=True)
        out["robots"][robot] = rows
    return out


def _um(x: float | None) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{1e6 * x:.1f}"


def render(doc: dict) -> str:
    """The Markdown table of ``doc``."""
    lines = [
        "| robot | instrument | plan | rank (pool) | p99 Δλ [µm] | p99 tilt [µrad] "
        "| p99 Δλ, part registered [µm] | toleranced | cost |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for robot, rows in doc["robots"].items():
        for r in rows:
            if "study_error" in r:
                m = re.search(r"of (\d+) of (\d+) machines did not converge", r["study_error"])
                why = (
                    f"study failed: {m.group(1)} of {m.group(2)} machines not converged"
                    if m
                    else "study failed"
                )
                study = [why, "-", "-", "-", "-"]
            else:
                flag = "" if r["linear_valid"] else " ¹"
                study = [
                    f"{r['plan_size']}, {r['values']} values",
                    f"{r['rank']} of {r['parameters']} ({r['pool_rank']})",
                    _um(r["p99_dlambda_m"]) + flag,
                    _um(r["p99_tilt_rad"]),
                    _um(r.get("p99_registered_m")),
                ]
            if "allocation_error" in r:
                alloc = [
                    "none meets Δλ*",
                    "noise floor" if "NoiseFloor" in r["allocation_error"] else "failed",
                ]
            else:
                alloc = [str(r["toleranced"]), f"{r['cost']:.4g}"]
            lines.append("| " + " | ".join([robot, r["label"], *study, *alloc]) + " |")
    return "\n".join(lines)


def page_with(table: str) -> str:
    text = PAGE.read_text(encoding="utf-8")
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[:a] + "\n" + table + "\n" + text[b:]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only check the page against the JSON")
    args = ap.parse_args()
    if args.check:
        doc = json.loads(DATA.read_text(encoding="utf-8"))
        same = page_with(render(doc)) == PAGE.read_text(encoding="utf-8")
        print(
            "docs/instruments.md matches docs/data/instruments.json"
            if same
            else "docs/instruments.md is stale"
        )
        return 0 if same else 1
    doc = run()
    DATA.parent.mkdir(parents=True, exist_ok=True)
    DATA.write_text(json.dumps(doc, indent=1, default=float) + "\n", encoding="utf-8")
    PAGE.write_text(page_with(render(doc)), encoding="utf-8")
    print(render(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
