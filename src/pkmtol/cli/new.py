"""``pkmtol new <family>``: a checked robot folder (mechanism.toml and limb URDFs) from a few dimensions."""

from __future__ import annotations

import argparse
from pathlib import Path

from pkmtol.cli.common import show_progress
from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError
from pkmtol.kinematics.robot_folder import new_robot
from pkmtol.model.families import FAMILIES, SUMMARY
from pkmtol.model.robot_files import length_text as shown
from pkmtol.units import parse_length


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol new`` and one sub-command per family with its dimensions."""
    p = subparsers.add_parser(
        "new",
        help="write a checked robot folder of a bundled family (tricept, sprint_z3, exechon, r2rps_ups, "
        "the hybrids r2rps_ups_wrist, tricept_wrist) "
        "from a few dimensions",
        description="Write robots/<name>/mechanism.toml and its limb URDFs for one of the bundled "
        "families with the dimensions given (the others keep the bundled robot's values; with no "
        "option the bundled robot is reproduced exactly). The D–H tables are derived from the "
        "joint axes, the URDFs generated from them, and the folder is only written if it loads "
        "and passes `pkmtol check` (mobility, every task-space point reachable within the limits). "
        "Every dimension is a length with its unit, as elsewhere in pkmtol (550mm, 0.55m, 550000um); "
        "a bare number is refused.",
    )
    families = p.add_subparsers(dest="family", required=True, metavar="family")
    for family, (_, dims) in FAMILIES.items():
        doc = SUMMARY[family]
        f = families.add_parser(
            family,
            help=doc,
            description=f"{doc}. Dimensions not given keep the bundled robots/{family} values.",
        )
        for d in dims:
            option = "--" + d.name.replace("_", "-")
            what = d.help.replace(" [m]", "")
            if isinstance(d.default, tuple):
                f.add_argument(
                    option,
                    nargs=2,
                    metavar=("MIN", "MAX"),
                    default=None,
                    help=f"{what}, lengths with their unit (default {' '.join(map(shown, d.default))})",
                )
            else:
                f.add_argument(
                    option,
                    metavar="LENGTH",
                    default=None,
                    help=f"{what}, a length with its unit (default {shown(d.default)})",
                )
        f.add_argument(
            "--out", type=Path, required=True, help="the new robot folder (must not exist, or be empty)"
        )
        f.add_argument("--name", default=None, help="mechanism name (default: the folder's name)")
        f.add_argument("--no-progress", action="store_true", help="no progress bar while checking")
        f.set_defaults(run=_run)


def _length(option: str, shown_as: str, text: str) -> float:
    """A dimension [m] from its text with a unit (``550mm``, ``0.55m``); a bare number is refused."""
    try:
        return parse_length(text, option)
    except InvalidRequestError as err:
        raise InvalidArgumentError(option, shown_as, str(err).removeprefix(f"{option}: ")) from err


def _run(args: argparse.Namespace) -> int:
    _, dims = FAMILIES[args.family]
    given: dict[str, float | tuple[float, ...]] = {}
    for d in dims:
        text = getattr(args, d.name)
        if text is None:
            continue
        option = "--" + d.name.replace("_", "-")
        if isinstance(text, list):
            given[d.name] = tuple(_length(option, " ".join(text), t) for t in text)
        else:
            given[d.name] = _length(option, text, text)
    robot = new_robot(args.family, args.out, args.name, show_progress(args.no_progress), **given)
    for path in robot.files:
        print(f"wrote {path}")
    rep = robot.report
    print(
        f"check: mobility {rep.mobility} with {rep.mechanism.n_actuators} actuators, constraint wrenches "
        + ", ".join(f"{lb.name} {lb.constraint_count}" for lb in rep.limbs)
        + f"; {rep.n_reachable}/{len(rep.points)} task-space points reachable: OK"
    )
    print(f"made by: {robot.command}")
    return 0
