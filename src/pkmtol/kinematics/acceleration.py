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

from pkmtol.exceptions import InvalidArgumentError

#: Environment variable that turns the kernels off (``0``, ``false``, ``no``, ``off``) or leaves
#: them on (unset, empty, ``1``, ``true``, ``yes``, ``on``); any other value is refused.
ENVIRONMENT = "PKMTOL_JIT"
_OFF = frozenset({"0", "false", "no", "off"})
_ON = frozenset({"", "1", "true", "yes", "on"})


@cache
def kernels() -> ModuleType | None:
    """The module of compiled kernels, or None: the numpy path then runs, with the same numbers.

    None when numba is not installed, when :data:`ENVIRONMENT` turns the kernels off, or when
    numba has nowhere to cache them (the package's folder and numba's user cache both read-only;
    set ``NUMBA_CACHE_DIR`` to a writable folder).

    Raises:
        InvalidArgumentError: :data:`ENVIRONMENT` holds a value that is neither on nor off.
    """
    value = os.environ.get(ENVIRONMENT, "")
    if value.strip().lower() in _OFF:
        return None
    if value.strip().lower() not in _ON:
        raise InvalidArgumentError(
            ENVIRONMENT,
            value,
            "set it to 0 (the numpy path) or 1 (the compiled kernels, the default when numba is "
            "installed), or unset it",
        )
    try:
        return importlib.import_module("pkmtol.kinematics.jit_kernels")
    except ImportError:  # numba is not installed
        return None
    except RuntimeError:  # numba finds no writable cache directory for the compiled code
        return None
