"""Closed-chain kinematics: inverse then forward returns the target over the whole task space,
closure holds, the perturbed forward kinematics agrees with a finite-difference prediction, and
unreachable, singular and out-of-limit targets raise their own errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol import ClosedChain, Mechanism, TaskSpace, load_mechanism
from pkmtol.exceptions import JointLimitError, SingularPoseError, UnreachableTargetError
from pkmtol.kinematics.perturbation import perturbed_limb_models

SEED = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


@pytest.fixture(scope="module")
def mech() -> Mechanism:
    return load_mechanism(SEED)


@pytest.fixture(scope="module")
def grid_poses(mech):
    """Inverse kinematics along the 147-point grid, each warm-started from the previous one."""
    chain = ClosedChain(mech)
    q = chain.home()
    poses = []
    for target in mech.task_space.grid():
        pose = chain.inverse(target, q)
        q = pose.q_all
        poses.append(pose)
    return poses


def closure_error(mech: Mechanism, q_limbs) -> float:
    """Largest platform-frame mismatch between limb 0 and any other limb [m, rad], by plain FK."""
    placements = []
    for limb, q in zip(mech.limbs, q_limbs, strict=True):
        data = limb.model.createData()
        pin.framesForwardKinematics(limb.model, data, q)
        placements.append(data.oMf[limb.platform_frame])
    return max(float(np.linalg.norm(pin.log6(placements[0].actInv(m)).vector)) for m in placements[1:])


# --- inverse and forward over the task space --------------------------------------------------


def test_home_closes_with_actuators_unchanged(mech):
    chain = ClosedChain(mech)
    q = chain.home()
    assert closure_error(mech, np.split(q, chain.offsets[1:-1])) <= 1e-10
    home = np.concatenate([limb.home for limb in mech.limbs])
    np.testing.assert_array_equal(q[chain.actuated_idx], home[chain.actuated_idx])


def test_inverse_reaches_every_task_space_point_with_closure(mech, grid_poses):
    grid = mech.task_space.grid()
    assert len(grid_poses) == 147
    for target, pose in zip(grid, grid_poses, strict=True):
        np.testing.assert_allclose(pose.p_m, target, rtol=0, atol=1e-12)
        assert pose.residual <= 1e-10
        assert closure_error(mech, pose.q) <= 1e-10  # checked independently of the solver
        # P recomputed from the platform placement of the passive limb 4 as well
        limb4 = mech.limbs[3]
        data = limb4.model.createData()
        pin.framesForwardKinematics(limb4.model, data, pose.q[3])
        np.testing.assert_allclose(
            data.oMf[limb4.platform_frame].act(mech.reference_point_m), target, atol=1e-10
        )
        assert pose.condition < 1e3


def test_forward_returns_the_inverse_target(mech, grid_poses):
    chain = ClosedChain(mech)
    rng = np.random.default_rng(1)
    grid = mech.task_space.grid()
    for target, pose in zip(grid, grid_poses, strict=True):
        q_actuated = pose.q_all[chain.actuated_idx]
        guess = pose.q_all + rng.uniform(-0.02, 0.02, size=pose.q_all.size)  # perturbed start
        fwd = chain.forward(q_actuated, guess)
        np.testing.assert_allclose(fwd.p_m, target, rtol=0, atol=1e-9)
        assert np.linalg.norm(pin.log6(pose.oMp.actInv(fwd.oMp)).vector) <= 1e-9
        np.testing.assert_allclose(fwd.q_all, pose.q_all, atol=1e-9)
        np.testing.assert_array_equal(fwd.q_all[chain.actuated_idx], q_actuated)
        assert fwd.residual <= 1e-10


# --- forward kinematics of a perturbed mechanism ----------------------------------------------


def pose_error(mech, chain, pose, eps) -> np.ndarray:
    """``δ`` with ``X_actual = X_nominal · exp6(δ)`` for the geometric errors ``eps`` (6,)."""
    models = perturbed_limb_models(mech, eps)
    actual = ClosedChain(mech, models=models, check_limits=False).forward(
        pose.q_all[chain.actuated_idx], pose.q_all
    )
    assert actual.residual <= 1e-12
    return pin.log6(pose.oMp.actInv(actual.oMp)).vector


@pytest.mark.parametrize("point", [0, 48, 121, 146])  # centre, rims of each layer
def test_perturbed_forward_matches_a_finite_difference_prediction(mech, grid_poses, point):
    chain = ClosedChain(mech)
    pose = grid_poses[point]
    rng = np.random.default_rng(point)
    direction = [rng.normal(size=(limb.nq + 1, 6)) for limb in mech.limbs]
    h = 1e-6  # parameter errors of order 1e-6 m / rad

    def scaled(s):
        return [s * d for d in direction]

    # exact responses to h, -h and 2h
    d_plus, d_minus, d_double = (pose_error(mech, chain, pose, scaled(s)) for s in (h, -h, 2 * h))
    slope = (d_plus - d_minus) / (2 * h)
    assert np.linalg.norm(slope) > 0.1  # the errors do move the platform
    assert np.linalg.norm(d_plus - h * slope) <= 1e-3 * np.linalg.norm(h * slope)
    assert np.linalg.norm(d_double - 2 * h * slope) <= 1e-3 * np.linalg.norm(2 * h * slope)

    # independent prediction: implicit function theorem with the nominal closure Jacobian and a
    # central finite difference of the perturbed closure residual at the nominal joint values
    q = pose.q_all
    passive = np.ones(q.size, dtype=bool)
    passive[chain.actuated_idx] = False

    def residual(s):
        return ClosedChain(mech, models=perturbed_limb_models(mech, scaled(s)))._evaluate(q, None)[0].copy()

    dr_ds = (residual(h) - residual(-h)) / (2 * h)
    a_passive = chain._evaluate(q, None)[1][:, passive].copy()
    dq = np.zeros(q.size)
    dq[passive] = -np.linalg.lstsq(a_passive, dr_ds * h, rcond=None)[0]
    limb0 = perturbed_limb_models(mech, scaled(h))[0]
    data = limb0.createData()
    n0 = mech.limbs[0].nq
    pin.framesForwardKinematics(limb0, data, q[:n0] + dq[:n0])
    predicted = pin.log6(pose.oMp.actInv(data.oMf[mech.limbs[0].platform_frame])).vector
    assert np.linalg.norm(d_plus - predicted) <= 1e-3 * np.linalg.norm(d_plus)


@pytest.mark.parametrize("point", [0, 60, 146])
def test_a_common_base_error_moves_the_platform_rigidly(mech, grid_poses, point):
    """Moving every limb's base by the same ``B = exp6(ε_K)`` moves the platform by B, exactly."""
    chain = ClosedChain(mech)
    pose = grid_poses[point]
    eps_k = np.random.default_rng(10 + point).normal(scale=1e-3, size=6)
    base_motion = pin.exp6(eps_k)
    eps = []
    for limb in mech.limbs:
        e = np.zeros((limb.nq + 1, 6))
        # jointPlacements[1] · exp6(ε_1) = B · jointPlacements[1]  ⇔  ε_1 = Ad(M1⁻¹) ε_K
        e[0] = limb.model.jointPlacements[1].actInv(pin.Motion(eps_k)).vector
        eps.append(e)
    models = perturbed_limb_models(mech, eps)
    actual = ClosedChain(mech, models=models).forward(pose.q_all[chain.actuated_idx], pose.q_all)
    expected = base_motion * pose.oMp
    assert np.linalg.norm(pin.log6(expected.actInv(actual.oMp)).vector) <= 1e-10
    np.testing.assert_allclose(actual.p_m, base_motion.act(pose.p_m), atol=1e-10)
    np.testing.assert_allclose(actual.q_all, pose.q_all, atol=1e-9)  # nothing else moves


# --- targets the mechanism cannot take --------------------------------------------------------


def test_target_outside_joint_limits(mech):
    # the closure equations do have a solution at z = 5 m: with legs 4.7 m long
    target = np.array([0.0, 0.0, 5.0])
    with pytest.raises(JointLimitError) as info:
        ClosedChain(mech).inverse(target)
    err = info.value
    assert type(err) is JointLimitError
    assert (err.limb, err.joint) == ("limb1", "limb1_p3")
    assert err.value == pytest.approx(4.70664, abs=1e-5)
    assert (err.lower, err.upper) == (0.4, 1.6)
    assert str(err).startswith(
        "limb 'limb1': target P = (0.000, 0.000, 5000.000) mm is unreachable: joint 'limb1_p3' "
        "would be at 4.70664, outside its limits [0.4, 1.6]; "
    )
    unlimited = ClosedChain(mech, check_limits=False).inverse(target)
    np.testing.assert_allclose(unlimited.p_m, target, atol=1e-12)
    assert unlimited.q[0][2] == pytest.approx(err.value, abs=1e-5)


def build_arm_mechanism() -> tuple[Mechanism, np.ndarray]:
    """A 2-limb mechanism built from ``pin.Model`` objects, and an assembled configuration.

    Limb ``slide`` (3 prismatic joints x, y, z) carries the platform without rotating it; limb
    ``arm`` is a spatial arm: a waist and shoulder at the origin, an elbow 1 m out, a 1 m forearm
    and a 3-revolute wrist. P = the platform origin, so P can be reached iff ``|P| ≤ 2 m``.
    """

    def chain(name, joints):
        model = pin.Model()
        parent = 0
        for k, (joint, placement) in enumerate(joints):
            parent = model.addJoint(parent, joint, placement, f"{name}_j{k + 1}")
        model.addFrame(pin.Frame("platform", parent, 0, pin.SE3.Identity(), pin.FrameType.BODY))
        return model

    ident = pin.SE3.Identity()
    ahead = pin.SE3(np.eye(3), np.array([1.0, 0.0, 0.0]))
    slide = chain(
        "slide",
        [(pin.JointModelPX(), ident), (pin.JointModelPY(), ident), (pin.JointModelPZ(), ident)],
    )
    arm = chain(
        "arm",
        [
            (pin.JointModelRZ(), ident),
            (pin.JointModelRY(), ident),
            (pin.JointModelRY(), ahead),
            (pin.JointModelRZ(), ahead),
            (pin.JointModelRY(), ident),
            (pin.JointModelRX(), ident),
        ],
    )
    q_arm = np.array([0.0, -0.5, 1.0, 0.0, -0.5, 0.0])  # shoulder/elbow/wrist pitches sum to 0
    data = arm.createData()
    pin.framesForwardKinematics(arm, data, q_arm)
    q_slide = data.oMf[arm.getFrameId("platform")].translation.copy()
    mech = Mechanism.from_models(
        "arm",
        [slide, arm],
        [["slide_j1"], ["arm_j2"]],
        "platform",
        [0.0, 0.0, 0.0],
        TaskSpace(kind="points", points_m=np.zeros((1, 3))),
        limb_names=["slide", "arm"],
        homes=[q_slide, q_arm],
    )
    return mech, np.concatenate([q_slide, q_arm])


def test_arm_mechanism_reaches_inside_its_workspace():
    mech, q0 = build_arm_mechanism()
    target = np.array([1.0, 0.5, 0.5])
    pose = ClosedChain(mech).inverse(target, q0)
    np.testing.assert_allclose(pose.p_m, target, atol=1e-12)
    assert closure_error(mech, pose.q) <= 1e-10


def test_unreachable_target():
    # the seed robot reaches any P (its prismatic legs extend without bound in the equations; the
    # limits are what stops it, see above), so use the 2 m arm and a target 3 m away
    mech, q0 = build_arm_mechanism()
    with pytest.raises(UnreachableTargetError) as info:
        ClosedChain(mech).inverse(np.array([3.0, 0.0, 0.0]), q0)
    assert type(info.value) is UnreachableTargetError
    np.testing.assert_array_equal(info.value.target_m, [3.0, 0.0, 0.0])
    assert info.value.limb == "arm"
    assert str(info.value).startswith(
        "limb 'arm': target P = (3000.000, 0.000, 0.000) mm is unreachable: the closure equations "
        "have no solution near the initial guess"
    )
    assert "move the target (or the task space) inside the workspace" in str(info.value)


def test_singular_pose():
    """The arm folded back onto its shoulder puts P at the origin: a genuine singularity."""
    mech, q0 = build_arm_mechanism()
    chain = ClosedChain(mech)
    target = np.zeros(3)
    # the folded configuration: elbow at (1, 0, 0), forearm back to the origin, wrist undoing
    # the half-turn RY(π) of the elbow (RZ(π)·RY(0)·RX(π) = RY(π))
    q_folded = np.r_[0.0, 0.0, 0.0, 0.0, 0.0, np.pi, np.pi, 0.0, np.pi]
    res, jac = chain._evaluate(q_folded, target)
    assert np.max(np.abs(res)) <= 1e-12  # it solves the equations exactly ...
    singular_values = np.linalg.svd(jac, compute_uv=False)
    assert singular_values[-1] <= 1e-12 * singular_values[0]  # ... where the Jacobian loses rank
    # the self-motion behind it: turning the waist and the first wrist joint together (RY(π)
    # flips the wrist's z axis) leaves the platform frames where they were, P at the origin
    q_turned = q_folded.copy()
    q_turned[[3, 6]] += 0.3
    assert np.max(np.abs(chain._evaluate(q_turned, target)[0])) <= 1e-12

    for start in (q_folded, q0):  # at the singular pose, and from the assembled configuration
        with pytest.raises(SingularPoseError) as info:
            chain.inverse(target, start)
        assert type(info.value) is SingularPoseError
        assert info.value.condition > 1e8
        np.testing.assert_array_equal(info.value.target_m, target)
        assert str(info.value).startswith(
            "singular configuration at P = (0.000, 0.000, 0.000) mm: the inverse kinematics "
            "Jacobian has condition number "
        )
