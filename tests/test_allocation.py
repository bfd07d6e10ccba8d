"""The main job on the seed robot: Table III's structure, the pose search, verification, comparison."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from pkmtol.design.fosm import fosm_tolerances
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.error_model.accuracy import norm_moments
from pkmtol.exceptions import InvalidRequestError, MechanismFormatError, OutputError
from pkmtol.model.loader import load_mechanism
from pkmtol.present.outputs import write_outputs
from pkmtol.present.tables import to_json

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"

PAPER_R_PERCENT = [69.14, 84.13, 93.32, 97.72, 99.38, 99.87]  # Table III


@pytest.fixture(scope="module")
def mech():
    return load_mechanism(SEED)


@pytest.fixture(scope="module")
def result(mech):
    """The default job (10^4 samples, 1,000 exact samples)."""
    return allocate(mech, DesignOptions(seed=1))


def test_reliability_row_is_table_iii(result):
    assert result.betas == (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
    np.testing.assert_allclose(100 * result.reliability_fosm, PAPER_R_PERCENT, atol=0.01)


def test_sigma_times_beta_constant_along_rows(result):
    tol = result.tolerances[result.uncompensatable]
    prod = tol * np.asarray(result.betas)[None, :]
    np.testing.assert_allclose(prod, prod[:, :1].repeat(prod.shape[1], axis=1), rtol=1e-12)
    # equal effect: ω_i σ_i the same for all, and Σ ω_i² σ_i² = (Δλ*/β)²
    col = result.design_column
    eff = result.sensitivity[result.uncompensatable] * tol[:, col]
    np.testing.assert_allclose(eff, eff[0], rtol=1e-12)
    assert math.isclose(np.sum(eff**2), (result.target_m / result.design_beta) ** 2, rel_tol=1e-12)


def test_fourteen_allocated(result):
    assert len(result.uncompensatable) == 14


def test_worst_point_monte_carlo_vs_analytic_on_rim(result, mech):
    s = result.search
    rim = mech.task_space.on_rim()
    assert rim[s.worst_index] and rim[s.worst_index_analytic]
    # sampled and analytic σ agree within sampling error at every point
    n = s.samples
    se = s.sigma_analytic_m / math.sqrt(2 * (n - 1))
    assert np.all(np.abs(s.sigma_sampled_m - s.sigma_analytic_m) <= 6 * se)
    # the sampled worst point is the analytic worst point (up to ties within sampling error)
    best = s.sigma_analytic_m.max()
    assert s.sigma_analytic_m[s.worst_index] >= best - 6 * se[s.worst_index_analytic]
    assert result.worst_index == s.worst_index_analytic


def test_norm_moments_against_sampling():
    rng = np.random.default_rng(0)
    lam = np.array([4.0, 1.0, 0.01])
    x = rng.standard_normal((400_000, 3)) * np.sqrt(lam)
    r = np.linalg.norm(x, axis=1)
    m, s = norm_moments(lam)
    assert abs(m - r.mean()) < 5 * r.std() / math.sqrt(r.size)
    assert abs(s - r.std()) < 5 * s / math.sqrt(2 * r.size) * 2


def test_verification_exact_agrees_with_linear(result):
    for name, v in result.verification.items():
        assert v.linear.samples == 10_000
        assert v.exact is not None and v.exact.samples == 1_000
        # per-sample: exact and linear Δλ differ by far less than Δλ*
        assert v.max_relative_difference < 1e-2, name
        lo, hi = v.exact.failure_ci95
        assert lo <= v.linear_subsample.failure_fraction <= hi
        lo, hi = v.linear.failure_ci95
        assert lo - 0.01 <= v.exact.failure_fraction <= hi + 0.01
        assert math.isclose(v.exact.mean_m, v.linear_subsample.mean_m, rel_tol=1e-2)


def test_uniform_sigma_has_a_third_of_the_variance(result):
    """The paper's ±σ uniform check tests E[Δλ²] three times smaller than the design's."""
    v = result.verification

    def second(s):
        return s.std_m**2 + s.mean_m**2

    ratio = second(v["uniform_sqrt3_sigma"].linear) / second(v["uniform_sigma"].linear)
    assert 2.8 < ratio < 3.2
    # variance-matched Gaussian over the whole task space: E[Δλ²] stays below the design
    # point's (Δλ*/β)² (FOSM's design equation), since the design point is the most sensitive
    g = v["gaussian"].linear
    assert (
        0.2 * (result.target_m / result.design_beta) ** 2
        < second(g)
        <= (result.target_m / result.design_beta) ** 2
    )


def test_traditional_is_tighter(result):
    col = result.design_column
    trad = dict(zip(result.traditional.columns.tolist(), result.traditional.tolerance, strict=True))
    shared = [i for i in result.uncompensatable if np.isfinite(result.tolerances[i, col])]
    assert shared
    for i in shared:
        assert trad[i] < result.tolerances[i, col], result.pset.names[i]
    assert len(result.traditional.columns) > len(result.uncompensatable)


def test_same_seed_same_bytes(mech):
    opts = DesignOptions(samples=500, verification_poses=50, exact_samples=5, seed=3)
    assert to_json(allocate(mech, opts)) == to_json(allocate(mech, opts))


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"target_m": 0.0}, "Δλ* must be positive"),
        ({"target_m": -1e-5}, "Δλ* must be positive"),
        ({"betas": (1.0, -2.0)}, "β must be positive"),
        ({"design_beta": 0.0}, "β must be positive"),
        ({"samples": 0}, "samples = 0: must be ≥ 2"),
    ],
)
def test_bad_requests(mech, kwargs, needle):
    with pytest.raises(InvalidRequestError, match=re.escape(needle)):
        allocate(mech, DesignOptions(**kwargs))


def test_not_a_robot_folder(tmp_path):
    with pytest.raises(MechanismFormatError, match="mechanism.toml"):
        load_mechanism(tmp_path)
    with pytest.raises(MechanismFormatError, match="not a folder"):
        load_mechanism(tmp_path / "nope")


def test_unwritable_output_leaves_nothing(mech, tmp_path):
    r = allocate(mech, DesignOptions(samples=200, verification_poses=20, exact_samples=0))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="cannot write"):
        write_outputs(r, blocker / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
    out = tmp_path / "ok"
    written = write_outputs(r, out)
    assert sorted(p.name for p in out.iterdir()) == sorted([p.name for p in written] + ["pkmtol-run.json"])


def test_fosm_tolerance_formula():
    t = fosm_tolerances(np.array([0.5, 2.0]), 5e-5, np.array([2.0]))
    np.testing.assert_allclose(t[:, 0], 5e-5 / (math.sqrt(2) * np.array([0.5, 2.0]) * 2.0))
