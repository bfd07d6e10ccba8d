"""What every subcommand shares: exit codes, number formats, checks of option values, the executor."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import signal
import sys
import threading
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError
from pkmtol.executor import Executor
from pkmtol.units import parse_angle, parse_length

#: Exit code of a pkmtol error (bad input or an impossible request).
EXIT_ERROR = 2
#: Exit code of a check that ran but found problems.
EXIT_PROBLEMS = 1


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM: the run stops; :func:`pkmtol.cli.main` prints one line and exits 128 + signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def signals_as_interrupts() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`Interrupted` in the main thread (restored afterwards).

    Off the main thread (a caller's worker thread) signals cannot be handled: nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    fired: list[int] = []

    def interrupt(signum: int, frame: object) -> None:
        if fired:  # a second Ctrl-C while the first one is being handled: already stopping
            return
        fired.append(signum)
        raise Interrupted(signum)

    old = {sig: signal.signal(sig, interrupt) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


#: Option of each DesignOptions field, for messages that name what the user typed.
OPTION_OF_FIELD = {
    "target_m": "--target",
    "betas": "--beta",
    "design_beta": "--design-beta",
    "parameter_set": "--set",
    "samples": "--samples",
    "verification_poses": "--verification-poses",
    "exact_samples": "--exact-samples",
    "seed": "--seed",
    "method": "--method",
    "criterion": "--criterion",
    "claim_poses": "--claim-poses",
}


def mm(p_m: np.ndarray) -> str:
    """A position [m] as ``(x, y, z) mm`` with one decimal and no ``-0.0``."""
    return "(" + ", ".join(f"{round(1e3 * x, 1) + 0.0:.1f}" for x in p_m) + ") mm"


@contextlib.contextmanager
def named_as_options(names: Mapping[str, str] = OPTION_OF_FIELD) -> Iterator[None]:
    """Re-raise an InvalidArgumentError about an option field as one about its command-line option."""
    try:
        yield
    except InvalidArgumentError as err:
        if err.argument in names:
            raise err.renamed(names[err.argument]) from err
        raise


def target_option(text: str | None) -> float | None:
    """``--target`` [m]: a positive length with its unit (``0.05mm``, ``50um``); None if not given."""
    if text is None:
        return None
    try:
        value = parse_length(text, "--target")
    except InvalidRequestError as err:
        raise InvalidArgumentError("--target", text, str(err).removeprefix("--target: ")) from err
    if value <= 0:
        raise InvalidArgumentError(
            "--target", text, "the required accuracy Δλ* must be positive, e.g. 0.05mm"
        )
    return value


def show_progress(no_progress: bool) -> bool:
    """Progress bars on stderr: when it is a terminal and ``--no-progress`` is not given."""
    return not no_progress and sys.stderr.isatty()


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


def add_tool_options(parser: argparse.ArgumentParser) -> None:
    """``--tool-length`` and ``--compensate-with``: a hybrid's tool and compensation (docs/hybrid.md)."""
    parser.add_argument(
        "--tool-length",
        default=None,
        metavar="LENGTH",
        help="a hybrid machine: the tool length, spindle nose → TCP, with its unit (150mm); default "
        "[tool] length",
    )
    parser.add_argument(
        "--lock-wrist",
        default=None,
        metavar="JOINT=ANGLE,...",
        help="a hybrid machine: lock every wrist joint at the given value for 3-axis work, e.g. "
        "wrist_c=90deg,wrist_a=45deg (the task is then the TCP position; the tool axis follows)",
    )
    parser.add_argument(
        "--compensate-with",
        choices=["machine", "module"],
        default=None,
        help="a hybrid machine: which actuators compensate — machine: the module's and the wrist's "
        "together (default), module: the module's alone, the wrist's commands unchanged (the paper's "
        "Eq. 25 carried to the TCP)",
    )


def apply_tool_options(mechanism: Any, args: argparse.Namespace) -> Any:
    """The mechanism with ``--tool-length`` and ``--compensate-with`` applied (unchanged without them).

    Raises:
        InvalidArgumentError: a bad length, or a tool option on a mechanism without a [tool] chain.
    """
    length = getattr(args, "tool_length", None)
    scope = getattr(args, "compensate_with", None)
    lock = getattr(args, "lock_wrist", None)
    if length is None and scope is None and lock is None:
        return mechanism
    if mechanism.tool is None:
        given = (("--tool-length", length), ("--compensate-with", scope), ("--lock-wrist", lock))
        option, value = next((o, v) for o, v in given if v is not None)
        raise InvalidArgumentError(
            option, value, f"'{mechanism.name}' has no tool chain; add a [tool] table (docs/hybrid.md)"
        )
    tool = mechanism.tool
    directions = mechanism.tool_directions
    if lock is not None:
        tool, directions = _locked(tool, lock), None
    if length is not None:
        try:
            value = parse_length(length, "--tool-length")
        except InvalidRequestError as err:
            raise InvalidArgumentError(
                "--tool-length", length, str(err).removeprefix("--tool-length: ")
            ) from err
        if value < 0:
            raise InvalidArgumentError("--tool-length", length, "a tool length must be ≥ 0, e.g. 150mm")
        tool = tool.with_length(value)
    extra = dict(mechanism.extra)
    if scope is not None:
        extra["tool_scope"] = scope
    return dataclasses.replace(mechanism, tool=tool, tool_directions=directions, extra=extra)


def _locked(tool: Any, text: str) -> Any:
    """``--lock-wrist``: the tool chain with every joint of ``joint=value,...`` locked (all of them)."""
    locked: dict[str, float] = {}
    kinds = dict(zip(tool.joint_names, tool.joint_kinds, strict=True))
    for item in (x.strip() for x in text.split(",") if x.strip()):
        name, sep, value = (part.strip() for part in item.partition("="))
        if not sep or name not in kinds:
            raise InvalidArgumentError(
                "--lock-wrist",
                text,
                f"write JOINT=VALUE,... with the joints {', '.join(kinds)}, e.g. wrist_a=45deg",
            )
        parse = parse_angle if kinds[name] == "R" else parse_length
        try:
            locked[name] = parse(value, "--lock-wrist")
        except InvalidRequestError as err:
            raise InvalidArgumentError("--lock-wrist", text, str(err).removeprefix("--lock-wrist: ")) from err
    missing = [n for n in kinds if n not in locked]
    if missing:
        raise InvalidArgumentError(
            "--lock-wrist", text, f"lock every wrist joint for 3-axis work; missing {', '.join(missing)}"
        )
    return tool.with_locked(locked)
