"""The calibration-plan options shared by ``calibrate``, ``allocate`` and ``errors`` (calibrated mode)."""

from __future__ import annotations

import argparse
from pathlib import Path

from pkmtol.calibration.settings import (
    CONTROLLERS,
    INSTRUMENTS,
    SELECTIONS,
    TRACKER_FRAMES,
    CalibrationSettings,
    settings_from_table,
)
from pkmtol.model.mechanism import Mechanism
from pkmtol.units import parse_length


def add_plan_options(p: argparse.ArgumentParser) -> None:
    """Register the plan options: instrument and frame, poses, selection, controller, noise, prior, ranks."""
    g = p.add_argument_group("calibration plan (default: the [calibration] table of mechanism.toml)")
    g.add_argument(
        "--instrument",
        choices=INSTRUMENTS,
        default=None,
        help="measurement model: tracker (P's position, default), tracker-multi (several reflectors), "
        "tracker-6d (position and orientation), ballbar (ISO 230-4 circles), probe (touches on a "
        "sphere artifact); docs/instruments.md",
    )
    g.add_argument(
        "--tracker-frame",
        choices=TRACKER_FRAMES,
        default=None,
        help="registered: the tracker reads in the base frame (default); identify: its transform to "
        "the base is identified with the machine (6 parameters)",
    )
    g.add_argument(
        "--poses",
        type=int,
        default=None,
        help="calibration poses N (default 40; probe 120 touches; ballbar: circles, default 6)",
    )
    g.add_argument("--selection", choices=SELECTIONS, default=None, help="pose selection (default d-optimal)")
    g.add_argument(
        "--controller",
        default=None,
        help="controller model: compensatable (default), full, or comma-separated parameter names",
    )
    g.add_argument(
        "--noise",
        default=None,
        help="instrument noise σ per reading, e.g. 0.01mm (default: tracker 0.01mm, ballbar and probe "
        "0.001mm)",
    )
    g.add_argument("--prior", action="store_true", help="identify with a Gaussian prior (MAP)")
    g.add_argument(
        "--rank-tolerance", type=float, default=None, help="relative pivot tolerance (default 1e-6)"
    )
    g.add_argument(
        "--candidates", type=int, default=None, help="random poses added to the grid pool (default 300)"
    )


def plan_settings(mech: Mechanism, args: argparse.Namespace, seed: int | None = None) -> CalibrationSettings:
    """The ``[calibration]`` table of ``mech``, overridden by the options given."""
    controller: str | tuple[str, ...] | None = None
    if args.controller is not None:
        names = [c.strip() for c in args.controller.split(",") if c.strip()]
        controller = names[0] if len(names) == 1 and names[0] in CONTROLLERS else tuple(names)
    overrides = {
        "instrument": getattr(args, "instrument", None),
        "tracker_frame": getattr(args, "tracker_frame", None),
        "poses": args.poses,
        "selection": args.selection,
        "controller": controller,
        "noise_m": None if args.noise is None else parse_length(args.noise, "--noise"),
        "prior": True if args.prior else None,
        "rank_tolerance": args.rank_tolerance,
        "candidates": args.candidates,
        "seed": seed,
    }
    path = (mech.root / "mechanism.toml") if mech.root is not None else Path("<mechanism>")
    return settings_from_table(dict(mech.extra.get("calibration") or {}), path, **overrides)
