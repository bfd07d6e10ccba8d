"""The ``pkmtol`` command: one subcommand per job, each a thin layer over a library function.

``pkmtol check robots/<robot>`` loads and validates a mechanism and prints its structure, mobility,
constraints and task-space reachability (:mod:`pkmtol.kinematics.check`). Every pkmtol error is printed as
``pkmtol: error: <message>`` on stderr with exit code 2 (running out of memory too); a check that
finds problems exits 1. Warnings (:class:`~pkmtol.exceptions.PkmtolWarning`, e.g. a missing mesh)
are printed as ``pkmtol: warning: <message>``.

To add a subcommand, write a module ``pkmtol/cli/<name>.py`` with ``add(subparsers)`` that
registers its arguments and sets ``run=`` to a function ``(args) -> int``, and list it in
:data:`SUBCOMMANDS`.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import signal
import sys
import warnings
from collections.abc import Iterator, Sequence
from typing import TextIO


def _interrupted_while_starting(signum: int, frame: object) -> None:
    """Ctrl-C or SIGTERM before :func:`main` runs (while the subcommands import): one line, no file."""
    os.write(2, b"pkmtol: interrupted; nothing was written\n")
    os._exit(128 + signum)


# Started as the command (`pkmtol`, `python -m pkmtol.cli`): a signal during the imports below
# (seconds on a cold start) gets the same one line as one during a run, not Python's traceback or
# a silent death. Imported by another program, the signals are left alone.
if sys.argv and (sys.argv[0] == "-m" or os.path.basename(sys.argv[0]) == "pkmtol"):
    signal.signal(signal.SIGINT, _interrupted_while_starting)
    signal.signal(signal.SIGTERM, _interrupted_while_starting)

from pkmtol import __version__, executor, files  # noqa: E402
from pkmtol.cli import allocate, calibrate, check, errors, new, show, sweep  # noqa: E402
from pkmtol.cli.common import EXIT_ERROR, Interrupted, signals_as_interrupts  # noqa: E402
from pkmtol.exceptions import PkmtolError, PkmtolWarning  # noqa: E402
from pkmtol.present.terminal import FittedStream  # noqa: E402

#: The subcommands in the order ``pkmtol --help`` lists them.
SUBCOMMANDS = (check, errors, allocate, calibrate, show, sweep, new)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``pkmtol`` command line.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit code: 0 on success, 1 if a check found problems, 2 on a pkmtol error.

    """
    written = files.commits()
    with warnings.catch_warnings(), signals_as_interrupts(), _fitted_stdout():
        warnings.simplefilter("always", PkmtolWarning)
        warnings.showwarning = _show_warning
        try:
            return run(argv)
        except KeyboardInterrupt as err:  # Ctrl-C, or SIGTERM (Interrupted)
            executor.abort()
            signum = err.signum if isinstance(err, Interrupted) else int(signal.SIGINT)
            done = files.commits() - written
            print(
                "pkmtol: interrupted; nothing was written"
                if done == 0
                else f"pkmtol: interrupted after its files were written whole ({done} write(s))",
                file=sys.stderr,
            )
            return 128 + signum
        except RecursionError:
            executor.abort()
            print("pkmtol: error: an input is nested too deeply to read; simplify it", file=sys.stderr)
            return EXIT_ERROR
        except PkmtolError as err:
            executor.abort()  # a run's pool is stopped on every error
            print(f"pkmtol: error: {err}", file=sys.stderr)
            return EXIT_ERROR
        except MemoryError:
            executor.abort()
            print(
                "pkmtol: error: out of memory; ask for fewer --samples or --verification-poses, "
                "or a coarser task-space grid",
                file=sys.stderr,
            )
            return EXIT_ERROR
        except BrokenPipeError:  # output piped into `head` and closed early
            sys.stderr.close()
            return 0


@contextlib.contextmanager
def _fitted_stdout() -> Iterator[None]:
    """Print through :class:`~pkmtol.present.terminal.FittedStream`: tables and lines fit the terminal."""
    stdout = sys.stdout
    sys.stdout = FittedStream(stdout)  # type: ignore[assignment]
    try:
        yield
    finally:
        try:
            sys.stdout.flush()
        finally:
            sys.stdout = stdout


def run(argv: Sequence[str] | None = None) -> int:
    """Run the command line like :func:`main`, but let a :class:`~pkmtol.exceptions.PkmtolError` propagate.

    For callers (and tests) that want the exception itself rather than its printed message.
    """
    args = _parser().parse_args(argv)
    args.argv = ["pkmtol", *(sys.argv[1:] if argv is None else argv)]  # the report's provenance
    return int(args.run(args))


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """Show pkmtol's warnings as one line each, ``pkmtol: warning: <message>``, on stderr; others as usual."""
    if not issubclass(category, PkmtolWarning):
        _SHOW_WARNING(message, category, filename, lineno, file, line)
        return
    print(f"pkmtol: warning: {message}", file=sys.stderr if file is None else file)


_SHOW_WARNING = warnings.showwarning


@functools.lru_cache(maxsize=1)  # built once a process: main() may run many times (notebooks, tests)
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
