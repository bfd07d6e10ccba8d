"""What every subcommand shares: exit codes, how numbers are printed, the executor options."""

from __future__ import annotations

import argparse

import numpy as np

from pkmtol.executor import Executor

#: Exit code of a pkmtol error (bad input or an impossible request).
EXIT_ERROR = 2
#: Exit code of a check that ran but found problems.
EXIT_PROBLEMS = 1


def mm(p_m: np.ndarray) -> str:
    """A position [m] as ``(x, y, z) mm`` with one decimal and no ``-0.0``."""
    return "(" + ", ".join(f"{round(1e3 * x, 1) + 0.0:.1f}" for x in p_m) + ") mm"


def add_executor_options(parser: argparse.ArgumentParser) -> None:
    """``--workers N`` and ``--dask ADDRESS``: where the parallel loops run (docs/scale.md)."""
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="local worker processes for the parallel loops (default 1: serial; the numbers do not "
        "depend on it); with --dask local, the number of Dask workers",
    )
    parser.add_argument(
        "--dask",
        default=None,
        metavar="ADDRESS",
        help="run the parallel loops on a Dask scheduler (tcp://host:8786), or 'local' to start a "
        "LocalCluster; needs pip install 'pkmtol[dask]'",
    )


def executor_from(args: argparse.Namespace) -> Executor:
    """The :class:`Executor` of ``--workers``/``--dask``, its Dask scheduler reached already.

    Raises:
        ExecutorError: a bad worker count, or no scheduler at the ``--dask`` address.
    """
    return Executor(workers=args.workers, dask=args.dask).connect()
