"""Print a bundled machine's mechanism.toml as derived from its dimensions (D–H tables and homes).

A thin wrapper over :mod:`pkmtol.model.families` (the derivation: :mod:`pkmtol.model.dh_derivation`):
each limb is described at home by the lines of its joint axes in K and the platform frame, turned
into the D–H rows of ``[limbs.dh]`` with every revolute at 0 and every slide at its home length,
and checked to reproduce the platform frame at home. The dimensions are those of docs/robots.md;
the printout is what robots/<machine>/mechanism.toml holds (D–H numbers rounded to 6 decimals,
homes to 5). ``pkmtol new <machine> --<dimension> ... --out <folder>`` writes a checked folder
with other dimensions.

Usage:
    python scripts/derive_dh.py tricept|exechon|sprint_z3|r2rps_ups
"""

from __future__ import annotations

import argparse
import sys

from pkmtol.model.families import FAMILIES, draft
from pkmtol.model.robot_files import command_line, render_toml


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("machine", choices=sorted(FAMILIES))
    args = ap.parse_args(argv)
    robot = draft(args.machine)
    print(render_toml(robot, args.machine, command_line(robot, f"robots/{args.machine}")), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
