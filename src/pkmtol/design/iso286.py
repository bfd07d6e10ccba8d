"""ISO 286-1 standard tolerance grades IT1–IT18: the published table, its formulas, the grade of a zone.

A standard tolerance IT is the **width** of a tolerance zone (upper minus lower limit) for a
nominal size in one of the standard's size ranges (``above`` … ``up to and including``).
:data:`IT_TABLE_UM` holds ISO 286-1:2010 Table 1 (µm) for nominal sizes up to 3150 mm; grades
are read from it, since the table, not the formula, is normative.

The formulas it was derived from (ISO 286-1, Annex A), with ``D`` the geometric mean of the size
range's limits in mm (``√(1·3)`` for the first range):

* ``D ≤ 500 mm``: the standard tolerance factor ``i = 0.45 ∛D + 0.001 D`` µm; IT5 … IT18 are
  ``7, 10, 16, 25, 40, 64, 100, 160, 250, 400, 640, 1000, 1600, 2500`` × i;
* ``500 < D ≤ 3150 mm``: ``I = 0.004 D + 2.1`` µm; IT1 … IT4 are ``2, 2.7, 3.7, 5`` × I and IT5 …
  IT18 the same multiples of I as above.

The table's values are the formula's rounded by the standard's rules: within 8.4 % of the table
value for IT5 … IT18 above 3 mm and IT1 … IT4 above 500 mm (tested). The first range (≤ 3 mm) and
IT1 … IT4 up to 500 mm were fixed by the standard outside these formulas: table only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pkmtol.exceptions import InvalidRequestError

#: Size ranges (mm): ``(above, up to and including)``; the first is "up to 3 mm".
SIZE_RANGES_MM = (
    (0, 3),
    (3, 6),
    (6, 10),
    (10, 18),
    (18, 30),
    (30, 50),
    (50, 80),
    (80, 120),
    (120, 180),
    (180, 250),
    (250, 315),
    (315, 400),
    (400, 500),
    (500, 630),
    (630, 800),
    (800, 1000),
    (1000, 1250),
    (1250, 1600),
    (1600, 2000),
    (2000, 2500),
    (2500, 3150),
)
#: Grades of :data:`IT_TABLE_UM`'s columns.
GRADES = tuple(range(1, 19))

# fmt: off
#: ISO 286-1:2010 Table 1: standard tolerance values [µm], one row per size range, IT1 … IT18.
IT_TABLE_UM = (
    (0.8, 1.2, 2, 3, 4, 6, 10, 14, 25, 40, 60, 100, 140, 250, 400, 600, 1000, 1400),
    (1, 1.5, 2.5, 4, 5, 8, 12, 18, 30, 48, 75, 120, 180, 300, 480, 750, 1200, 1800),
    (1, 1.5, 2.5, 4, 6, 9, 15, 22, 36, 58, 90, 150, 220, 360, 580, 900, 1500, 2200),
    (1.2, 2, 3, 5, 8, 11, 18, 27, 43, 70, 110, 180, 270, 430, 700, 1100, 1800, 2700),
    (1.5, 2.5, 4, 6, 9, 13, 21, 33, 52, 84, 130, 210, 330, 520, 840, 1300, 2100, 3300),
    (1.5, 2.5, 4, 7, 11, 16, 25, 39, 62, 100, 160, 250, 390, 620, 1000, 1600, 2500, 3900),
    (2, 3, 5, 8, 13, 19, 30, 46, 74, 120, 190, 300, 460, 740, 1200, 1900, 3000, 4600),
    (2.5, 4, 6, 10, 15, 22, 35, 54, 87, 140, 220, 350, 540, 870, 1400, 2200, 3500, 5400),
    (3.5, 5, 8, 12, 18, 25, 40, 63, 100, 160, 250, 400, 630, 1000, 1600, 2500, 4000, 6300),
    (4.5, 7, 10, 14, 20, 29, 46, 72, 115, 185, 290, 460, 720, 1150, 1850, 2900, 4600, 7200),
    (6, 8, 12, 16, 23, 32, 52, 81, 130, 210, 320, 520, 810, 1300, 2100, 3200, 5200, 8100),
    (7, 9, 13, 18, 25, 36, 57, 89, 140, 230, 360, 570, 890, 1400, 2300, 3600, 5700, 8900),
    (8, 10, 15, 20, 27, 40, 63, 97, 155, 250, 400, 630, 970, 1550, 2500, 4000, 6300, 9700),
    (9, 11, 16, 22, 32, 44, 70, 110, 175, 280, 440, 700, 1100, 1750, 2800, 4400, 7000, 11000),
    (10, 13, 18, 25, 36, 50, 80, 125, 200, 320, 500, 800, 1250, 2000, 3200, 5000, 8000, 12500),
    (11, 15, 21, 28, 40, 56, 90, 140, 230, 360, 560, 900, 1400, 2300, 3600, 5600, 9000, 14000),
    (13, 18, 24, 33, 47, 66, 105, 165, 260, 420, 660, 1050, 1650, 2600, 4200, 6600, 10500, 16500),
    (15, 21, 29, 39, 55, 78, 125, 195, 310, 500, 780, 1250, 1950, 3100, 5000, 7800, 12500, 19500),
    (18, 25, 35, 46, 65, 92, 150, 230, 370, 600, 920, 1500, 2300, 3700, 6000, 9200, 15000, 23000),
    (22, 30, 41, 55, 78, 110, 175, 280, 440, 700, 1100, 1750, 2800, 4400, 7000, 11000, 17500, 28000),
    (26, 36, 50, 68, 96, 135, 210, 330, 540, 860, 1350, 2100, 3300, 5400, 8600, 13500, 21000, 33000),
)
# fmt: on

#: Multiples of the tolerance factor (i or I) for IT5 … IT18.
MULTIPLIERS = dict(
    zip(range(5, 19), (7, 10, 16, 25, 40, 64, 100, 160, 250, 400, 640, 1000, 1600, 2500), strict=True)
)
#: Multiples of I for IT1 … IT4 above 500 mm.
MULTIPLIERS_ABOVE_500 = {1: 2.0, 2: 2.7, 3: 3.7, 4: 5.0}
#: Largest nominal size of the standard [mm].
MAX_SIZE_MM = 3150.0


def size_range(nominal_mm: float) -> int:
    """Index into :data:`SIZE_RANGES_MM` of a nominal size (> 0 and ≤ 3150 mm).

    Raises:
        InvalidRequestError: the size is not positive or beyond 3150 mm.

    >>> SIZE_RANGES_MM[size_range(30.0)], SIZE_RANGES_MM[size_range(30.001)]
    ((18, 30), (30, 50))
    """
    if not (math.isfinite(nominal_mm) and 0.0 < nominal_mm <= MAX_SIZE_MM):
        raise InvalidRequestError(
            f"ISO 286-1 grades nominal sizes above 0 up to {MAX_SIZE_MM:g} mm, got {nominal_mm!r} mm"
        )
    for k, (_, hi) in enumerate(SIZE_RANGES_MM):
        if nominal_mm <= hi:
            return k
    raise AssertionError  # unreachable: the last range ends at MAX_SIZE_MM


def it_tolerance_um(grade: int, nominal_mm: float) -> float:
    """The standard tolerance ITgrade for a nominal size [µm], from :data:`IT_TABLE_UM`.

    >>> it_tolerance_um(7, 100.0)
    35.0
    """
    if grade not in GRADES:
        raise InvalidRequestError(f"IT grades are {GRADES[0]}–{GRADES[-1]}, got {grade!r}")
    return float(IT_TABLE_UM[size_range(nominal_mm)][grade - 1])


def it_formula_um(grade: int, nominal_mm: float) -> float:
    """The formula value of ITgrade [µm] (unrounded) at the geometric mean of the size's range.

    Defined for IT5 … IT18 up to 500 mm and IT1 … IT18 above (the module docstring).

    Raises:
        InvalidRequestError: a grade the formulas do not cover at that size.
    """
    lo, hi = SIZE_RANGES_MM[size_range(nominal_mm)]
    d = math.sqrt(max(lo, 1) * hi)
    if d <= 500:
        if grade not in MULTIPLIERS:
            raise InvalidRequestError(f"the ISO 286 formulas give IT5–IT18 up to 500 mm, not IT{grade}")
        return MULTIPLIERS[grade] * (0.45 * d ** (1.0 / 3.0) + 0.001 * d)
    factor = MULTIPLIERS_ABOVE_500.get(grade, MULTIPLIERS.get(grade))
    if factor is None:
        raise InvalidRequestError(f"IT grades are {GRADES[0]}–{GRADES[-1]}, got {grade!r}")
    return factor * (0.004 * d + 2.1)


@dataclass(frozen=True)
class ItGrade:
    """The ISO 286-1 grade a tolerance zone meets for a nominal size.

    Attributes:
        grade: The coarsest grade whose IT fits in the zone (1–18), or None when the zone is
            narrower than IT1.
        it_um: That grade's IT [µm] (IT1's when ``grade`` is None).
        zone_um: The zone width 2t [µm].
        nominal_mm: The nominal size [mm].
        size_range_mm: Its range ``(above, up to and including)`` [mm].
    """

    grade: int | None
    it_um: float
    zone_um: float
    nominal_mm: float
    size_range_mm: tuple[int, int]

    @property
    def label(self) -> str:
        """``IT7``, ``finer than IT1`` or ``IT18 (coarser allowed)``."""
        if self.grade is None:
            return "finer than IT1"
        return f"IT{self.grade}"


def it_grade(zone_um: float, nominal_mm: float) -> ItGrade:
    """The coarsest ISO 286-1 grade whose standard tolerance fits in a zone of width ``zone_um``.

    A part made to that grade (IT ≤ zone) meets the tolerance; the next coarser one does not.

    Args:
        zone_um: Width of the tolerance zone, 2t for ±t [µm].
        nominal_mm: Nominal size [mm], in (0, 3150].

    >>> it_grade(60.0, 250.0).label   # ±0.030 mm on 250 mm: IT7 = 46 µm fits, IT8 = 72 µm does not
    'IT7'
    """
    if not (math.isfinite(zone_um) and zone_um > 0):
        raise InvalidRequestError(f"a tolerance zone must be positive, got {zone_um!r} µm")
    k = size_range(nominal_mm)
    row = IT_TABLE_UM[k]
    fits = [g for g, it in zip(GRADES, row, strict=True) if it <= zone_um]
    grade = fits[-1] if fits else None
    return ItGrade(
        grade=grade,
        it_um=float(row[(grade or 1) - 1]),
        zone_um=float(zone_um),
        nominal_mm=float(nominal_mm),
        size_range_mm=SIZE_RANGES_MM[k],
    )
