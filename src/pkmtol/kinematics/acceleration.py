"""Whether the batched solver runs its compiled kernels: numba installed, and not turned off.

The kernels (:mod:`pkmtol.kinematics.jit_kernels`) come with the optional extra ``pkmtol[fast]``.
They are loaded on the first solve of a process, not at ``import pkmtol``, so commands that solve
nothing do not pay numba's import.
"""

from __future__ import annotations

import importlib
import os
from functools import cache
from types import ModuleType

#: Environment variable that turns the kernels off: ``0``, ``false``, ``no`` or ``off``.
ENVIRONMENT = "PKMTOL_JIT"


@cache
def kernels() -> ModuleType | None:
    """The module of compiled kernels, or None: the numpy path then runs, with the same numbers.

    None when numba is not installed, when :data:`ENVIRONMENT` turns the kernels off, or when
    numba has nowhere to cache them (the package's folder and numba's user cache both read-only;
    set ``NUMBA_CACHE_DIR`` to a writable folder).
    """
    if os.environ.get(ENVIRONMENT, "1").strip().lower() in {"0", "false", "no", "off"}:
        return None
    try:
        return importlib.import_module("pkmtol.kinematics.jit_kernels")
    except ImportError:  # numba is not installed
        return None
    except RuntimeError:  # numba finds no writable cache directory for the compiled code
        return None
