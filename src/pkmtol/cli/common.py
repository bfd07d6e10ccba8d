"""What every subcommand shares: exit codes and how numbers are printed."""

from __future__ import annotations

import numpy as np

#: Exit code of a pkmtol error (bad input or an impossible request).
EXIT_ERROR = 2
#: Exit code of a check that ran but found problems.
EXIT_PROBLEMS = 1


def mm(p_m: np.ndarray) -> str:
    """A position [m] as ``(x, y, z) mm`` with one decimal and no ``-0.0``."""
    return "(" + ", ".join(f"{round(1e3 * x, 1) + 0.0:.1f}" for x in p_m) + ") mm"
