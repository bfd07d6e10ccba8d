"""Chunked Monte Carlo: the same random stream and the same numbers as one draw, with bounded memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pkmtol.design.exact as exact_mod
import pkmtol.design.pose_search as pose_search
import pkmtol.design.verification as verification
from pkmtol.design.exact import claimed_vs_true
from pkmtol.design.pose_search import search_sensitive_pose
from pkmtol.design.verification import verify_all
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


def test_chunked_linear_verification_is_bit_identical(seed_maps, monkeypatch):
    mech, pset, _, rnd, unc = seed_maps
    sigma = np.full(unc.size, 2e-5)
    sigma[0] = np.inf  # a free tolerance is held at zero
    rng_one = np.random.default_rng(9)
    one = verify_all(mech, pset, rnd, unc, sigma, 5e-5, 5000, 0, rng_one)
    monkeypatch.setattr(verification, "LINEAR_CHUNK", 777)
    rng = np.random.default_rng(9)
    chunked = verify_all(mech, pset, rnd, unc, sigma, 5e-5, 5000, 0, rng)
    for dist in one:
        np.testing.assert_array_equal(one[dist].dlam_linear_m, chunked[dist].dlam_linear_m)
        assert one[dist].linear == chunked[dist].linear
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
