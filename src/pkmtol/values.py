"""Checks of user-given values (numbers, counts, choices, vectors), each failing with the argument's name.

Every public entry point validates what it is given with these, so that a wrong value raises
:class:`~pkmtol.exceptions.InvalidArgumentError` naming the argument (``target_m``,
``TaskSpace.radius_m``, ``--samples``) and saying what to write instead, never a ``TypeError``
or ``IndexError`` from deep inside. ``bool`` is never taken for a number.
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from numbers import Integral, Real
from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.exceptions import InvalidArgumentError

#: Largest length a mechanism may hold [m]: beyond it a number is a typo or a wrong unit (and its
#: square overflows nothing yet, so every computation stays finite).
MAX_LENGTH_M = 1e4


def within_length(name: str, value: Any) -> np.ndarray:
    """``value`` (numbers [m]) if every entry is within ±:data:`MAX_LENGTH_M`, else InvalidArgumentError."""
    arr = np.asarray(value, dtype=float)
    if arr.size and float(np.max(np.abs(arr))) > MAX_LENGTH_M:
        raise InvalidArgumentError(
            name, value, f"a length beyond ±{MAX_LENGTH_M:g} m; is the unit right (metres)?"
        )
    return arr


def number(name: str, value: Any, *, positive: bool = False, nonnegative: bool = False) -> float:
    """``value`` as a finite float (``positive``: > 0, ``nonnegative``: ≥ 0).

    >>> number("beta", 2)
    2.0
    """
    if isinstance(value, bool) or not isinstance(value, Real):
        hint = "; give the number itself, in SI units (m, rad)" if isinstance(value, str) else ""
        raise InvalidArgumentError(name, value, f"expected a number{hint}")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidArgumentError(name, value, "expected a finite number")
    if positive and x <= 0:
        raise InvalidArgumentError(name, value, "must be > 0")
    if nonnegative and x < 0:
        raise InvalidArgumentError(name, value, "must be ≥ 0")
    return x


def length_m(name: str, value: Any) -> float:
    """A positive length [m] given as a number (text with a unit goes through ``parse_length``)."""
    if isinstance(value, str):
        raise InvalidArgumentError(
            name,
            value,
            "expected a number of metres; convert text with its unit first, e.g. "
            f"pkmtol.units.parse_length({value!r})",
        )
    x = number(name, value, positive=True)
    if x > MAX_LENGTH_M:
        raise InvalidArgumentError(
            name, value, f"a length beyond {MAX_LENGTH_M:g} m; is the unit right (metres)?"
        )
    return x


def count(name: str, value: Any, low: int = 0, high: int | None = None) -> int:
    """``value`` as an int with ``low ≤ value (≤ high)``; a float or a bool is refused.

    >>> count("samples", 1000, low=2)
    1000
    """
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise InvalidArgumentError(name, value, f"expected a whole number ≥ {low}")
    n = int(value)
    if n < low:
        raise InvalidArgumentError(name, value, f"must be ≥ {low}")
    if high is not None and n > high:
        raise InvalidArgumentError(name, value, f"must be ≤ {high}")
    return n


def flag(name: str, value: Any) -> bool:
    """``value`` as a bool (``True``/``False`` only)."""
    if not isinstance(value, bool | np.bool_):
        raise InvalidArgumentError(name, value, "expected True or False")
    return bool(value)


def text(name: str, value: Any, *, empty: bool = False) -> str:
    """``value`` as a string (non-empty unless ``empty``)."""
    if not isinstance(value, str):
        raise InvalidArgumentError(name, value, "expected a string")
    if not empty and not value.strip():
        raise InvalidArgumentError(name, value, "must not be empty")
    return value


def choice(name: str, value: Any, choices: Iterable[str]) -> str:
    """``value`` if it is one of ``choices``; otherwise an error with the closest one suggested.

    >>> choice("method", "fosm", ("fosm", "exact", "cost"))
    'fosm'
    """
    options = tuple(choices)
    if isinstance(value, str) and value in options:
        return value
    close = difflib.get_close_matches(str(value), options, n=1) if isinstance(value, str) else []
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise InvalidArgumentError(name, value, f"{hint}use one of {', '.join(map(repr, options))}")


def vector(name: str, value: Any, n: int) -> np.ndarray:
    """``value`` as a float array of shape (n,) with finite entries.

    >>> vector("reference_point_m", [0, 0, 0.3], 3).tolist()
    [0.0, 0.0, 0.3]
    """
    arr = array(name, value)
    if arr.shape != (n,):
        raise InvalidArgumentError(name, value, f"expected {n} numbers, got shape {arr.shape}")
    return arr


def array(name: str, value: Any, ndim: int | None = None, finite: bool = True) -> np.ndarray:
    """``value`` as a float array of finite numbers (``ndim`` dimensions if given).

    ``finite=False`` lets nan and inf through (arrays that an iteration may have made).
    """
    if isinstance(value, str | bytes | bool) or value is None or isinstance(value, dict):
        raise InvalidArgumentError(name, value, "expected numbers (a list or an array)")
    if isinstance(value, np.ndarray):
        if value.dtype == bool or not np.issubdtype(value.dtype, np.number):
            raise InvalidArgumentError(name, value, "expected an array of numbers")
    elif isinstance(value, Sequence) and _has_non_number(value):
        raise InvalidArgumentError(name, value, "expected numbers only (rows of equal length)")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InvalidArgumentError(name, value, "expected numbers only (rows of equal length)") from None
    if ndim is not None and arr.ndim != ndim:
        raise InvalidArgumentError(name, value, f"expected {ndim} dimension(s), got shape {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise InvalidArgumentError(name, value, "every entry must be a finite number (no nan or inf)")
    return arr


def _has_non_number(value: Sequence[Any]) -> bool:
    for v in value:
        if isinstance(v, bool | str | bytes) or v is None:
            return True
        if isinstance(v, Sequence) and not isinstance(v, str) and _has_non_number(v):
            return True
    return False


def strings(name: str, value: Any) -> tuple[str, ...]:
    """``value`` as a tuple of strings (a list or tuple of ``str``)."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InvalidArgumentError(name, value, "expected a list of strings")
    bad = [v for v in value if not isinstance(v, str)]
    if bad:
        raise InvalidArgumentError(name, value, f"expected strings only, found {bad[0]!r}")
    return tuple(value)


def path(name: str, value: Any, what: str = "a file path (str or pathlib.Path)") -> Path:
    """``value`` as a :class:`~pathlib.Path` (a ``str`` or path-like); otherwise InvalidArgumentError.

    >>> path("urdf", "robot.urdf")
    PosixPath('robot.urdf')
    """
    if isinstance(value, bool) or not isinstance(value, str | os.PathLike):
        raise InvalidArgumentError(name, value, f"expected {what}")
    out = Path(value)
    if "\x00" in str(out):
        raise InvalidArgumentError(name, value, "a path cannot hold a NUL character")
    return out


def instance(name: str, value: Any, kind: type | tuple[type, ...], what: str) -> Any:
    """``value`` if it is a ``kind``; otherwise InvalidArgumentError saying it should be ``what``.

    >>> instance("rng", 3, int, "a number")
    3
    """
    if not isinstance(value, kind):
        raise InvalidArgumentError(name, value, f"expected {what}")
    return value


def array_of_shape(name: str, value: Any, shape: tuple[int | None, ...], finite: bool = True) -> np.ndarray:
    """``value`` as a finite float array whose shape matches ``shape`` (``None``: any length)."""
    arr = array(name, value, ndim=len(shape), finite=finite)
    if any(s is not None and s != n for s, n in zip(shape, arr.shape, strict=True)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise InvalidArgumentError(name, f"shape {arr.shape}", f"expected an array of shape {want}")
    return arr


def optional(check: Any, name: str, value: Any, *args: Any, **kwargs: Any) -> Any:
    """``None`` if ``value`` is None, else ``check(name, value, *args, **kwargs)``.

    >>> optional(number, "k", None) is None
    True
    """
    return None if value is None else check(name, value, *args, **kwargs)


def generator(name: str, value: Any) -> np.random.Generator:
    """``value`` if it is a :class:`numpy.random.Generator` (``np.random.default_rng(seed)``)."""
    return instance(name, value, np.random.Generator, "a numpy Generator, e.g. np.random.default_rng(0)")


def index(name: str, value: Any, size: int) -> int:
    """``value`` as an index into ``size`` things (``0 ≤ value < size``)."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise InvalidArgumentError(name, value, f"expected a whole number from 0 to {size - 1}")
    if not 0 <= int(value) < size:
        raise InvalidArgumentError(name, value, f"must be from 0 to {size - 1}")
    return int(value)


def joint_values(name: str, value: Any) -> dict[str, float]:
    """``value`` as a mapping of joint names to finite values [rad or m] (``{"limb1_p3": 0.8}``)."""
    if not isinstance(value, Mapping):
        raise InvalidArgumentError(name, value, "expected a mapping of joint names to values")
    out = {}
    for key, v in value.items():
        if not isinstance(key, str):
            raise InvalidArgumentError(name, value, f"expected joint names (strings) as keys, found {key!r}")
        out[key] = number(f"{name}[{key!r}]", v)
    return out


def lengths(name: str, value: Any) -> dict[str, float]:
    """``value`` as a mapping of names to positive lengths [m] (``{"limb1_p3": 0.2}``)."""
    if not isinstance(value, Mapping):
        raise InvalidArgumentError(name, value, "expected a mapping of names to lengths [m], e.g. {'j': 0.1}")
    out = {}
    for key, v in value.items():
        if not isinstance(key, str):
            raise InvalidArgumentError(name, value, f"expected names (strings) as keys, found {key!r}")
        out[key] = length_m(f"{name}[{key!r}]", v)
        within_length(f"{name}[{key!r}]", v)
    return out


def instances(
    name: str, value: Any, kind: type | tuple[type, ...], what: str, size: int | None = None
) -> list[Any]:
    """``value`` as a list of ``kind`` (``size`` of them if given); else InvalidArgumentError."""
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence):
        raise InvalidArgumentError(name, value, f"expected a list of {what}")
    if size is not None and len(value) != size:
        raise InvalidArgumentError(name, f"{len(value)} items", f"expected {size} ({what}), one per limb")
    for k, v in enumerate(value):
        instance(f"{name}[{k}]", v, kind, what)
    return list(value)


def text_or_none(name: str, value: Any) -> str | None:
    """``value`` if it is None or a non-empty string."""
    return optional(text, name, value)


def indices(name: str, value: Any, size: int) -> np.ndarray:
    """``value`` as a 1-D int array of indices into ``size`` things (``0 ≤ i < size``)."""
    arr = array(name, value, ndim=1)
    if np.any(arr != np.round(arr)) or (arr.size and (arr.min() < 0 or arr.max() >= size)):
        raise InvalidArgumentError(name, value, f"expected whole numbers from 0 to {size - 1}")
    return arr.astype(int)


#: Most random samples one call draws (a larger count runs for hours; ask for fewer).
MAX_SAMPLES = 10**9
#: Largest magnitude of a linear map's entry (sensitivities [m/m, m/rad], covariances): beyond it,
#: products of entries overflow and the linear algebra fails.
MAX_MAP_ENTRY = 1e100


def linear_map(name: str, value: Any, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a finite array of ``shape``, at least one row, entries within ±:data:`MAX_MAP_ENTRY`.

    Zero columns are allowed: a design with nothing left to tolerance (every error identified by a
    calibration, or compensated) has maps of no parameter.
    """
    arr = array_of_shape(name, value, shape)
    if arr.ndim == 0 or arr.shape[0] == 0:
        raise InvalidArgumentError(name, f"shape {arr.shape}", "must hold at least one pose (row)")
    if arr.size == 0:
        return arr
    if float(np.max(np.abs(arr))) > MAX_MAP_ENTRY:
        raise InvalidArgumentError(
            name,
            f"max |entry| {float(np.max(np.abs(arr))):.3g}",
            f"entries beyond ±{MAX_MAP_ENTRY:g}; are the units SI?",
        )
    return arr


def points(name: str, value: Any) -> np.ndarray:
    """``value`` as at least one point in K, shape (n, 3) [m], within ±:data:`MAX_LENGTH_M`."""
    arr = within_length(name, array_of_shape(name, value, (None, 3)))
    if not len(arr):
        raise InvalidArgumentError(name, "shape (0, 3)", "expected at least one point")
    return arr
