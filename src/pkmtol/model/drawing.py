"""How tolerances go on a drawing: the ±t convention, nominal sizes and feature lengths (``[drawing]``).

A design gives each error a standard deviation σ_i; a drawing gives a tolerance ±t_i. The
convention that links them must be stated:

``normal`` (default)
    ±t = k·σ with k = 3: a Gaussian process of standard deviation σ keeps 99.73 % of its parts
    inside ±t;
``uniform``
    ±t = √3·σ: a process spread uniformly over ±t has standard deviation σ (the tightest ±t that
    does not promise more than the design assumed for any distribution filling the zone).

The optional ``[drawing]`` table of ``mechanism.toml`` (all keys optional; lengths with a unit)::

    [drawing]
    convention = "normal"        # or "uniform"
    k = 3                        # the k of ±t = k·σ (normal only)
    feature_length = "100 mm"    # default L of an axis-orientation zone (zone = L·tan δ)
    [drawing.feature_lengths]    # L per joint (the joint whose axis the error tilts)
    limb4_u1 = "80 mm"
    [drawing.nominals]           # nominal size per length parameter (default: the D–H a/d value
    "δd_{2,4}" = "250 mm"        # or the URDF origin's offset along the error)

L defaults to 100 mm, a typical length of a bearing seat or shaft journal carrying a joint axis.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError, MechanismFormatError
from pkmtol.units import parse_length

CONVENTIONS = ("normal", "uniform")
#: Keys of the ``[drawing]`` table.
TABLE_KEYS = ("convention", "k", "feature_length", "feature_lengths", "nominals")
DEFAULT_K = 3.0
#: Largest k of ±t = k·σ (a Gaussian process leaves 1.5e-23 of its parts outside ±10σ already).
MAX_K = 100.0
#: Default feature length L of an axis-orientation zone [m].
DEFAULT_FEATURE_LENGTH_M = 0.1


@dataclass(frozen=True)
class DrawingSettings:
    """The drawing convention and the sizes it needs.

    Attributes:
        convention: ``normal`` (±t = k·σ) or ``uniform`` (±t = √3·σ).
        k: The k of the normal convention (> 0).
        feature_length_m: Default feature length L of an axis-orientation zone [m].
        feature_lengths_m: L per joint name [m] (the joint whose axis an angle error tilts, or a
            limb's platform attachment).
        nominals_m: Nominal size per length parameter name [m] (overrides the geometry's value).
    """

    convention: str = "normal"
    k: float = DEFAULT_K
    feature_length_m: float = DEFAULT_FEATURE_LENGTH_M
    feature_lengths_m: Mapping[str, float] = field(default_factory=dict)
    nominals_m: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise InvalidRequestError(
                f"unknown drawing convention {self.convention!r}; use {' or '.join(CONVENTIONS)}"
            )
        k = values.number("DrawingSettings.k", self.k)
        if not 0 < k <= MAX_K:
            raise InvalidArgumentError(
                "DrawingSettings.k", self.k, f"the k of ±t = k·σ must be a positive number ≤ {MAX_K:g}"
            )
        values.length_m("DrawingSettings.feature_length_m", self.feature_length_m)
        values.within_length("DrawingSettings.feature_length_m", self.feature_length_m)
        values.lengths("DrawingSettings.feature_lengths_m", self.feature_lengths_m)
        values.instance(
            "DrawingSettings.nominals_m", self.nominals_m, Mapping, "a mapping of names to sizes [m]"
        )
        for name, value in self.nominals_m.items():
            values.text("DrawingSettings.nominals_m", name)
            values.within_length(f"DrawingSettings.nominals_m[{name!r}]", value)
            values.number(f"DrawingSettings.nominals_m[{name!r}]", value, nonnegative=True)

    @property
    def factor(self) -> float:
        """t/σ: k (normal) or √3 (uniform)."""
        return self.k if self.convention == "normal" else math.sqrt(3.0)

    @property
    def short_label(self) -> str:
        """``±t = 3σ`` or ``±t = √3σ``."""
        return "±t = √3σ" if self.convention == "uniform" else f"±t = {self.k:g}σ"

    @property
    def label(self) -> str:
        """The convention in words, for every table that shows ±t."""
        if self.convention == "uniform":
            return "±t = √3·σ (uniform: a process spread evenly over ±t has standard deviation σ)"
        inside = 100.0 * math.erf(self.k / math.sqrt(2.0))
        return f"±t = {self.k:g}·σ (normal: a Gaussian process keeps {inside:.4g} % of its parts inside ±t)"

    def feature_length(self, joint: str) -> float:
        """L for the axis of ``joint`` [m] (its own entry, else the default)."""
        values.text("joint", joint)
        return float(self.feature_lengths_m.get(joint, self.feature_length_m))

    def with_convention(self, convention: str | None = None, k: float | None = None) -> DrawingSettings:
        """The same settings with the convention and/or k replaced (None: keep)."""
        values.optional(values.choice, "convention", convention, CONVENTIONS)
        values.optional(values.number, "k", k, positive=True)
        return replace(
            self,
            convention=self.convention if convention is None else convention,
            k=self.k if k is None else k,
        )


def read_drawing(table: Mapping[str, Any], path: Path | str, joints: Iterable[str]) -> DrawingSettings:
    """The ``[drawing]`` table of ``mechanism.toml`` as :class:`DrawingSettings`.

    Args:
        table: The parsed table (empty: the defaults).
        path: The file, for messages.
        joints: Names ``[drawing.feature_lengths]`` may use (joints and platform attachments).

    Raises:
        MechanismFormatError: an unknown key (with the closest known one), a wrong type, a length
            without a unit, or a joint that no limb has.
    """
    known = sorted(set(joints))
    for key in table:
        if key not in TABLE_KEYS:
            raise MechanismFormatError(path, f"drawing.{key}", "unknown key" + _hint(key, TABLE_KEYS))
    kw: dict[str, Any] = {}
    if "convention" in table:
        if not isinstance(table["convention"], str):
            raise MechanismFormatError(
                path, "drawing.convention", f"expected 'normal' or 'uniform', got {table['convention']!r}"
            )
        kw["convention"] = table["convention"]
    if "k" in table:
        k = table["k"]
        if isinstance(k, bool) or not isinstance(k, int | float):
            raise MechanismFormatError(path, "drawing.k", f"expected a number such as 3, got {k!r}")
        kw["k"] = float(k)
    if "feature_length" in table:
        kw["feature_length_m"] = _length(table["feature_length"], path, "drawing.feature_length")
    lengths = {}
    for joint, value in _subtable(table, "feature_lengths", path).items():
        if joint not in known:
            raise MechanismFormatError(
                path, f"drawing.feature_lengths.{joint}", "no limb has this joint" + _hint(joint, known)
            )
        lengths[joint] = _length(value, path, f"drawing.feature_lengths.{joint}")
    nominals = {
        name: _length(value, path, f'drawing.nominals."{name}"')
        for name, value in _subtable(table, "nominals", path).items()
    }
    try:
        return DrawingSettings(**kw, feature_lengths_m=lengths, nominals_m=nominals)
    except InvalidRequestError as err:
        raise MechanismFormatError(path, "drawing", str(err)) from err


def _subtable(table: Mapping[str, Any], key: str, path: Path | str) -> Mapping[str, Any]:
    sub = table.get(key, {})
    if not isinstance(sub, Mapping):
        raise MechanismFormatError(path, f"drawing.{key}", f"expected a table [drawing.{key}], got {sub!r}")
    return sub


def _length(value: Any, path: Path | str, key: str) -> float:
    if not isinstance(value, str):
        raise MechanismFormatError(path, key, f'write the unit with the number, e.g. "{value} mm"')
    try:
        return parse_length(value, key)
    except InvalidRequestError as err:
        raise MechanismFormatError(path, key, str(err)) from err


def _hint(key: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(key, list(choices), n=1)
    return f"; did you mean '{close[0]}'?" if close else f"; known: {', '.join(choices)}"
