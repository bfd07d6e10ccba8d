"""Worst case of ‖L η‖ over a tolerance box: exact by zonotope vertices, checked by brute force, bounds."""

from __future__ import annotations

import numpy as np
import pytest

from pkmtol.design.stackup import (
    MAX_BRUTE_FORCE,
    stack_up,
    worst_case_norm,
    worst_case_norm_vertices,
)
from pkmtol.exceptions import InvalidRequestError


def _cases():
    """Random maps, and the degenerate structures real mechanisms have (seeded)."""
    rng = np.random.default_rng(16)
    for trial in range(240):
        n = int(rng.integers(1, 15))
        L = rng.standard_normal((3, n))
        kind = trial % 8
        if kind == 1:
            L[2] = 0.0  # rank 2: every generator in one plane (the tilt of an axis)
        elif kind == 2 and n > 2:
            L[:, 1] = -2.5 * L[:, 0]  # antiparallel columns
            L[:, 2] = 0.5 * L[:, 0]
        elif kind == 3 and n > 3:
            L[:, 2] = 0.3 * L[:, 0] + 0.7 * L[:, 1]  # three and four columns in one plane
            L[:, 3] = L[:, 0] - L[:, 1]
        elif kind == 4:
            L[:, : n // 2] = 0.0  # errors with no effect
        elif kind == 5:
            L[1:] = 0.0  # rank 1
        elif kind == 6:
            L = np.round(L)  # integer columns: many exact coplanarities and ties
        elif kind == 7 and n > 1:
            L = L[:2]  # a 2-D map
        yield L, rng.uniform(0.1, 2.0, n) * (rng.random(n) > 0.1)


@pytest.mark.parametrize("case", list(_cases()), ids=lambda c: f"n{c[0].shape[1]}")
def test_zonotope_enumeration_equals_brute_force(case):
    L, t = case
    exact = worst_case_norm(L, t)
    brute = worst_case_norm_vertices(L, t)
    assert exact.value == pytest.approx(brute.value, rel=1e-12, abs=1e-14)
    # the returned vertex reaches it, and is a vertex of the box
    assert set(np.unique(exact.signs)) <= {-1.0, 1.0}
    assert np.linalg.norm(L @ (exact.signs * t)) == pytest.approx(exact.value, rel=1e-12, abs=1e-14)
    # far fewer candidates than 2ⁿ once n is not tiny
    n = t.size
    assert exact.candidates <= 2 * (n * (n - 1) * 2 + 2) + 2


def test_bounds_rss_below_worst_case_below_arithmetic():
    rng = np.random.default_rng(3)
    for _ in range(200):
        n = int(rng.integers(1, 30))
        L, t = rng.standard_normal((3, n)), rng.uniform(0.0, 1.0, n)
        wc = worst_case_norm(L, t).value
        g = np.linalg.norm(L, axis=0) * t
        rss, arith = float(np.sqrt(np.sum(g**2))), float(g.sum())
        assert rss <= wc * (1 + 1e-12) + 1e-15
        assert wc <= arith * (1 + 1e-12) + 1e-15
        assert wc <= np.linalg.norm(np.abs(L) @ t) * (1 + 1e-12) + 1e-15


def test_beyond_brute_force_it_stays_exact_against_the_support_function():
    """n = 60: max over the box = max over unit u of Σ t_i |L_iᵀu|; dense directions bound it from below."""
    rng = np.random.default_rng(60)
    L, t = rng.standard_normal((3, 60)), rng.uniform(0.1, 1.0, 60)
    wc = worst_case_norm(L, t)
    u = rng.standard_normal((200_000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    sampled = float(np.max(np.abs(u @ L) @ t))
    assert sampled <= wc.value * (1 + 1e-12)
    assert wc.value - sampled < 2e-4 * wc.value  # the sampled directions come within 0.02 %
    # no single sign flip of the returned vertex increases the norm (a local maximum of the box)
    base = L @ (wc.signs * t)
    flips = base[:, None] - 2 * L * (wc.signs * t)[None, :]
    assert np.all(np.linalg.norm(flips, axis=0) <= wc.value * (1 + 1e-12))
    with pytest.raises(InvalidRequestError, match="n ≤ 20"):
        worst_case_norm_vertices(L, t)
    assert MAX_BRUTE_FORCE == 20


def test_zero_and_bad_input():
    assert worst_case_norm(np.zeros((3, 4)), np.ones(4)).value == 0.0
    assert worst_case_norm(np.ones((3, 2)), np.zeros(2)).value == 0.0
    with pytest.raises(InvalidRequestError, match="shape"):
        worst_case_norm(np.ones((4, 2)), np.ones(2))
    with pytest.raises(InvalidRequestError, match="shape"):
        worst_case_norm(np.ones((3, 2)), np.ones(3))
    with pytest.raises(InvalidRequestError, match="≥ 0"):
        worst_case_norm(np.ones((3, 2)), np.array([1.0, -1.0]))
    with pytest.raises(InvalidRequestError, match="finite"):
        worst_case_norm(np.array([[np.nan], [0.0], [0.0]]), np.ones(1))
    with pytest.raises(InvalidRequestError, match="shape"):
        stack_up(np.ones((3, 2)), np.ones(2))


def test_stack_up_over_poses():
    rng = np.random.default_rng(5)
    L, t = rng.standard_normal((7, 3, 9)), rng.uniform(0.1, 1.0, 9)
    st = stack_up(L, t)
    for k in range(7):
        assert st.worst_case_m[k] == pytest.approx(worst_case_norm_vertices(L[k], t).value, rel=1e-12)
        g = np.linalg.norm(L[k], axis=0) * t
        assert st.arithmetic_m[k] == pytest.approx(g.sum())
        assert st.rss_m[k] == pytest.approx(np.sqrt(np.sum(g**2)))
        assert np.linalg.norm(L[k] @ (st.worst_signs[k] * t)) == pytest.approx(st.worst_case_m[k])
