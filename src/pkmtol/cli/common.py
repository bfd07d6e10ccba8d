"""What every subcommand shares: exit codes, how numbers are printed, and checks of option values."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator, Mapping

import numpy as np

from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError
from pkmtol.units import parse_length

#: Exit code of a pkmtol error (bad input or an impossible request).
EXIT_ERROR = 2
#: Exit code of a check that ran but found problems.
EXIT_PROBLEMS = 1

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
