"""Exact reliability, exact-R designs and cost-optimal designs (beyond FOSM)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from pkmtol.design.cost import cost_model, cost_optimal
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.design.reliability import exact_reliability, exact_reliability_imhof
from pkmtol.design.verification import verify
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import InvalidRequestError
from pkmtol.model.loader import load_mechanism

SEED = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"
TARGET = 5e-5

J_ISOTROPIC = np.eye(3)
J_ONE_DIRECTION = np.array([[1.0, 0.3, 0.0, 0.2], [0.0, 0.05, 0.01, 0.0], [0.0, 0.0, 0.02, 0.01]])


def _fosm_sigma(J: np.ndarray, beta: float) -> np.ndarray:
    omega = np.linalg.norm(J, axis=0)
    return TARGET / (math.sqrt(J.shape[1]) * omega * beta)


@pytest.mark.parametrize("J", [J_ISOTROPIC, J_ONE_DIRECTION], ids=["isotropic", "one-direction"])
@pytest.mark.parametrize("beta", [1.0, 2.0, 3.0])
def test_exact_reliability_against_million_samples(J, beta):
    sigma = _fosm_sigma(J, beta)
    a = J * sigma
    r, _ = exact_reliability(a @ a.T, TARGET)
    rng = np.random.default_rng(int(beta * 10) + J.shape[1])
    n = 1_000_000
    dl = np.linalg.norm(rng.standard_normal((n, J.shape[1])) * sigma @ J.T, axis=1)
    p = float(np.mean(dl <= TARGET))
    se = math.sqrt(p * (1 - p) / n)
    assert abs(r - p) <= 3 * se
    # and it is not FOSM's Φ(β) (which the isotropic case misses by far at β = 1)
    if J is J_ISOTROPIC and beta == 1.0:
        assert abs(r - stats.norm.cdf(beta)) > 0.1


@pytest.mark.parametrize(
    "lam", [[1, 1, 1], [1, 1e-2, 1e-4], [1, 1e-8, 0], [1, 0.5, 0.2], [1, 0, 0], [1, 1, 1e-3]]
)
@pytest.mark.parametrize("t", [1e-5, 2e-5, 3e-5, 4e-5, 5e-5])
def test_exact_reliability_matches_imhof(lam, t):
    """Two independent exact methods agree to 1e-9 (incl. the far tail, R → 1 − 1e-6)."""
    lam = np.array(lam, float) * 1e-10
    r, _ = exact_reliability(np.diag(lam), t)
    assert abs(r - exact_reliability_imhof(lam, t)) < 1e-9


def test_exact_reliability_gradient_finite_differences():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 3))
    cov = a @ a.T * 1e-10
    _, g = exact_reliability(cov, 2e-5, gradient=True)
    h = 1e-16
    for i, j in [(0, 0), (0, 1), (1, 2), (2, 2)]:
        e = np.zeros((3, 3))
        e[i, j] += h
        if i != j:
            e[j, i] += h
        fd = (exact_reliability(cov + e, 2e-5)[0] - exact_reliability(cov - e, 2e-5)[0]) / (2 * h)
        assert math.isclose(fd, g[i, j] * (2 if i != j else 1), rel_tol=1e-5)


@pytest.fixture(scope="module")
def mech():
    return load_mechanism(SEED)


@pytest.fixture(scope="module")
def exact_worst(mech):
    return allocate(
        mech,
        DesignOptions(
            samples=2000, verification_poses=200, exact_samples=0, method="exact", criterion="worst", seed=2
        ),
    )


@pytest.fixture(scope="module")
def cost_design(mech):
    return allocate(
        mech, DesignOptions(samples=2000, verification_poses=200, exact_samples=0, method="cost", seed=2)
    )


def _independent_check(mech, result, pose_index):
    """Monte Carlo (linear) at one grid pose, and exact kinematics on a subsample there."""
    md = result.method_design
    one = sweep(mech, result.pset, result.grid.points_m[pose_index : pose_index + 1])
    v = verify(
        mech,
        result.pset,
        one,
        result.uncompensatable,
        md.sigma,
        result.target_m,
        "gaussian",
        40_000,
        200,
        np.random.default_rng(9),
    )
    lo, hi = v.linear.failure_ci95
    assert lo <= 1 - md.reliability[pose_index] <= hi
    assert v.max_relative_difference < 1e-2
    lo, hi = v.exact.failure_ci95
    assert lo <= v.linear_subsample.failure_fraction <= hi
    return v


def test_exact_design_meets_target_at_worst_pose(mech, exact_worst):
    md = exact_worst.method_design
    w = exact_worst.worst_index
    assert md.reliability[w] == pytest.approx(stats.norm.cdf(2.0), abs=1e-9)
    _independent_check(mech, exact_worst, w)


def test_exact_every_and_average(mech, exact_worst):
    r = exact_worst
    J = r.grid.J[:, :, r.uncompensatable]
    from pkmtol.design.exact import scale_design

    shape = r.tolerances[r.uncompensatable, r.design_column]
    r_star = stats.norm.cdf(2.0)
    every = scale_design(J, shape, r.target_m, r_star, "every", r.worst_index)
    avg = scale_design(J, shape, r.target_m, r_star, "average", r.worst_index)
    assert every.reliability.min() == pytest.approx(r_star, abs=1e-9)
    assert avg.reliability.mean() == pytest.approx(r_star, abs=1e-9)
    # every ⇒ tighter than worst-pose ⇒ tighter than average on this robot
    assert every.scale < exact_worst.method_design.sigma[0] / shape[0] < avg.scale


def test_cost_design(mech, cost_design):
    md = cost_design.method_design
    r_star = stats.norm.cdf(2.0)
    assert md.reliability.min() >= r_star - 1e-9
    assert md.reliability.min() == pytest.approx(r_star, abs=1e-6)
    # cheaper than the equal-effect design with the same true reliability
    assert md.cost <= md.reference_cost
    _independent_check(mech, cost_design, int(np.argmin(md.reliability)))


def test_cost_infeasible_names_binding_parameters(mech, cost_design):
    r = cost_design
    unc = r.uncompensatable
    params = [r.pset.parameters[i] for i in unc]
    model = cost_model(params, {"length": {"t_min": 0.05}, "angle": {"t_min": 1.0}})
    with pytest.raises(InvalidRequestError, match=r"infeasible.*binding parameters are δ"):
        cost_optimal(
            r.grid.J[:, :, unc],
            model,
            r.target_m,
            stats.norm.cdf(2.0),
            r.method_design.sigma,
            [p.name for p in params],
        )


def test_cost_overrides_are_checked(cost_design):
    params = [cost_design.pset.parameters[i] for i in cost_design.uncompensatable]
    with pytest.raises(InvalidRequestError, match="unknown parameters"):
        cost_model(params, {"parameters": {"nope": {"B": 2}}})
    with pytest.raises(InvalidRequestError, match="cost field"):
        cost_model(params, {"length": {"C": 2}})
    m = cost_model(params, {"parameters": {params[0].name: {"B": 7.0}}})
    assert m.B[0] == 7.0 and m.B[1] == 1.0


def test_closed_form_chi3_cdf_agrees_with_gammainc():
    from scipy import special

    from pkmtol.design.reliability import chi3_cdf_half_square

    x = np.concatenate([[0.0], np.logspace(-12, np.log10(300.0), 20_000)])
    closed = chi3_cdf_half_square(x)
    np.testing.assert_allclose(closed, special.gammainc(1.5, x), rtol=0, atol=5e-15)
    assert closed[0] == 0.0 and closed[-1] == 1.0


@pytest.mark.filterwarnings("error::RuntimeWarning")  # the pose without variance computes no inf·0
def test_stacked_reliability_matches_pose_by_pose():
    from pkmtol.design.reliability import exact_reliability_many

    rng = np.random.default_rng(4)
    a = rng.standard_normal((30, 3, 14)) * 1e-5
    a[3] = 0.0  # a pose without variance: R = 1, zero gradient
    a[4, :, 5:] = 0.0
    a[4, 2] = 0.0  # rank-deficient covariance
    cov = a @ np.swapaxes(a, 1, 2)
    r, g = exact_reliability_many(cov, TARGET, gradient=True)
    for k, c in enumerate(cov):
        rk, gk = exact_reliability(c, TARGET, gradient=True)
        assert r[k] == pytest.approx(rk, abs=1e-15)
        np.testing.assert_allclose(g[k], gk, rtol=1e-12, atol=1e-12 * np.abs(gk).max(initial=1.0))
    assert r[3] == 1.0 and not g[3].any()
    assert np.isfinite(g).all()
    assert exact_reliability_many(cov, TARGET)[1] is None
