"""The ``pkmtol`` command: one subcommand per job, each a thin layer over a library function.

``pkmtol check robots/<robot>`` loads and validates a mechanism and prints its structure, mobility,
constraints and task-space reachability (:mod:`pkmtol.kinematics.check`). Every pkmtol error is printed as
``pkmtol: error: <message>`` on stderr with exit code 2; a check that finds problems exits 1.

To add a subcommand, write a module ``pkmtol/cli/<name>.py`` with ``add(subparsers)`` that
registers its arguments and sets ``run=`` to a function ``(args) -> int``, and list it in
:data:`SUBCOMMANDS`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from pkmtol import __version__
from pkmtol.cli import allocate, calibrate, check, errors, show
from pkmtol.cli.common import EXIT_ERROR
from pkmtol.exceptions import PkmtolError

#: The subcommands in the order ``pkmtol --help`` lists them.
SUBCOMMANDS = (check, errors, allocate, calibrate, show)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``pkmtol`` command line.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit code: 0 on success, 1 if a check found problems, 2 on a pkmtol error.

    """
    args = _parser().parse_args(argv)
    args.argv = ["pkmtol", *(sys.argv[1:] if argv is None else argv)]  # the report's provenance
    try:
        return int(args.run(args))
    except PkmtolError as err:
        print(f"pkmtol: error: {err}", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:  # output piped into `head` and closed early
        sys.stderr.close()
        return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pkmtol",
        description="Accuracy design of lower-mobility parallel kinematic machines.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="command")
    for command in SUBCOMMANDS:
        command.add(subparsers)
    return parser
