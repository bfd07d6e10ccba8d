"""``pkmtol check``: load and validate a mechanism; mobility, constraints, task-space reachability."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from pkmtol.cli.common import EXIT_PROBLEMS, add_tool_options, apply_tool_options, mm, show_progress
from pkmtol.kinematics.check import CheckReport, JointReport, check_mechanism
from pkmtol.model.loader import load_mechanism
from pkmtol.model.taskspace import TaskSpace

#: Unreachable points listed one by one; the rest are counted.
MAX_LISTED = 10


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol check`` and its options."""
    p = subparsers.add_parser(
        "check",
        help="load and validate a mechanism; mobility, constraints, task-space reachability",
        description="Load robots/<robot>/mechanism.toml and its limb URDFs, then print the limbs "
        "and joints, the mobility, the constraint wrenches per limb, and inverse kinematics over "
        "the task-space grid (reachability, joint ranges, worst conditioning). Exit code 1 if a "
        "point is unreachable or the mobility differs from the number of actuators.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml (e.g. robots/r2rps_ups)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_tool_options(p)
    p.set_defaults(run=_run)


def _run(args: argparse.Namespace) -> int:
    report = check_mechanism(
        apply_tool_options(load_mechanism(args.robot), args), progress=show_progress(args.no_progress)
    )
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
        f"reference point P in the platform frame {mm(mech.reference_point_m)}"
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
    if report.tool is not None:  # a hybrid: the tool chain on the platform
        t, tool = report.tool, mech.tool
        assert tool is not None
        actuated = [j.name for j in t.joints if j.actuated]
        locked = [j.name for j in t.joints if not j.actuated]
        source = t.urdf_path.name if t.urdf_path is not None else "(pin.Model)"
        out.append(
            f"  tool chain  {source}  actuated: {', '.join(actuated) or 'none'}  locked: "
            f"{', '.join(locked) or 'none'}  TCP {1e3 * tool.length_m:.1f} mm beyond '{tool.nose_name}'"
        )
        width = max(len("joint"), *(len(j.name) for j in t.joints))
        out.append(
            f"    {'joint':<{width}}  type  unit  {'lower':>9}  {'upper':>9}  "
            f"{'range min':>9}  {'range max':>9}"
        )
        for j in t.joints:
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
    if report.actuation:  # nothing was solved: the actuators do not determine the pose
        out.append("task space: not solved (the actuation is wrong, see below)")
        out.append("")
        out.append("result: " + "; ".join(report.problems))
        return out
    out.append(f"task space: {_describe_task_space(report)}")
    out.append(f"reachable: {report.n_reachable}/{len(report.points)} points")
    for p in report.unreachable[:MAX_LISTED]:
        out.append(f"  - {p.error}")
    if len(report.unreachable) > MAX_LISTED:
        out.append(f"  ... and {len(report.unreachable) - MAX_LISTED} more unreachable points")
    n_passive = report.n_joints - mech.n_actuators
    rows = [
        (
            "inverse",
            f"inverse kinematics (closure + task rows, {report.n_joints} joints)"
            if mech.tool is None
            else f"inverse kinematics (the TCP task: {3 + len(mech.tool.actuated)} rows, P and the wrist)",
        ),
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
                f"worst at {'P' if mech.tool is None else 'TCP'} = {mm(worst.target_m)}"
            )
    out.append("")
    out.append("result: " + ("; ".join(report.problems) if report.problems else "OK"))
    return out


def _describe_task_space(report: CheckReport) -> str:
    ts = report.mechanism.task_space
    n = len(report.points)
    cone = report.mechanism.tool_directions
    if cone is not None:  # a hybrid: the TCP points x the tool axes
        axes = len(cone.grid())
        return (
            f"TCP points x {axes} tool axes within {np.degrees(cone.half_angle_rad):.1f} deg of "
            f"{np.round(cone.axis, 4).tolist()} = {n} targets; TCP points: " + _describe_points(ts, n // axes)
        )
    return _describe_points(ts, n)


def _describe_points(ts: TaskSpace, n: int) -> str:
    if ts.kind == "cylinder":
        per_layer = " + ".join(str(k) for k in (1, *ts.rings))
        z0, z1 = (f"{round(1e3 * z, 1) + 0.0:.1f}" for z in ts.z_range_m)
        return (
            f"cylinder radius {1e3 * ts.radius_m:.1f} mm about {mm(np.array(ts.center_xy_m))}, "
            f"z {z0} to {z1} mm, {ts.layers} layers x ({per_layer}) = {n} points"
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
