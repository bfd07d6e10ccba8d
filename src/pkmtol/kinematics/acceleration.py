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
    """The module of compiled kernels, or None (numba not installed, or :data:`ENVIRONMENT` off)."""
    if os.environ.get(ENVIRONMENT, "1").strip().lower() in {"0", "false", "no", "off"}:
        return None
    try:
        return importlib.import_module("pkmtol.kinematics.jit_kernels")
    except ImportError:
        return None
