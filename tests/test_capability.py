"""Process capability of Δλ = ‖x‖, x ~ N(0, Σ): Cpk, the exact PPM, sigma level, quantiles; percent shares."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from pkmtol.design.capability import capability, exact_quantile
from pkmtol.design.contributions import contributions
from pkmtol.design.reliability import exact_distribution, exact_reliability
from pkmtol.exceptions import InvalidRequestError


def _covs():
    rng = np.random.default_rng(7)
    out = [np.eye(3) * 1e-10, np.diag([4e-10, 1e-10, 0.0]), np.diag([9e-10, 0.0, 0.0])]
    for _ in range(3):
        a = rng.standard_normal((3, 5)) * 1e-5
        out.append(a @ a.T)
    return np.array(out)


def test_cpk_ppm_and_sigma_level_against_monte_carlo():
    covs = _covs()
    target = 5e-5
    cap = capability(covs, target, reliability_target=0.95)
    rng = np.random.default_rng(11)
    n = 400_000
    for k, c in enumerate(covs):
        lam, vec = np.linalg.eigh(c)
        x = rng.standard_normal((n, 3)) * np.sqrt(np.clip(lam, 0, None)) @ vec.T
        d = np.linalg.norm(x, axis=1)
        # μ and σ of the norm (closed form) against the sample
        assert cap.mean[k] == pytest.approx(d.mean(), rel=5e-3)
        assert cap.std[k] == pytest.approx(d.std(), rel=5e-3)
        assert cap.cpk[k] == pytest.approx((target - cap.mean[k]) / (3 * cap.std[k]))
        p = float(np.mean(d > target))
        se = math.sqrt(max(p * (1 - p), 1e-12) / n)
        assert cap.ppm[k] / 1e6 == pytest.approx(p, abs=4 * se + 1e-6)
        assert cap.ppm[k] == pytest.approx(1e6 * (1 - exact_reliability(c, target)[0]), abs=1e-3)
        assert cap.ppm_normal[k] == pytest.approx(1e6 * stats.norm.sf(3 * cap.cpk[k]))
        if cap.ppm[k] > 1e-3:
            assert cap.sigma_level[k] == pytest.approx(stats.norm.isf(cap.ppm[k] / 1e6))
        assert float(np.mean(d <= cap.quantile[k])) == pytest.approx(0.95, abs=4 * math.sqrt(0.05 * 0.95 / n))
    # a norm is not normal: the normal-theory PPM of Cpk is not the true one
    assert not np.allclose(cap.ppm, cap.ppm_normal, rtol=0.1)
    assert cap.worst_cpk_index == int(np.argmin(cap.cpk)) and cap.worst_ppm_index == int(np.argmax(cap.ppm))


def test_exact_distribution_and_quantile():
    c = _covs()[4]
    F = exact_distribution(c)
    for q in (1e-6, 2e-5, 5e-5, 1e-4):
        assert F(q) == pytest.approx(exact_reliability(c, q)[0], abs=1e-12)
    assert F(0.0) == 0.0 and F(-1.0) == 0.0
    for r in (0.1, 0.5, 0.9772, 0.999):
        q = exact_quantile(c, r)
        assert F(q) == pytest.approx(r, abs=1e-9)
    # isotropic unit covariance: ‖x‖ is χ₃
    assert exact_quantile(np.eye(3), 0.5) == pytest.approx(stats.chi.ppf(0.5, 3), rel=1e-8)
    assert exact_quantile(np.zeros((3, 3)), 0.5) == 0.0
    assert exact_distribution(np.zeros((3, 3)))(1e-9) == 1.0
    with pytest.raises(InvalidRequestError, match="probability"):
        exact_quantile(np.eye(3), 1.0)


def test_density_is_the_derivative_of_the_distribution():
    for c in _covs():
        F = exact_distribution(c)
        scale = math.sqrt(max(np.linalg.eigvalsh(c).max(), 1e-30))
        for q in scale * np.array([0.05, 0.5, 1.0, 2.0, 4.0]):
            h = 1e-5 * q
            fd = (F(q + h) - F(q - h)) / (2 * h)
            assert F.density(q) == pytest.approx(fd, rel=1e-6, abs=1e-9 / scale)
    assert exact_distribution(np.zeros((3, 3))).density(1e-9) == 0.0


def test_quantile_is_brents_root():
    # the quantile by safeguarded Newton agrees with scipy's brentq at the tolerance it was given
    from scipy import optimize, special

    for c in _covs():
        F = exact_distribution(c)
        lam_max = float(np.linalg.eigvalsh(c).max())
        for r in (0.05, 0.5, 0.9772, 0.999999):
            hi = math.sqrt(lam_max) * math.sqrt(2.0 * float(special.gammaincinv(1.5, r))) * (1 + 1e-9)
            ref = optimize.brentq(lambda q, F=F, r=r: F(q) - r, 0.0, hi, xtol=1e-12 * hi, rtol=1e-10)
            assert exact_quantile(c, r) == pytest.approx(ref, rel=3e-10)


def test_capability_refuses_bad_input():
    with pytest.raises(InvalidRequestError, match="shape"):
        capability(np.eye(3), 1.0)
    with pytest.raises(InvalidRequestError, match="positive"):
        capability(_covs(), 0.0)
    with pytest.raises(InvalidRequestError, match="probability"):
        capability(_covs(), 1.0, reliability_target=1.5)
    zero = capability(np.zeros((1, 3, 3)), 1e-5)
    assert zero.cpk[0] == math.inf and zero.ppm[0] == 0.0 and not zero.resolved[0]


def test_shares_split_the_mean_square_exactly():
    """E‖L δ + N ν‖² = Σ ω_i² σ_i² + σ_m² ‖N‖²_F: the shares sum to 1 and match a sample."""
    rng = np.random.default_rng(2)
    m, n, M = 5, 6, 4
    L, N = rng.standard_normal((m, 3, n)) * 1e-2, rng.standard_normal((m, 3, M)) * 0.3
    sigma = np.array([1e-3, 2e-3, 5e-4, 0.0, np.inf, 1e-3])  # a free (inf) error counts as 0
    cols = np.array([0, 1, 2, 3, 4, 5])
    c = contributions(L, sigma, cols, 2, N, 1e-5)
    np.testing.assert_allclose(c.shares.sum(axis=1) + c.noise_share, 1.0, rtol=1e-12)
    s = np.where(np.isfinite(sigma), sigma, 0.0)
    x = rng.standard_normal((200_000, n)) * s
    nu = rng.standard_normal((200_000, M)) * 1e-5
    e = x @ L[2].T + nu @ N[2].T
    assert c.mean_square[2] == pytest.approx(np.mean(np.sum(e**2, axis=1)), rel=1e-2)
    expected = (np.linalg.norm(L[2], axis=0) * s) ** 2 / c.mean_square[2]
    np.testing.assert_allclose(c.at_design, expected, rtol=1e-12)
    assert c.at_design[3] == 0.0 and c.at_design[4] == 0.0
    assert np.all(c.worst >= c.at_design) and np.all(c.worst == c.shares.max(axis=0))
    np.testing.assert_array_equal(c.worst_pose, c.shares.argmax(axis=0))
    order = c.order()
    assert list(c.at_design[order]) == sorted(c.at_design, reverse=True)
    no_noise = contributions(L, sigma, cols, 0)
    assert not no_noise.noise_share.any() and no_noise.noise_at_design == 0.0
    with pytest.raises(InvalidRequestError, match="outside"):
        contributions(L, sigma, cols, 9)
    with pytest.raises(InvalidRequestError, match="shape"):
        contributions(L, sigma[:3], cols, 0)
