"""Units: parsing of user-given lengths and the human-facing unit of each error parameter.

Inside pkmtol everything is SI (m, rad). Tables shown to people state their unit in the header:
lengths in mm or µm, angles in mrad (DESIGN.md, "Units").
"""

from __future__ import annotations

import math
import re
from decimal import Decimal

from pkmtol.exceptions import InvalidRequestError

#: Length units and their power of ten relative to the metre.
LENGTH_UNITS = {"m": 0, "mm": -3, "um": -6, "µm": -6, "μm": -6}

#: Display scale of each SI unit in tables: (factor from SI, display unit).
DISPLAY = {"m": (1e3, "mm"), "rad": (1e3, "mrad")}

_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Zµμ]*)\s*$")


def parse_length(value: str | float | int, what: str = "length") -> float:
    """Parse a length such as ``"0.05 mm"``, ``"50um"`` or ``5e-5`` (bare numbers are metres).

    Returns:
        The length [m].

    Raises:
        InvalidRequestError: the text is not a number with a known length unit.

    >>> parse_length("0.05 mm")
    5e-05
    >>> parse_length("50 um")
    5e-05
    """
    if isinstance(value, bool):
        raise InvalidRequestError(f"{what}: expected a length such as '0.05 mm', got {value!r}")
    if isinstance(value, int | float):
        return float(value)
    m = _NUMBER_UNIT.match(str(value))
    if not m:
        raise InvalidRequestError(f"{what}: cannot read {value!r}; write it as e.g. '0.05 mm' or '50 um'")
    number, unit = m.groups()
    unit = unit or "m"
    if unit not in LENGTH_UNITS:
        raise InvalidRequestError(
            f"{what}: unknown unit {unit!r} in {value!r}; use one of {', '.join(LENGTH_UNITS)}"
        )
    # decimal scaling, so that "50 um" is the double nearest to 5e-5, not 50 × 1e-6
    return float(Decimal(number).scaleb(LENGTH_UNITS[unit]))


def display(value_si: float, unit_si: str) -> float:
    """Convert an SI value of unit ``"m"`` or ``"rad"`` to its display unit (mm, mrad)."""
    return value_si * DISPLAY[unit_si][0]


def display_unit(unit_si: str) -> str:
    """The display unit (``"mm"`` or ``"mrad"``) of an SI unit."""
    return DISPLAY[unit_si][1]


#: Angle units and their factor to the radian.
ANGLE_UNITS = {
    "rad": 1.0,
    "mrad": 1e-3,
    "urad": 1e-6,
    "µrad": 1e-6,
    "μrad": 1e-6,
    "deg": math.pi / 180.0,
    "arcmin": math.pi / 180.0 / 60.0,
    "arcsec": math.pi / 180.0 / 3600.0,
}


def parse_angle(value: str | float | int, what: str = "angle") -> float:
    """Parse an angle such as ``"0.1 mrad"``, ``"20 arcsec"`` or ``"0.5 deg"``; a unit is required.

    Returns:
        The angle [rad].

    Raises:
        InvalidRequestError: not a number with a known angle unit.

    >>> parse_angle("0.5 mrad")
    0.0005
    >>> round(parse_angle("1 deg"), 12)
    0.01745329252
    """
    if isinstance(value, bool) or isinstance(value, int | float):
        raise InvalidRequestError(
            f"{what}: give the angle with its unit, e.g. '0.1 mrad' or '20 arcsec', got {value!r}"
        )
    m = _NUMBER_UNIT.match(str(value))
    if not m or not m.group(2):
        raise InvalidRequestError(
            f"{what}: cannot read {value!r}; write it as e.g. '0.1 mrad' or '20 arcsec'"
        )
    number, unit = m.groups()
    if unit not in ANGLE_UNITS:
        raise InvalidRequestError(
            f"{what}: unknown unit {unit!r} in {value!r}; use one of {', '.join(ANGLE_UNITS)}"
        )
    if unit in ("mrad", "urad", "µrad", "μrad", "rad"):
        exponent = {"rad": 0, "mrad": -3}.get(unit, -6)
        return float(Decimal(number).scaleb(exponent))
    return float(number) * ANGLE_UNITS[unit]
