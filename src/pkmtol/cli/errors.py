"""``pkmtol errors``: every error parameter, its class and its sensitivity at the worst pose."""

from __future__ import annotations

import argparse
from pathlib import Path

from pkmtol.cli.calibration_options import add_plan_options, calibrated_settings
from pkmtol.cli.common import add_tool_options, apply_tool_options, mm, show_progress
from pkmtol.design.modes import mode_error_table
from pkmtol.error_model.sweep import CLASSES
from pkmtol.exceptions import OutputError
from pkmtol.files import destination, write_atomic
from pkmtol.model.loader import load_mechanism
from pkmtol.present.tables import overconstraint_lines, text_table


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol errors`` and its options."""
    p = subparsers.add_parser(
        "errors",
        help="classify every geometric error parameter; sensitivities at the worst pose",
        description="Build the error model over the task-space grid, classify every parameter "
        "(absorbed / compensatable / uncompensatable) and print its sensitivity at the most "
        "error-sensitive pose.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    p.add_argument(
        "--set",
        dest="pset",
        choices=["dh", "urdf"],
        default=None,
        help="parameter set (default: dh when every limb has a D–H table, else urdf)",
    )
    p.add_argument(
        "--compensation",
        choices=["ideal", "calibrated", "none"],
        default="ideal",
        help="ideal: the paper's classes (default); calibrated: identified / toleranced / absorbed after "
        "the calibration plan of [calibration] or the options below; none: no compensation",
    )
    add_plan_options(p)
    p.add_argument("--json", type=Path, default=None, help="also write the table as JSON to FILE")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_tool_options(p)
    p.set_defaults(run=_run)


def _run(args: argparse.Namespace) -> int:
    mech = apply_tool_options(load_mechanism(args.robot), args)
    if args.json is not None and not (args.json.parent or Path(".")).is_dir():
        raise OutputError(args.json, f"folder {args.json.parent} does not exist")
    if args.json is not None:
        destination(args.json)  # a device or FIFO is refused before any work (docs/outputs.md)
    settings = calibrated_settings(mech, args)
    table = mode_error_table(
        mech, args.pset, args.compensation, settings, progress=show_progress(args.no_progress)
    )
    text = table.to_json()  # rendered before anything is printed or written
    names = CLASSES if args.compensation == "ideal" else tuple(dict.fromkeys(table.classes))
    counts = {c: table.classes.count(c) for c in names}
    mode = "" if args.compensation == "ideal" else f" ({args.compensation} compensation)"
    print(
        f"parameter set '{table.pset.kind}'{mode}: {len(table.pset)} parameters — "
        + ", ".join(f"{counts[c]} {c}" for c in names)
    )
    what = "η_c" if args.compensation == "ideal" else "the toleranced errors"
    point = "P" if mech.tool is None else "TCP"
    print(f"worst pose (largest σ[Δλ] with {what} ~ N(0,1) SI): {point} = {mm(table.worst_point_m)}")
    for line in overconstraint_lines(table.grid, table.pset.names):
        print(line)
    wc = table.grid.W_condition
    what_w = "the wrench matrix W" if mech.tool is None else "D S B (what the actuators do to the task)"
    print(f"condition number of {what_w} over the grid: {wc.min():.3g}–{wc.max():.3g}")
    rows = [["parameter", "unit", "class", "sensitivity", "uncompensated"]]
    for p, c, s, su in zip(
        table.pset.parameters, table.classes, table.sensitivity, table.sensitivity_uncompensated, strict=True
    ):
        # the unit of the sensitivities (P's displacement per unit error), not of the error itself
        unit = "µm/µm" if p.unit == "m" else "µm/µrad"
        rows.append([p.name, unit, c, f"{s:.4f}", f"{su:.4f}"])
    print(text_table(rows))
    if args.json is not None:
        write_atomic(args.json, text.encode())
        print(f"wrote {args.json}")
    return 0
