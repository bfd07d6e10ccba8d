"""The ``pkmtol`` command: one subcommand per job, each a thin layer over a library function.

``pkmtol check robots/<robot>`` loads and validates a mechanism and prints its structure, mobility,
constraints and task-space reachability (:mod:`pkmtol.check`). Every pkmtol error is printed as
``pkmtol: error: <message>`` on stderr with exit code 2; a check that finds problems exits 1.

To add a subcommand, write ``_add_<name>(subparsers)`` that registers its arguments and sets
``run=`` to a ``_run_<name>(args) -> int``, and list it in :data:`_SUBCOMMANDS`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from pkmtol import __version__
from pkmtol.design.job import DesignOptions, DesignResult, allocate
from pkmtol.error_model.sweep import CLASSES
from pkmtol.error_model.table import error_table
from pkmtol.exceptions import FiguresError, PkmtolError
from pkmtol.files import write_atomic
from pkmtol.kinematics.check import CheckReport, JointReport, check_mechanism
from pkmtol.model.loader import load_mechanism
from pkmtol.present.tables import (
    check_output_folder,
    overconstraint_lines,
    summary_text,
    text_table,
    write_outputs,
)
from pkmtol.units import parse_length

#: Exit code of a pkmtol error (bad input or an impossible request).
EXIT_ERROR = 2
#: Exit code of a check that ran but found problems.
EXIT_PROBLEMS = 1
#: Unreachable points listed one by one; the rest are counted.
MAX_LISTED = 10


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``pkmtol`` command line.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit code: 0 on success, 1 if a check found problems, 2 on a pkmtol error.

    """
    args = _parser().parse_args(argv)
    try:
        return int(args.run(args))
    except PkmtolError as err:
        print(f"pkmtol: error: {err}", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:  # output piped into `head` and closed early
        sys.stderr.close()
        return 0


# --- check -------------------------------------------------------------------------------


def _add_check(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "check",
        help="load and validate a mechanism; mobility, constraints, task-space reachability",
        description="Load robots/<robot>/mechanism.toml and its limb URDFs, then print the limbs "
        "and joints, the mobility, the constraint wrenches per limb, and inverse kinematics over "
        "the task-space grid (reachability, joint ranges, worst conditioning). Exit code 1 if a "
        "point is unreachable or the mobility differs from the number of actuators.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml (e.g. robots/r2rps_ups)")
    p.set_defaults(run=_run_check)


def _run_check(args: argparse.Namespace) -> int:
    report = check_mechanism(load_mechanism(args.robot))
    print("\n".join(format_check(report)))
    return EXIT_PROBLEMS if report.problems else 0


def format_check(report: CheckReport) -> list[str]:
    """Format ``report`` as the lines ``pkmtol check`` prints."""
    mech = report.mechanism
    out = [f"mechanism {mech.name}" + (f": {mech.description}" if mech.description else "")]
    if mech.root is not None:
        out.append(f"  folder {mech.root}")
    out.append(
        f"  {len(mech.limbs)} limbs, {mech.n_joints} joints, {mech.n_actuators} actuators; "
        f"reference point P in the platform frame {_mm(mech.reference_point_m)}"
    )
    out.append("")
    out.append("limbs (limits from the URDF; range = values used at the reachable grid points)")
    for limb in report.limbs:
        actuated = [j.name for j in limb.joints if j.actuated]
        source = limb.urdf_path.name if limb.urdf_path is not None else "(pin.Model)"
        out.append(
            f"  {limb.name}  {source}  actuated: {', '.join(actuated) or 'none (passive limb)'}  "
            f"constraint wrenches: {limb.constraint_count}"
        )
        width = max(len("joint"), *(len(j.name) for j in limb.joints))
        out.append(
            f"    {'joint':<{width}}  type  unit  {'lower':>9}  {'upper':>9}  "
            f"{'range min':>9}  {'range max':>9}"
        )
        for j in limb.joints:
            out.append(f"    {j.name:<{width}}  {_joint_row(j)}")
    out.append("")
    out.append(
        f"mobility: f = {report.mobility}  ({report.n_joints} joints - rank {report.closure_rank} "
        f"of the closure Jacobian at home; {mech.n_actuators} actuators)"
    )
    out.append(
        "constraint wrenches per limb (6 - rank of its joint twists at home): "
        + ", ".join(f"{limb.name} {limb.constraint_count}" for limb in report.limbs)
    )
    out.append("")
    out.append(f"task space: {_describe_task_space(report)}")
    out.append(f"reachable: {report.n_reachable}/{len(report.points)} points")
    for p in report.unreachable[:MAX_LISTED]:
        out.append(f"  - {p.error}")
    if len(report.unreachable) > MAX_LISTED:
        out.append(f"  ... and {len(report.unreachable) - MAX_LISTED} more unreachable points")
    n_passive = report.n_joints - mech.n_actuators
    rows = [
        ("inverse", f"inverse kinematics (closure + task rows, {report.n_joints} joints)"),
        ("forward", f"forward kinematics (closure rows, {n_passive} passive joints)"),
    ]
    if report.n_reachable:
        width = max(len(label) for _, label in rows)
        out.append("condition number over the reachable points (Jacobians mix m and rad):")
        for which, label in rows:
            worst = report.worst(which)
            assert worst is not None
            values = [getattr(p, f"{which}_condition") for p in report.points if p.reachable]
            out.append(
                f"  {label:<{width}}  {min(values):.4g} to {max(values):.4g}, "
                f"worst at P = {_mm(worst.target_m)}"
            )
    out.append("")
    out.append("result: " + ("; ".join(report.problems) if report.problems else "OK"))
    return out


def _describe_task_space(report: CheckReport) -> str:
    ts = report.mechanism.task_space
    n = len(report.points)
    if ts.kind == "cylinder":
        per_layer = " + ".join(str(k) for k in (1, *ts.rings))
        return (
            f"cylinder radius {1e3 * ts.radius_m:.1f} mm about ({1e3 * ts.center_xy_m[0]:.1f}, "
            f"{1e3 * ts.center_xy_m[1]:.1f}) mm, z {1e3 * ts.z_range_m[0]:.1f} to "
            f"{1e3 * ts.z_range_m[1]:.1f} mm, {ts.layers} layers x ({per_layer}) = {n} points"
        )
    return f"{n} listed points"


def _joint_row(joint: JointReport) -> str:
    """Type (``*`` = actuated), unit, limits and grid range of a joint in deg (R) or mm (P)."""
    unit, scale = ("deg", 180.0 / np.pi) if joint.kind == "R" else ("mm", 1e3)
    values = (joint.lower, joint.upper, joint.grid_min, joint.grid_max)
    kind = joint.kind + ("*" if joint.actuated else "")
    return f"{kind:<4}  {unit:<4}  " + "  ".join(_num(v, scale) for v in values)


def _num(value: float, scale: float) -> str:
    if np.isnan(value):
        return f"{'-':>9}"
    if abs(value) > 1e300:  # Pinocchio's "no limit"
        return f"{'-inf' if value < 0 else 'inf':>9}"
    return f"{round(value * scale, 3) + 0.0:9.3f}"  # + 0.0: no "-0.000"


def _mm(p_m: np.ndarray) -> str:
    return "(" + ", ".join(f"{round(1e3 * x, 1) + 0.0:.1f}" for x in p_m) + ") mm"


# --- errors ------------------------------------------------------------------------------


def _add_errors(subparsers: argparse._SubParsersAction) -> None:
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
    p.add_argument("--json", type=Path, default=None, help="also write the table as JSON to FILE")
    p.set_defaults(run=_run_errors)


def _run_errors(args: argparse.Namespace) -> int:
    table = error_table(load_mechanism(args.robot), args.pset)
    text = table.to_json()  # rendered before anything is printed or written
    wp = table.worst_point_m * 1e3
    counts = {c: table.classes.count(c) for c in CLASSES}
    print(
        f"parameter set '{table.pset.kind}': {len(table.pset)} parameters — "
        + ", ".join(f"{counts[c]} {c}" for c in CLASSES)
    )
    print(f"worst pose (largest σ[Δλ] with η_c ~ N(0,1) SI): P = ({wp[0]:.1f}, {wp[1]:.1f}, {wp[2]:.1f}) mm")
    for line in overconstraint_lines(table.grid, table.pset.names):
        print(line)
    wc = table.grid.W_condition
    print(f"condition number of the wrench matrix W over the grid: {wc.min():.3g}–{wc.max():.3g}")
    rows = [["parameter", "unit", "class", "sensitivity", "uncompensated"]]
    for p, c, s, su in zip(
        table.pset.parameters, table.classes, table.sensitivity, table.sensitivity_uncompensated, strict=True
    ):
        unit = "µm/µm" if p.unit == "m" else "µm/µrad"
        rows.append([p.name, p.unit, c, f"{s:.4f} {unit}", f"{su:.4f} {unit}"])
    print(text_table(rows))
    if args.json is not None:
        write_atomic(args.json, text.encode())
        print(f"wrote {args.json}")
    return 0


# --- allocate ----------------------------------------------------------------------------


def _add_allocate(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "allocate",
        help="the main job: tolerance table for a required accuracy and reliability",
        description="Error model, sensitive-pose search, FOSM tolerance allocation over the β "
        "series (the paper's Table III), verification by Monte Carlo (linear model and exact "
        "kinematics) and the traditional method for comparison. Prints the tables and writes "
        "allocation.json, allocation.csv and allocation.md (and figures) into --out.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    p.add_argument(
        "--target",
        default=None,
        help="required accuracy Δλ* at P, e.g. 0.05mm or 50um (default: mechanism.toml)",
    )
    p.add_argument(
        "--beta",
        type=float,
        nargs="+",
        default=None,
        help="reliability index of the design (one value) or the whole β series "
        "(several; the design β is then --design-beta or the mechanism's)",
    )
    p.add_argument("--design-beta", type=float, default=None, help="β of the verified design")
    p.add_argument("--set", dest="pset", choices=["dh", "urdf"], default=None, help="parameter set")
    p.add_argument("--samples", type=int, default=10_000, help="Monte Carlo samples (default 10000)")
    p.add_argument(
        "--exact-samples",
        type=int,
        default=1_000,
        help="exact-kinematics verification samples per distribution (default 1000)",
    )
    p.add_argument(
        "--verification-poses",
        type=int,
        default=2_000,
        help="distinct random task-space poses of the verification (default 2000)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--method",
        choices=["fosm", "exact", "cost"],
        default="fosm",
        help="fosm: the paper's Eq. 20 (default); exact: equal-effect shape scaled so "
        "that the exact reliability equals Φ(β); cost: cheapest tolerances with exact "
        "reliability ≥ Φ(β) at every grid pose",
    )
    p.add_argument(
        "--criterion",
        choices=["worst", "every", "average"],
        default="every",
        help="with --method exact: reach Φ(β) at the worst pose, at every grid pose (default) or on average",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default: out/<robot name>)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--view",
        action="store_true",
        help="afterwards, serve the 3D scene in meshcat on 127.0.0.1 until Ctrl-C",
    )
    p.add_argument(
        "--html",
        type=Path,
        default=None,
        help="also write the 3D scene as a self-contained HTML page to FILE",
    )
    p.add_argument("--no-figures", action="store_true", help="do not write the PNG/SVG figures")
    p.set_defaults(run=_run_allocate)


def _run_allocate(args: argparse.Namespace) -> int:
    mech = load_mechanism(args.robot)
    target = None if args.target is None else parse_length(args.target, "--target")
    betas = design_beta = None
    if args.beta is not None and len(args.beta) == 1:
        design_beta = args.beta[0]
    elif args.beta is not None:
        betas = tuple(args.beta)
    if args.design_beta is not None:
        design_beta = args.design_beta
    opts = DesignOptions(
        target_m=target,
        betas=betas,
        design_beta=design_beta,
        parameter_set=args.pset,
        samples=args.samples,
        verification_poses=args.verification_poses,
        exact_samples=args.exact_samples,
        seed=args.seed,
        method=args.method,
        criterion=args.criterion,
        progress=not args.no_progress and sys.stderr.isatty(),
    )
    out = args.out if args.out is not None else Path("out") / mech.name
    check_output_folder(out)
    result = allocate(mech, opts)
    print(summary_text(result), end="")
    print("\nstage times: " + ", ".join(f"{k} {v:.2f} s" for k, v in result.timings_s.items()))
    for path in write_outputs(result, out):
        print(f"wrote {path}")
    if not args.no_figures:
        _write_figures(result, out)
    _view(result, args.html, args.view)
    return 0


def _write_figures(result: DesignResult, out: Path) -> None:
    """Figures next to the tables; without matplotlib, say how to get them and carry on."""
    from pkmtol.present.figures import write_figures

    try:
        for path in write_figures(result, out):
            print(f"wrote {path}")
    except FiguresError as err:
        print(f"pkmtol: warning: no figures: {err}", file=sys.stderr)


def _view(result: DesignResult, html: Path | None, live: bool) -> None:
    from pkmtol.present.viewer.export import export_html, show

    if html is not None:
        info = export_html(result, html)
        spheres = info.scene.spheres
        print(f"wrote {info.path} ({info.bytes} bytes, {spheres.count if spheres else 0} error spheres)")
    if live:
        show(result)


# --- show --------------------------------------------------------------------------------


def _add_show(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "show",
        help="3D scene in meshcat: mechanism at the worst pose, error spheres, verification samples",
        description="Run the error analysis (no exact-kinematics verification) and show the "
        "mechanism at its most error-sensitive pose, an error sphere at every task-space grid "
        "point (radius ∝ σ[Δλ]) and the verification samples, in meshcat on 127.0.0.1. With "
        "--html, write a self-contained page instead and stop.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    p.add_argument("--html", type=Path, default=None, help="write the scene to FILE and exit")
    p.add_argument("--samples", type=int, default=10_000, help="Monte Carlo samples (default 10000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--set", dest="pset", choices=["dh", "urdf"], default=None, help="parameter set")
    p.set_defaults(run=_run_show)


def _run_show(args: argparse.Namespace) -> int:
    mech = load_mechanism(args.robot)
    if args.html is not None:
        check_output_folder(args.html.parent if str(args.html.parent) else Path("."))
    opts = DesignOptions(
        samples=args.samples,
        exact_samples=0,
        seed=args.seed,
        parameter_set=args.pset,
        verification_poses=min(2_000, args.samples),
    )
    result = allocate(mech, opts)
    _view(result, args.html, args.html is None)
    return 0


# --- the parser --------------------------------------------------------------------------

_SUBCOMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_check,
    _add_errors,
    _add_allocate,
    _add_show,
]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pkmtol",
        description="Accuracy design of lower-mobility parallel kinematic machines.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="command")
    for add in _SUBCOMMANDS:
        add(subparsers)
    return parser


if __name__ == "__main__":
    sys.exit(main())
