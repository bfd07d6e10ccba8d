"""Kinematic calibration against exact kinematics (DESIGN.md, "Compensation and calibration").

The contract of the calibrated mode: measurements simulated on exact kinematics, identification by
Gauss–Newton on exact kinematics, compensation by the identified model's exact inverse kinematics,
and the linear post-calibration model ``L δ + N ν`` agreeing with all of it to second order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pkmtol.calibration.compensation import controller_commands, pose_errors
from pkmtol.calibration.identification import identify, model_positions
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.plan import candidate_pool, make_plan
from pkmtol.calibration.postcal import calibrated_maps
from pkmtol.calibration.prediction import predict
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"


@pytest.fixture(scope="module")
def seed():
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    classes = sweep(mech, pset, mech.task_space.grid(), chain).classify()
    settings = CalibrationSettings(candidates=100)
    pool = candidate_pool(mech, pset, settings, chain)
    return mech, pset, classes, settings, pool


def _draw(pset, columns, rng, size_m=1e-4, size_rad=5e-4):
    delta = np.zeros(len(pset))
    scale = np.where(np.array(pset.units) == "m", size_m, size_rad)
    delta[columns] = rng.standard_normal(len(columns)) * scale[columns]
    return delta


def _measure(mech, pset, plan, delta, rng=None):
    true = Machine(mech, pset, delta)
    y, _ = model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
    nu = np.zeros(y.size) if rng is None else rng.standard_normal(y.size) * plan.settings.noise_m
    return true, y + nu.reshape(y.shape), nu


def _identify(mech, pset, plan, y):
    return identify(
        mech, pset, plan.ident, plan.H, plan.maps.commands, plan.maps.q, y, plan.targets_m, plan.prior_sigma
    )


def test_seed_ranks_match_the_independent_study(seed):
    """DESIGN.md: the compensatable urdf set has 46 parameters of rank 23 from P, with a clean gap."""
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, settings, pool, poses=40)
    assert plan.ident.columns.size == 46 and plan.ident.rank == 23
    assert plan.ident.pivots[22] > 1e-5 and plan.ident.pivots[23] < 1e-12
    full = make_plan(mech, pset, classes, CalibrationSettings(controller="full"), pool, poses=40)
    assert full.ident.columns.size == 64 and full.ident.rank == 33
    # every dependent column is its combination of base columns, to round-off
    H = plan.H[:, plan.ident.columns]
    Hb, Hd = H[:, plan.ident.base], H[:, plan.ident.dependent]
    assert np.abs(Hd - Hb @ plan.ident.combination).max() < 1e-10 * np.abs(H).max()


def test_measurement_jacobian_matches_finite_differences_of_exact_kinematics(seed):
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, CalibrationSettings(controller="full"), pool, poses=12)
    rng = np.random.default_rng(4)
    cols = plan.ident.columns[rng.choice(plan.ident.columns.size, 12, replace=False)]
    y0, _ = model_positions(
        Machine(mech, pset, np.zeros(len(pset))), plan.maps.commands, plan.maps.q, plan.targets_m
    )
    h = 1e-6
    for c in cols:
        d = np.zeros(len(pset))
        d[c] = h
        yp, _ = model_positions(Machine(mech, pset, d), plan.maps.commands, plan.maps.q, plan.targets_m)
        d[c] = -h
        ym, _ = model_positions(Machine(mech, pset, d), plan.maps.commands, plan.maps.q, plan.targets_m)
        fd = ((yp - ym) / (2 * h)).reshape(-1)
        np.testing.assert_allclose(plan.H[:, c], fd, atol=1e-7 * max(1.0, np.abs(fd).max()))


def test_actuation_map_is_the_twist_of_the_actuator_offsets(seed):
    mech, pset, classes, settings, pool = seed
    act = [i for i, p in enumerate(pset.parameters) if p.actuator]
    np.testing.assert_allclose(pool.actuation, pool.twist[:, :, act], atol=1e-12)


def test_noise_free_identification_recovers_the_base_combination(seed):
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, settings, pool, poses=40)
    rng = np.random.default_rng(11)
    delta = np.zeros(len(pset))
    scale = np.where(np.array(pset.units) == "m", 1e-4, 5e-4)
    b = plan.ident.base_columns
    delta[b] = rng.standard_normal(b.size) * scale[b]
    _, y, _ = _measure(mech, pset, plan, delta)
    res = _identify(mech, pset, plan, y)
    beta = plan.ident.true_base_values(delta)
    assert res.converged
    assert np.linalg.norm(res.identified - beta) <= 1e-8 * np.linalg.norm(beta)
    assert res.rms_after_m <= 1e-12 < res.rms_before_m


def test_machine_with_only_compensatable_errors_is_exact_after_calibration(seed):
    """Every compensatable error (dependent ones too) at manufacturing σ: nothing left at P."""
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, settings, pool, poses=40)
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta = _draw(pset, comp, np.random.default_rng(2))
    true, y, _ = _measure(mech, pset, plan, delta)
    res = _identify(mech, pset, plan, y)
    model = Machine(mech, pset, res.estimate)
    held = pool.subset(np.setdiff1d(np.arange(len(pool)), plan.chosen)[:40])
    u, ok = controller_commands(model, held.points_m, held.q)
    err = pose_errors(true, u, held.q, held.points_m, held.rotations)
    before = pose_errors(true, held.commands, held.q, held.points_m, held.rotations)
    assert ok.all() and err.solved.all()
    assert err.dlambda_m.max() <= 1e-9 < 1e-4 < before.dlambda_m.max()


def test_linear_post_calibration_model_matches_exact_simulation_to_second_order(seed):
    """``e = L δ + N ν`` and the platform rotation against the exact study: ≤ 1e-3 at 1e-6, ×1/10."""
    mech, pset, classes, settings, pool = seed
    nonabs = [i for i, c in enumerate(classes) if c != "absorbed"]
    held = pool.subset(np.arange(len(pool))[-25:])
    for controller in ("compensatable", "full"):
        plan = make_plan(mech, pset, classes, CalibrationSettings(controller=controller), pool, poses=30)
        maps = calibrated_maps(held, plan.H, plan.ident, plan.prior_sigma)
        mismatch = []
        for size in (1e-5, 1e-6):
            rng = np.random.default_rng(7)
            delta = _draw(pset, nonabs, rng, size, 5 * size)
            nu = rng.standard_normal(plan.H.shape[0]) * 0.1 * size
            true = Machine(mech, pset, delta)
            y, _ = model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
            res = _identify(mech, pset, plan, y + nu.reshape(y.shape))
            u, _ = controller_commands(Machine(mech, pset, res.estimate), held.points_m, held.q)
            err = pose_errors(true, u, held.q, held.points_m, held.rotations)
            lin_p = np.einsum("kin,n->ki", maps.position, delta) + np.einsum(
                "kiM,M->ki", maps.position_noise, nu
            )
            lin_r = np.einsum("kin,n->ki", maps.rotation, delta) + np.einsum(
                "kiM,M->ki", maps.rotation_noise, nu
            )
            mismatch.append(
                max(
                    np.linalg.norm(err.position_m - lin_p) / np.linalg.norm(lin_p),
                    np.linalg.norm(err.rotation_rad - lin_r) / np.linalg.norm(lin_r),
                )
            )
        assert mismatch[1] <= 1e-3, (controller, mismatch)
        assert mismatch[0] / mismatch[1] > 5, (controller, mismatch)


def test_identifiable_parameters_leave_no_column_in_L(seed):
    """With the whole pool measured, a base parameter of the controller model has a zero column."""
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, settings, pool, chosen=np.arange(len(pool)))
    maps = calibrated_maps(pool, plan.H, plan.ident)
    scale = np.abs(maps.position).max()
    for c in plan.ident.base_columns:
        assert np.abs(maps.position[:, :, c]).max() <= 1e-12 * max(scale, 1.0)
    # an uncompensatable parameter outside the model keeps an effect
    unc = [i for i, c in enumerate(classes) if c == "uncompensatable"]
    assert max(np.abs(maps.position[:, :, i]).max() for i in unc) > 1e-3


def test_noise_free_whole_grid_calibration_removes_errors_inside_the_model(seed):
    """σ_m → 0 and every pool pose measured: an error inside the identified set leaves Δλ → 0."""
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, CalibrationSettings(noise_m=0.0), pool, chosen=np.arange(len(pool)))
    maps = calibrated_maps(pool, plan.H, plan.ident)
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    assert np.abs(maps.position[:, :, comp]).max() < 1e-12


def test_empirical_covariance_matches_the_predicted_one(seed):
    """200 noisy calibrations of one machine: the whitened estimate errors are N(0, I).

    The estimate error ``β̂ − β`` is whitened by the predicted covariance ``σ_m² (H_Bᵀ H_B)⁻¹``
    (Cholesky). Tolerances: the mean of ‖z‖²/r is within 0.12 of 1 (its standard error is
    √(2/(200 r)) ≈ 0.02 for r = 23), and every direction's variance within [0.6, 1.5] (each is
    χ²₂₀₀/200, standard deviation 0.1; 0.6 and 1.5 are 4 and 5 standard deviations out).
    """
    mech, pset, classes, settings, pool = seed
    plan = make_plan(mech, pset, classes, CalibrationSettings(noise_m=1e-5), pool, poses=25)
    rng = np.random.default_rng(5)
    b = plan.ident.base_columns
    delta = np.zeros(len(pset))
    delta[b] = rng.standard_normal(b.size) * 1e-6  # small: the estimate is linear in the noise
    _, y0, _ = _measure(mech, pset, plan, delta)
    beta = plan.ident.true_base_values(delta)
    chol = np.linalg.cholesky(plan.ident.covariance)
    zs = []
    for _ in range(200):
        y = y0 + rng.standard_normal(y0.shape) * 1e-5
        res = _identify(mech, pset, plan, y)
        zs.append(np.linalg.solve(chol, res.identified - beta))
    z = np.array(zs)
    r = plan.ident.rank
    assert abs(np.mean(np.sum(z**2, axis=1)) / r - 1) < 0.12
    variances = np.var(z, axis=0)
    assert variances.min() > 0.6 and variances.max() < 1.5


def test_d_optimal_beats_random_in_det_and_predicted_error(seed):
    mech, pset, classes, settings, pool = seed
    sigma = settings.manufacturing_sigma(pset)
    sigma[[i for i, c in enumerate(classes) if c == "absorbed"]] = 0.0
    unc = [i for i, c in enumerate(classes) if c == "uncompensatable"]
    sigma[unc] = 5e-6
    held = pool.subset(np.arange(len(pool))[::3])
    dopt = make_plan(mech, pset, classes, settings, pool, sigma, poses=15)
    pd = predict(calibrated_maps(held, dopt.H, dopt.ident), sigma, 5e-5, np.array([0, 0, 1.0]))
    for k in range(5):
        rnd = make_plan(
            mech,
            pset,
            classes,
            CalibrationSettings(candidates=100, seed=k),
            pool,
            sigma,
            poses=15,
            selection="random",
        )
        pr = predict(calibrated_maps(held, rnd.H, rnd.ident), sigma, 5e-5, np.array([0, 0, 1.0]))
        assert dopt.log_det > rnd.log_det
        assert pd.mean_m < pr.mean_m and pd.p99_m < pr.p99_m
