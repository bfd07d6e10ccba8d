"""``pkmtol show``: the 3D scene in meshcat on 127.0.0.1, or written as a self-contained page."""

from __future__ import annotations

import argparse
from pathlib import Path

from pkmtol.cli.allocate import scene_options, view
from pkmtol.cli.common import add_tool_options, apply_tool_options, named_as_options, show_progress
from pkmtol.design.budget import check_memory
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.exceptions import OutputError
from pkmtol.model.loader import load_mechanism


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol show`` and its options."""
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
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--ellipsoids",
        action="store_true",
        help="the 1σ ellipsoid of P's error at every grid point instead of a sphere",
    )
    add_tool_options(p)
    p.set_defaults(run=_run)


def _run(args: argparse.Namespace) -> int:
    mech = apply_tool_options(load_mechanism(args.robot), args)
    if args.html is not None and not (args.html.parent or Path(".")).is_dir():
        raise OutputError(args.html, f"folder {args.html.parent} does not exist")
    with named_as_options():
        opts = DesignOptions(
            samples=args.samples,
            exact_samples=0,
            seed=args.seed,
            parameter_set=args.pset,
            verification_poses=max(1, min(2_000, args.samples)),
            progress=show_progress(args.no_progress),
        )
        check_memory(mech, opts)
    result = allocate(mech, opts)
    view(result, args.html, args.html is None, scene_options(args.ellipsoids))
    return 0
