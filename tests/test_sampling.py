"""Chunked Monte Carlo: the same random stream and the same numbers as one draw, with bounded memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pkmtol.design.exact as exact_mod
import pkmtol.design.mode_verification as mode_verification
import pkmtol.design.pose_search as pose_search
import pkmtol.design.verification as verification
from pkmtol.design.budget import BYTES_PER_SAMPLE
from pkmtol.design.exact import claimed_vs_true
from pkmtol.design.mode_verification import verify_mode
from pkmtol.design.pose_search import search_sensitive_pose
from pkmtol.design.verification import cyclic_products, sample_errors, verify_all
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.model.loader import load_mechanism

SEED = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


@pytest.fixture(scope="module")
def seed_maps():
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "dh")
    points = mech.task_space.sample(np.random.default_rng(2), 30)
    grid = sweep(mech, pset, mech.task_space.grid())
    rnd = sweep(mech, pset, points, guesses=np.tile(grid.poses[0].q_all, (30, 1)))
    unc = np.array([i for i, c in enumerate(grid.classify()) if c == "uncompensatable"])
    return mech, pset, grid, rnd, unc


def _same_stats(a, b):
    """Failure statistics of the same samples, their Δλ equal to round-off."""
    assert (a.samples, a.failure_fraction, a.failure_ci95) == (b.samples, b.failure_fraction, b.failure_ci95)
    assert a.mean_m == pytest.approx(b.mean_m, rel=1e-13) and a.std_m == pytest.approx(b.std_m, rel=1e-12)


@pytest.mark.parametrize(
    ("m", "start", "count"), [(7, 0, 70), (7, 3, 70), (7, 5, 4), (7, 12, 2), (1, 4, 9), (30, 0, 29)]
)
def test_cyclic_products_are_the_gathered_products(m, start, count):
    """Sample s uses map (start + s) mod m: whole cycles stacked per pose, the ends gathered."""
    g = np.random.default_rng(m + start + count)
    maps, x = g.standard_normal((m, 3, 5)), g.standard_normal((count, 5))
    gathered = np.einsum("sij,sj->si", maps[(start + np.arange(count)) % m], x)
    np.testing.assert_allclose(cyclic_products(maps, x, start), gathered, rtol=1e-13, atol=1e-15)


def test_chunked_linear_verification_is_the_one_draw(seed_maps, monkeypatch):
    mech, pset, _, rnd, unc = seed_maps
    sigma = np.full(unc.size, 2e-5)
    sigma[0] = np.inf  # a free tolerance is held at zero
    rng_one = np.random.default_rng(9)
    one = verify_all(mech, pset, rnd, unc, sigma, 5e-5, 5000, 0, rng_one)
    monkeypatch.setattr(verification, "LINEAR_CHUNK", 777)
    rng = np.random.default_rng(9)
    chunked = verify_all(mech, pset, rnd, unc, sigma, 5e-5, 5000, 0, rng)
    for dist in one:
        np.testing.assert_allclose(one[dist].dlam_linear_m, chunked[dist].dlam_linear_m, rtol=1e-13)
        _same_stats(one[dist].linear, chunked[dist].linear)
    # the generator is where the three unchunked draws leave it: the next stage sees the same stream
    assert rng.random() == rng_one.random()
    points = chunked["gaussian"].points_m
    assert points.shape == (5000, 3)
    np.testing.assert_array_equal(points[31], rnd.points_m[1])


def test_chunked_claims_are_identical(seed_maps, monkeypatch):
    _, _, grid, rnd, unc = seed_maps
    tol = np.outer(np.full(unc.size, 2e-5), [1.0, 0.5])
    args = (grid.J[3][:, unc], rnd.J[:, :, unc], tol, (1.0, 2.0), 5e-5, 3000)
    one = claimed_vs_true(*args, np.random.default_rng(4))
    monkeypatch.setattr(exact_mod, "LINEAR_CHUNK", 500)
    assert claimed_vs_true(*args, np.random.default_rng(4)) == one


def test_chunked_pose_search_agrees_with_one_draw(seed_maps, monkeypatch):
    _, _, grid, _, unc = seed_maps
    J = grid.J[:, :, unc]
    monkeypatch.setattr(pose_search, "SEARCH_CHUNK", 10**9)
    one = search_sensitive_pose(J, 20_000, np.random.default_rng(6))
    monkeypatch.setattr(pose_search, "SEARCH_CHUNK", 3000)
    chunked = search_sensitive_pose(J, 20_000, np.random.default_rng(6))
    np.testing.assert_allclose(chunked.sigma_sampled_m, one.sigma_sampled_m, rtol=1e-12)
    assert chunked.worst_index == one.worst_index
    # the sampled σ agrees with the analytic one to sampling error
    assert np.abs(chunked.sigma_sampled_m / chunked.sigma_analytic_m - 1).max() < 0.05


def _mode_maps(m=13, n=9, M=4, seed=0):
    g = np.random.default_rng(seed)
    rot = np.array([np.linalg.qr(g.standard_normal((3, 3)))[0] for _ in range(m)])
    return AccuracyMaps(
        mode="calibrated",
        position=g.standard_normal((m, 3, n)),
        rotation=g.standard_normal((m, 3, n)),
        position_noise=g.standard_normal((m, 3, M)),
        rotation_noise=g.standard_normal((m, 3, M)),
        noise_m=1e-5,
        rotations=rot,
    )


def _one_piece(maps, n, columns, sigma, bg, dist, samples, rng, axis):
    """The linear draw of verify_mode as one piece (what it did before it was chunked)."""
    at = np.arange(samples) % len(maps)
    delta = np.zeros((samples, n))
    delta[:, columns] = sample_errors(dist, np.where(np.isfinite(sigma), sigma, 0.0), samples, rng)
    delta[:, bg[0]] = rng.standard_normal((samples, len(bg[0]))) * bg[1]
    noise = rng.standard_normal((samples, maps.position_noise.shape[2])) * maps.noise_m
    e = np.einsum("sin,sn->si", maps.position[at], delta) + np.einsum(
        "siM,sM->si", maps.position_noise[at], noise
    )
    tmap, tnoise = maps.tilt_maps(axis)
    t = np.einsum("sin,sn->si", tmap[at], delta) + np.einsum("siM,sM->si", tnoise[at], noise)
    return np.linalg.norm(e, axis=1), np.linalg.norm(t, axis=1), delta, noise


@pytest.mark.parametrize("dist", ["gaussian", "uniform_sigma"])
def test_chunked_mode_verification_is_the_one_draw(monkeypatch, dist):
    """verify_mode (calibrated, none, and any mode with the tilt) in chunks: the one-piece numbers."""
    maps = _mode_maps()
    n, columns, bg = 9, np.array([0, 2, 3, 7]), (np.array([1, 5]), np.array([3e-6, 4e-6]))
    sigma = np.array([2e-5, np.inf, 1e-5, 3e-5])
    axis = np.array([0.0, 0.2, 1.0])
    monkeypatch.setattr(mode_verification, "MODE_CHUNK", 777)
    seen = {}

    def exact(k, delta, noise):
        seen[len(seen)] = (k, delta.copy(), noise.copy())
        return None

    rng_one, rng = np.random.default_rng(5), np.random.default_rng(5)
    dlam, tilt, delta, noise = _one_piece(maps, n, columns, sigma, bg, dist, 5000, rng_one, axis)
    ver = verify_mode(
        maps, np.zeros((13, 3)), n, columns, sigma, 5e-5, dist, 5000, 1600, rng, exact,
        background=bg, orientation=(axis, 1e-4),
    )  # fmt: skip
    np.testing.assert_allclose(ver.dlam_linear_m, dlam, rtol=1e-13)
    np.testing.assert_allclose(ver.tilt_linear_rad, tilt, rtol=1e-13)
    assert rng.random() == rng_one.random()  # the generator ends where the one-piece draws left it
    # the exact subsample (over two chunks) gets the same draws as in one piece
    assert len(seen) == 1600
    for s in (0, 776, 777, 1599):
        k, d, e = seen[s]
        assert k == s % 13
        np.testing.assert_array_equal(d, delta[s])
        np.testing.assert_array_equal(e, noise[s])


def test_mode_verification_memory_does_not_grow_with_samples(monkeypatch):
    """Peak traced memory grows by less than the budget's bytes per sample, not with the parameters."""
    import tracemalloc

    maps = _mode_maps(m=50, n=60, M=12)
    columns, sigma = np.arange(0, 60, 2), np.full(30, 1e-5)
    monkeypatch.setattr(mode_verification, "MODE_CHUNK", 4000)

    def peak(samples):
        tracemalloc.start()
        verify_mode(
            maps, np.zeros((50, 3)), 60, columns, sigma, 5e-5, "gaussian", samples, 0,
            np.random.default_rng(1), None, orientation=(np.array([0.0, 0.0, 1.0]), 1e-4),
        )  # fmt: skip
        top = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return top

    small, large = peak(4000), peak(32_000)
    # one piece, the gathered maps alone took 2 × 24 bytes × 60 parameters per sample
    assert (large - small) / 28_000 < BYTES_PER_SAMPLE, (small, large)


def test_vector_norms_are_numpys_norms_bit_for_bit():
    # Δλ of every Monte Carlo sample: the same numbers as np.linalg.norm over the last axis
    from pkmtol.error_model.accuracy import vector_norms

    rng = np.random.default_rng(11)
    for shape in ((1000, 3), (7, 50, 3), (3,)):
        x = rng.standard_normal(shape) * 10.0 ** rng.uniform(-9, 3, shape)
        np.testing.assert_array_equal(vector_norms(x), np.linalg.norm(x, axis=-1))
    view = rng.standard_normal((100, 6))[:, 3:]  # a strided view, as a tilt block
    np.testing.assert_array_equal(vector_norms(view), np.linalg.norm(view, axis=1))
