"""ISO 286-1 IT grades: the table, its size ranges and its formulas, against the published values."""

from __future__ import annotations

import math

import pytest

from pkmtol.design.iso286 import (
    GRADES,
    IT_TABLE_UM,
    SIZE_RANGES_MM,
    it_formula_um,
    it_grade,
    it_tolerance_um,
    size_range,
)
from pkmtol.exceptions import InvalidRequestError

#: (grade, a nominal size inside the range [mm], value [µm]) read from ISO 286-1:2010 Table 1.
PUBLISHED = [
    (6, 2.0, 6), (7, 2.0, 10), (11, 3.0, 60), (8, 5.0, 18), (10, 4.0, 48),
    (5, 8.0, 6), (7, 12.0, 18), (9, 15.0, 43), (6, 25.0, 13), (7, 25.0, 21),
    (8, 25.0, 33), (14, 20.0, 520), (7, 40.0, 25), (11, 65.0, 190), (9, 70.0, 74),
    (7, 100.0, 35), (12, 100.0, 350), (8, 150.0, 63), (9, 200.0, 115), (10, 200.0, 185),
    (7, 250.0, 46), (6, 300.0, 32), (13, 350.0, 890), (5, 450.0, 27), (16, 450.0, 4000),
    (1, 450.0, 8), (4, 300.0, 16), (7, 600.0, 70), (6, 700.0, 50), (17, 700.0, 8000),
    (9, 900.0, 230), (1, 1100.0, 13), (8, 1500.0, 195), (18, 1800.0, 23000), (7, 2200.0, 175),
    (11, 3000.0, 1350), (3, 3150.0, 50), (18, 3150.0, 33000),
]  # fmt: skip


@pytest.mark.parametrize(("grade", "size", "value"), PUBLISHED)
def test_published_values(grade, size, value):
    """ISO 286-1:2010, Table 1 — "Values of standard tolerance grades for nominal sizes up to 3150 mm".

    Cells tested (µm): ≤3 mm IT6 6, IT7 10, IT11 60; 3–6 IT8 18, IT10 48; 6–10 IT5 6; 10–18 IT7 18,
    IT9 43; 18–30 IT6 13, IT7 21, IT8 33, IT14 520; 30–50 IT7 25; 50–80 IT11 190, IT9 74; 80–120 IT7
    35, IT12 350; 120–180 IT8 63; 180–250 IT9 115, IT10 185, IT7 46; 250–315 IT6 32, IT4 16; 315–400
    IT13 890; 400–500 IT5 27, IT16 4000, IT1 8; 500–630 IT7 70; 630–800 IT6 50, IT17 8000; 800–1000
    IT9 230; 1000–1250 IT1 13; 1250–1600 IT8 195; 1600–2000 IT18 23000; 2000–2500 IT7 175; 2500–3150
    IT11 1350, IT3 50, IT18 33000.
    """
    assert it_tolerance_um(grade, size) == value


def test_size_ranges_are_above_and_up_to_and_including():
    """ISO 286-1 size ranges read "above … up to and including": 3 mm is in the first, 3.001 in the next."""
    assert SIZE_RANGES_MM[0] == (0, 3) and SIZE_RANGES_MM[-1] == (2500, 3150) and len(SIZE_RANGES_MM) == 21
    for k, (lo, hi) in enumerate(SIZE_RANGES_MM):
        assert size_range(hi) == k
        assert size_range(lo + 1e-6) == k
        if k:
            assert SIZE_RANGES_MM[k - 1][1] == lo
    assert size_range(1e-3) == 0
    for bad in (0.0, -1.0, 3150.001, math.nan, math.inf):
        with pytest.raises(InvalidRequestError, match="3150"):
            size_range(bad)
    with pytest.raises(InvalidRequestError, match="IT grades"):
        it_tolerance_um(19, 10.0)
    with pytest.raises(InvalidRequestError, match="IT grades"):
        it_tolerance_um(0, 10.0)


def test_table_is_the_formula_rounded():
    """Every value the formulas cover is the formula's within the standard's rounding (≤ 8.4 % of it).

    IT5–IT18 above 3 mm: i = 0.45 ∛D + 0.001 D (D ≤ 500 mm) or I = 0.004 D + 2.1 (above), D the
    geometric mean of the range; IT1–IT4 above 500 mm: 2, 2.7, 3.7, 5 × I. The largest gap is
    3–6 mm IT6 (7.33 → 8 µm). A mistyped cell (20 for 30, 500 for 5000) is off by far more.
    """
    worst = 0.0
    for k, (lo, hi) in enumerate(SIZE_RANGES_MM):
        if lo < 3:
            continue
        for g in GRADES:
            if g < 5 and hi <= 500:
                with pytest.raises(InvalidRequestError):
                    it_formula_um(g, hi)
                continue
            rel = abs(it_formula_um(g, hi) / IT_TABLE_UM[k][g - 1] - 1)
            worst = max(worst, rel)
            assert rel <= 0.085, (lo, hi, g)
    assert worst == pytest.approx(1 - 7.33 / 8, abs=2e-3)  # 3–6 mm IT6, the largest gap


def test_table_grows_with_grade_and_size():
    for row in IT_TABLE_UM:
        assert list(row) == sorted(row) and len(row) == 18
    for g in range(18):
        column = [row[g] for row in IT_TABLE_UM]
        assert column == sorted(column)


def test_grade_of_a_zone():
    # ±0.030 mm on 250 mm: zone 60 µm; IT7 = 46 fits, IT8 = 72 does not
    g = it_grade(60.0, 250.0)
    assert (g.grade, g.it_um, g.size_range_mm, g.label) == (7, 46.0, (180, 250), "IT7")
    assert it_grade(46.0, 250.0).grade == 7  # a zone equal to IT7 is IT7
    assert it_grade(45.9, 250.0).grade == 6
    fine = it_grade(1.0, 250.0)  # below IT1 = 4.5 µm
    assert fine.grade is None and fine.label == "finer than IT1" and fine.it_um == 4.5
    assert it_grade(1e6, 250.0).grade == 18
    with pytest.raises(InvalidRequestError, match="positive"):
        it_grade(0.0, 10.0)
