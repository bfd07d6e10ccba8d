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
#: The table unit systems (``--units``): ``mm`` (mm and mrad, the default) or ``um`` (µm, µrad).
DISPLAY_UNITS = {"mm": DISPLAY, "um": {"m": (1e6, "µm"), "rad": (1e6, "µrad")}}

_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Zµμ]*)\s*$")


def parse_length(value: str | float | int, what: str = "length") -> float:
    """Parse a length such as ``"0.05 mm"``, ``"50um"`` or ``"5e-5 m"``; a number is metres.

    Text must carry its unit: ``"50"`` is refused (it could mean 50 m or 50 µm).

    Returns:
        The length [m].

    Raises:
        InvalidRequestError: the text is not a number with a known length unit, or not finite.

    >>> parse_length("0.05 mm")
    5e-05
    >>> parse_length("50 um")
    5e-05
    """
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise InvalidRequestError(f"{what}: expected a length such as '0.05 mm', got {value!r}")
    if isinstance(value, int | float):
        if not math.isfinite(value):
            raise InvalidRequestError(f"{what}: expected a finite length, got {value!r}")
        return float(value)
    m = _NUMBER_UNIT.match(str(value))
    if not m:
        raise InvalidRequestError(f"{what}: cannot read {value!r}; write it as e.g. '0.05 mm' or '50 um'")
    number, unit = m.groups()
    if not unit:
        raise InvalidRequestError(
            f"{what}: {value!r} has no unit; write it with one, e.g. '{number} um' or '{number} mm' "
            f"(units: {', '.join(LENGTH_UNITS)})"
        )
    if unit not in LENGTH_UNITS:
        raise InvalidRequestError(
            f"{what}: unknown unit {unit!r} in {value!r}; use one of {', '.join(LENGTH_UNITS)}"
        )
    # decimal scaling, so that "50 um" is the double nearest to 5e-5, not 50 × 1e-6
    try:
        result = float(Decimal(number).scaleb(LENGTH_UNITS[unit]))
    except ArithmeticError:
        result = math.inf
    if not math.isfinite(result):
        raise InvalidRequestError(f"{what}: {value!r} is too large to be a length")
    return result


def display(value_si: float, unit_si: str, units: str = "mm") -> float:
    """Convert an SI value of unit ``"m"`` or ``"rad"`` to its display unit (``units``: mm or um).

    >>> display(5e-5, "m"), display(5e-5, "m", "um")
    (0.05, 50.0)
    """
    return value_si * _system(units)[unit_si][0]


def display_unit(unit_si: str, units: str = "mm") -> str:
    """The display unit (``"mm"``/``"mrad"``, or ``"µm"``/``"µrad"``) of an SI unit."""
    return _system(units)[unit_si][1]


def _system(units: str) -> dict[str, tuple[float, str]]:
    if units not in DISPLAY_UNITS:
        raise InvalidRequestError(f"units: unknown table units {units!r}; use {' or '.join(DISPLAY_UNITS)}")
    return DISPLAY_UNITS[units]


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
