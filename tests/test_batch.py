"""Batched kinematics against the per-pose solver: the same solutions (1e-12), the same errors per
pose, the same separations; the stacked SE(3) maths against Pinocchio's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from test_kinematics import build_arm_mechanism

from pkmtol.error_model.parameters import default_set, parameter_set
from pkmtol.error_model.separation import separate, separate_many
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.exceptions import ConvergenceError, JointLimitError, UnreachableTargetError
from pkmtol.kinematics import se3_batch
from pkmtol.kinematics.batch import BatchChain, Solutions
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.continuation import continuation
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = sorted(p.parent for p in (ROOT / "robots").glob("*/mechanism.toml"))


@pytest.fixture(scope="module", params=ROBOTS, ids=lambda p: p.name)
def robot(request):
    mech = load_mechanism(request.param)
    return mech, ClosedChain(mech)


def sequential_grid(chain: ClosedChain, points: np.ndarray):
    """The per-pose solver along the grid, each point from a tangent step off the previous one."""
    pose = chain.inverse(points[0], chain.home())
    poses = [pose]
    for p in points[1:]:
        pose = chain.inverse(p, chain.predict(pose, p))
        poses.append(pose)
    return poses


# --- stacked SE(3) maths ----------------------------------------------------------------------


def test_log6_and_jacobian_match_pinocchio_at_every_angle():
    rng = np.random.default_rng(0)
    placements = []
    for angle in (0.0, 1e-9, 1e-5, 1e-3, 0.1, 0.49, 0.51, 1.0, 2.0, 3.0, 3.13):
        for _ in range(8):
            axis = rng.standard_normal(3)
            placements.append(pin.SE3(pin.exp3(angle * axis / np.linalg.norm(axis)), rng.standard_normal(3)))
    rot = np.array([m.rotation for m in placements])
    trans = np.array([m.translation for m in placements])
    nu, jlog, near_pi = se3_batch.log6_and_jacobian(rot, trans)
    assert not near_pi.any()
    np.testing.assert_allclose(nu, [pin.log6(m).vector for m in placements], rtol=0, atol=1e-12)
    # Pinocchio's Jlog6 loses digits by cancellation near 1e-3 rad; the series here does not
    for m, j in zip(placements, jlog, strict=True):
        ref = pin.Jlog6(m)
        tol = 1e-6 if 5e-4 < np.linalg.norm(pin.log3(m.rotation)) < 5e-2 else 1e-12
        np.testing.assert_allclose(j, ref, rtol=0, atol=tol)
    # and the Jacobian is that of log6: a finite-difference check where Pinocchio is imprecise
    m = placements[3 * 8]
    h = 1e-7
    fd = np.column_stack(
        [
            (pin.log6(m * pin.exp6(h * e)).vector - pin.log6(m * pin.exp6(-h * e)).vector) / (2 * h)
            for e in np.eye(6)
        ]
    )
    np.testing.assert_allclose(jlog[3 * 8], fd, atol=1e-7)


def test_near_half_turn_is_flagged_and_act_inverse_matches():
    rot = np.array([pin.exp3(np.array([0.0, 0.0, np.pi - 1e-4]))])
    assert se3_batch.log3(rot)[2].tolist() == [True]
    rng = np.random.default_rng(1)
    ms = [pin.SE3.Random() for _ in range(5)]
    motion = rng.standard_normal((5, 6, 4))
    out = se3_batch.act_inverse(
        np.array([m.rotation for m in ms]), np.array([m.translation for m in ms]), motion
    )
    for m, x, y in zip(ms, motion, out, strict=True):
        np.testing.assert_allclose(y, m.toActionMatrixInverse() @ x, atol=1e-13)


# --- the same solutions and errors as the per-pose solver -----------------------------------------


def test_inverse_matches_the_per_pose_solver(robot):
    mech, chain = robot
    points = mech.task_space.sample(np.random.default_rng(2), 40)
    home = chain.home()
    sols = BatchChain(mech).inverse(points, np.tile(home, (len(points), 1)))
    for k, p in enumerate(points):
        ref = chain.inverse(p, home)
        pose = sols.pose(k)
        np.testing.assert_allclose(pose.q_all, ref.q_all, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pose.p_m, p, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pose.oMp.homogeneous, ref.oMp.homogeneous, rtol=0, atol=1e-12)
        # the condition bound: never below the 2-norm condition number, at most n times it
        assert ref.condition * (1 - 1e-9) <= pose.condition <= ref.condition * home.size


def test_grid_sweep_matches_the_sequential_per_pose_sweep(robot):
    mech, chain = robot
    pset = parameter_set(mech, default_set(mech))
    grid = mech.task_space.grid()
    batched = sweep(mech, pset, grid, chain)
    poses = sequential_grid(chain, grid)
    seps = [separate(mech, pset, chain, p) for p in poses]
    for b, p, s in zip(batched.separations, poses, seps, strict=True):
        np.testing.assert_allclose(b.pose.q_all, p.q_all, rtol=0, atol=1e-12)
        scale = max(1.0, float(np.abs(s.J_total).max()))
        names = (
            "J",
            "J_total",
            "twist_map",
            "uncompensated_map",
            "correction",
            "error_columns",
            "actuation_map",
        )
        for name in names:
            np.testing.assert_allclose(
                getattr(b, name), getattr(s, name), rtol=0, atol=1e-11 * scale, err_msg=name
            )
        np.testing.assert_allclose(b.W_a, s.W_a, atol=1e-11)
        np.testing.assert_allclose(b.Lambda_a, s.Lambda_a, rtol=1e-11)
        assert b.W_condition == pytest.approx(s.W_condition, rel=1e-11)
        # constraint wrenches: the same span (a basis of a null space of dimension > 1 is arbitrary)
        for k in range(b.W_c.shape[1]):
            wc = s.W_c[:, s.constraint_limb == b.constraint_limb[k]]
            np.testing.assert_allclose(wc @ (wc.T @ b.W_c[:, k]), b.W_c[:, k], atol=1e-10)
        np.testing.assert_allclose(
            np.linalg.norm(b.incompatible_map, axis=0),
            np.linalg.norm(s.incompatible_map, axis=0),
            atol=1e-11 * scale,
        )
    reference = Sweep(
        grid,
        tuple(poses),
        tuple(seps),
        np.array([s.J for s in seps]),
        np.array([s.J_total for s in seps]),
        np.zeros(len(grid)),
    )
    assert batched.classify() == reference.classify()
    assert batched.incompatible().tolist() == reference.incompatible().tolist()


def test_perturbed_forward_matches_fresh_perturbed_chains(robot):
    mech, chain = robot
    pset = parameter_set(mech, "urdf")
    rng = np.random.default_rng(3)
    grid = mech.task_space.grid()
    poses = sequential_grid(chain, grid[:: max(1, len(grid) // 12)])
    eta = rng.standard_normal((len(poses), len(pset))) * 1e-5
    eta[::3] = 0.0  # some samples nominal: their limbs run on the nominal models
    eta[1::3, pset.slices[0]] = 0.0  # some with an unperturbed first limb
    q0 = np.array([p.q_all for p in poses])
    u = q0[:, chain.actuated_idx] + 1e-5
    eps, offsets = pset.perturbations(eta, mech)
    sols = BatchChain(mech, check_limits=False).forward(u, q0, offsets, eps)
    for s in range(len(poses)):
        e, o = pset.perturbation(eta[s], mech)
        pert = ClosedChain(mech, perturbed_limb_models(mech, e), check_limits=False)
        try:
            ref = pert.forward(u[s], q0[s], o)
        except ConvergenceError as err:  # the over-constrained Exechon cannot assemble these
            assert type(sols.errors[s]) is ConvergenceError
            assert sols.errors[s].residual == pytest.approx(err.residual, rel=1e-6)
            continue
        assert sols.errors[s] is None
        np.testing.assert_allclose(sols.q[s], ref.q_all, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sols.p_m[s], ref.p_m, rtol=0, atol=1e-12)


def test_a_second_batch_reuses_the_slots_without_leftovers():
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    chain = ClosedChain(mech)
    pset = parameter_set(mech, "urdf")
    pose = chain.inverse(mech.task_space.grid()[5], chain.home())
    batch = BatchChain(mech, check_limits=False)
    q0 = np.tile(pose.q_all, (2, 1))
    u = q0[:, chain.actuated_idx]
    big = np.full((2, len(pset)), 1e-4)
    batch.forward(u, q0, *pset.perturbations(big, mech)[::-1])  # writes the slots
    eps, offsets = pset.perturbations(np.zeros((2, len(pset))), mech)
    again = batch.forward(u, q0, offsets, eps)
    np.testing.assert_allclose(again.p_m, np.tile(pose.p_m, (2, 1)), atol=1e-12)


def test_errors_per_pose_are_those_of_the_per_pose_solver():
    arm, q_arm = build_arm_mechanism()
    chain = ClosedChain(arm)
    targets = np.array([[1.0, 0.5, 0.5], [3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.9, -0.4, 0.6]])
    sols = BatchChain(arm).inverse(targets, np.tile(q_arm, (len(targets), 1)))
    assert [type(e).__name__ if e else None for e in sols.errors] == [
        None,
        "UnreachableTargetError",
        "SingularPoseError",
        None,
    ]
    for k, t in enumerate(targets):
        if sols.errors[k] is None:
            np.testing.assert_allclose(sols.pose(k).q_all, chain.inverse(t, q_arm).q_all, atol=1e-12)
            continue
        with pytest.raises(type(sols.errors[k])) as ref:
            chain.inverse(t, q_arm)
        assert str(sols.errors[k]) == str(ref.value)  # the same message: it names the target
        np.testing.assert_array_equal(sols.errors[k].target_m, t)
        with pytest.raises(type(sols.errors[k])):
            sols.pose(k)
    assert isinstance(sols.first_error(), UnreachableTargetError)
    assert sols.ok.tolist() == [True, False, False, True]

    seed = load_mechanism(ROOT / "robots" / "r2rps_ups")
    far = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, 1.0]])
    home = ClosedChain(seed).home()
    lim = BatchChain(seed).inverse(far, np.tile(home, (2, 1)))
    assert type(lim.errors[0]) is JointLimitError and lim.errors[1] is None
    with pytest.raises(JointLimitError) as ref:
        ClosedChain(seed).inverse(far[0], home)
    assert str(lim.errors[0]) == str(ref.value)


def test_forward_errors_name_the_problem():
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    chain = ClosedChain(mech)
    pose = chain.inverse(mech.task_space.grid()[0], chain.home())
    batch = BatchChain(mech)
    u = np.tile(pose.q_all[batch.actuated_idx], (2, 1))
    u[1, 0] = 10.0  # a 10 m leg beside two of 0.7 m: no platform closes the loops
    sols = batch.forward(u, np.tile(pose.q_all, (2, 1)))
    np.testing.assert_allclose(sols.p_m[0], pose.p_m, atol=1e-12)
    with pytest.raises(ConvergenceError) as ref:
        ClosedChain(mech, check_limits=False).forward(u[1], pose.q_all)  # checked, it refuses 10 m
    err = sols.errors[1]
    assert type(err) is ConvergenceError
    assert (err.residual, err.iterations) == (
        pytest.approx(ref.value.residual, rel=1e-6),
        ref.value.iterations,
    )
    assert str(err).startswith("forward kinematics (problem 1): Newton's method stopped at residual")


def test_sweep_raises_the_first_failing_point_in_order():
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    pset = parameter_set(mech, "dh")
    grid = mech.task_space.grid()
    points = np.vstack([grid[:2], [[0.0, 0.0, 5.0]], grid[2:4], [[0.0, 0.0, 6.0]]])
    home = ClosedChain(mech).home()
    for guesses in (None, np.tile(home, (len(points), 1))):
        with pytest.raises(JointLimitError) as info:
            sweep(mech, pset, points, guesses=guesses)
        np.testing.assert_array_equal(info.value.target_m, points[2])


def test_separate_many_matches_separate_and_keeps_errors():
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    chain = ClosedChain(mech)
    pset = parameter_set(mech, "dh")
    batch = BatchChain(mech, chain=chain)
    points = np.vstack([mech.task_space.grid()[:6], [[0.0, 0.0, 5.0]]])
    sols = batch.inverse(points, np.tile(chain.home(), (len(points), 1)))
    out = separate_many(mech, pset, batch, sols)
    assert isinstance(out[-1], JointLimitError)
    for k in range(6):
        ref = separate(mech, pset, chain, sols.pose(k))
        np.testing.assert_allclose(out[k].J, ref.J, atol=1e-12)
        np.testing.assert_allclose(out[k].Y_c, ref.Y_c, atol=1e-12)  # one constraint limb: same basis
    parts = Solutions.concatenate([sols.take([1, 0]), sols.take([2])])
    np.testing.assert_array_equal(parts.q, sols.q[[1, 0, 2]])


def test_continuation_solves_the_grid_as_the_per_pose_solver_and_reports_a_failing_first_point():
    seed = load_mechanism(ROOT / "robots" / "r2rps_ups")
    chain = ClosedChain(seed)
    batch = BatchChain(seed, chain=chain)
    home = chain.home()
    grid = seed.task_space.grid()
    sols = continuation(batch, grid, home)
    q, reference = home, []
    for target in grid:  # the per-pose solver along the grid, each point from the one before
        q = chain.inverse(target, q).q_all
        reference.append(q)
    np.testing.assert_allclose(sols.q, np.array(reference), atol=1e-12)
    assert sols.ok.all()

    # the first point out of reach: its error is the batch's from the start, the rest solved from the start
    points = np.vstack([[0.0, 0.0, 5.0], grid[:4]])
    out = continuation(batch, points, home)
    alone = batch.inverse(points[:1], home[None])
    assert type(out.errors[0]) is JointLimitError
    assert str(out.errors[0]) == str(alone.errors[0])
    rest = batch.inverse(points[1:], np.tile(home, (4, 1)))
    np.testing.assert_allclose(out.q[1:], rest.q, atol=1e-12)
    assert out.ok[1:].all()
