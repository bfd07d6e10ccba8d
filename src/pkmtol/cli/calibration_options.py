"""The calibration-plan options shared by ``calibrate``, ``allocate`` and ``errors`` (calibrated mode)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from pkmtol.calibration.settings import (
    ARTIFACTS,
    CONTROLLERS,
    INSTRUMENTS,
    SELECTIONS,
    TRACKER_FRAMES,
    CalibrationSettings,
    settings_from_table,
)
from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError
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
        "sphere or plane artifact); docs/instruments.md",
    )
    g.add_argument(
        "--artifact",
        choices=ARTIFACTS,
        default=None,
        help="the probe's artifact: sphere (spheres at [calibration] stations_m, default) or plane "
        "(the flat faces of a block, [calibration] artifact_faces)",
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


#: The option of each settings field, for messages that name what the user typed.
OPTION_OF_SETTING = {
    "instrument": "--instrument",
    "tracker_frame": "--tracker-frame",
    "artifact": "--artifact",
    "poses": "--poses",
    "selection": "--selection",
    "controller": "--controller",
    "noise_m": "--noise",
    "prior": "--prior",
    "rank_tolerance": "--rank-tolerance",
    "candidates": "--candidates",
    "seed": "--seed",
}
#: The largest instrument noise σ a command line may give [m] (a tracker reads to µm, not metres).
LARGEST_NOISE_M = 1.0


def plan_settings(mech: Mechanism, args: argparse.Namespace, seed: int | None = None) -> CalibrationSettings:
    """The ``[calibration]`` table of ``mech``, overridden by the options given.

    Raises:
        MechanismFormatError: the table of mechanism.toml is wrong (its key named).
        InvalidArgumentError: an option's value is wrong (the option named, not the table).
    """
    for option, value, low in (("--poses", args.poses, 1), ("--candidates", args.candidates, 0)):
        if value is not None and value < low:
            raise InvalidArgumentError(option, value, f"give an integer ≥ {low}")
    controller: str | tuple[str, ...] | None = None
    if args.controller is not None:
        names = [c.strip() for c in args.controller.split(",") if c.strip()]
        controller = names[0] if len(names) == 1 and names[0] in CONTROLLERS else tuple(names)
    overrides = {
        "instrument": getattr(args, "instrument", None),
        "tracker_frame": getattr(args, "tracker_frame", None),
        "artifact": getattr(args, "artifact", None),
        "poses": args.poses,
        "selection": args.selection,
        "controller": controller,
        "noise_m": None if args.noise is None else _noise(args.noise),
        "prior": True if args.prior else None,
        "rank_tolerance": args.rank_tolerance,
        "candidates": args.candidates,
        "seed": seed,
    }
    path = (mech.root / "mechanism.toml") if mech.root is not None else Path("<mechanism>")
    table = dict(mech.extra.get("calibration") or {})
    base = settings_from_table(table, path)  # the table alone: its own errors name its keys
    for key, value in overrides.items():
        if value is None:
            continue
        try:
            dataclasses.replace(base, **{key: value})
        except InvalidRequestError as err:
            typed = getattr(args, "noise", value) if key == "noise_m" else value
            shown = ",".join(typed) if isinstance(typed, tuple) else typed
            raise InvalidArgumentError(OPTION_OF_SETTING[key], shown, str(err)) from err
    return settings_from_table(table, path, **overrides)


#: The plan options (argparse destinations) and how they are typed.
PLAN_OPTIONS = {
    "instrument": "--instrument",
    "tracker_frame": "--tracker-frame",
    "artifact": "--artifact",
    "poses": "--poses",
    "selection": "--selection",
    "controller": "--controller",
    "noise": "--noise",
    "prior": "--prior",
    "rank_tolerance": "--rank-tolerance",
    "candidates": "--candidates",
}


def calibrated_settings(
    mech: Mechanism, args: argparse.Namespace, seed: int | None = None
) -> CalibrationSettings | None:
    """``allocate`` / ``errors``: the plan settings with ``--compensation calibrated``, else None.

    Raises:
        InvalidArgumentError: a plan option given without ``--compensation calibrated`` (it would be
            ignored), or a bad option value (:func:`plan_settings`).
    """
    if args.compensation == "calibrated":
        return plan_settings(mech, args, seed)
    for dest, option in PLAN_OPTIONS.items():
        value = getattr(args, dest, None)
        if value is not None and value is not False:
            raise InvalidArgumentError(
                option,
                value,
                f"a calibration-plan option; it is read only with --compensation calibrated (this run "
                f"is --compensation {args.compensation}): add that, or leave {option} out",
            )
    return None


def _noise(text: str) -> float:
    """``--noise``: a length with its unit, ≥ 0 and at most :data:`LARGEST_NOISE_M`."""
    try:
        value = parse_length(text, "--noise")
    except InvalidRequestError as err:
        raise InvalidArgumentError("--noise", text, str(err).removeprefix("--noise: ")) from err
    if not 0 <= value <= LARGEST_NOISE_M:
        raise InvalidArgumentError(
            "--noise", text, "an instrument's noise σ must be between 0 and 1 m, e.g. 0.01mm"
        )
    return value
