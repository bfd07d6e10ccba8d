"""Constraint models out: a mechanism as one pin.Model plus a FrameAnchorConstraintModel per loop.

pkmtol's closed-chain solutions, nominal and perturbed, satisfy those constraints as Pinocchio
evaluates them (constraint data and ``getConstraintsJacobian``), and Pinocchio's constraint Jacobian
allows exactly the platform motions that pkmtol's constraint wrenches allow."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol import ClosedChain, load_mechanism, perturbed_limb_models
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.separation import null_space, separate
from pkmtol.exceptions import InvalidRequestError, URDFError
from pkmtol.model.constraints import constraint_models
from pkmtol.model.mechanism import Mechanism

REPO = Path(__file__).resolve().parents[1]
SEED = REPO / "robots" / "r2rps_ups"
MJCF = REPO / "tests" / "data" / "r2rps_ups_mjcf"
#: Positions of P in K [m]: the task-space centre, two rim points, top and bottom layers.
POINTS = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.9], [-0.3, 0.52, 1.1]])


@pytest.fixture(scope="module", params=[SEED, MJCF], ids=["limb-urdfs", "mjcf"])
def mech(request) -> Mechanism:
    return load_mechanism(request.param)


def perturbed(mech: Mechanism, scale: float, seed: int):
    """Perturbed limb models and joint offsets for random errors of size ``scale`` [m, rad]."""
    pset = parameter_set(mech, "urdf")
    eta = np.random.default_rng(seed).standard_normal(len(pset)) * scale
    eps, offsets = pset.perturbation(eta, mech)
    return perturbed_limb_models(mech, eps), offsets


def pinocchio_residuals(cm, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residuals (constraint data) and ``getConstraintsJacobian``, calling Pinocchio directly."""
    model, data = cm.model, cm.model.createData()
    pin.computeJointJacobians(model, data, q)  # joint placements and Jacobians at q
    res = []
    for c in cm.constraints:
        d = c.createData()
        c.calc(model, data, d)
        res.append(np.array(d.constraint_position_error))
    models = pin.StdVec_ConstraintModel()
    for c in cm.constraints:
        models.append(pin.ConstraintModel(c))
    datas = pin.StdVec_ConstraintData()
    for c in models:
        datas.append(c.createData())
    for c, d in zip(models, datas, strict=True):
        c.calc(model, data, d)
    return np.concatenate(res), np.array(pin.getConstraintsJacobian(model, data, models, datas))


def test_one_model_in_limb_order(mech):
    cm = mech.constraint_models()
    assert cm.model.nq == cm.model.nv == mech.n_joints == 21
    assert list(cm.model.names[1:]) == [n for lb in mech.limbs for n in lb.joint_names]
    assert [type(c).__name__ for c in cm.constraints] == ["FrameAnchorConstraintModel"] * 3
    assert [c.name for c in cm.constraints] == ["limb2", "limb3", "limb4"]
    assert cm.actuated == (2, 8, 14)
    assert cm.model.frames[cm.platform_frame].name == "platform"
    assert [cm.model.frames[f].name for f in cm.platform_frames[1:]] == [
        "limb2/platform",
        "limb3/platform",
        "limb4/platform",
    ]
    # each limb's platform frame in the one model is where the limb model puts it
    rng = np.random.default_rng(3)
    qs = [rng.uniform(-1, 1, lb.nq) for lb in mech.limbs]
    data = cm.model.createData()
    pin.framesForwardKinematics(cm.model, data, cm.q(qs))
    for lb, q, fid in zip(mech.limbs, qs, cm.platform_frames, strict=True):
        d = lb.model.createData()
        pin.framesForwardKinematics(lb.model, d, q)
        np.testing.assert_allclose(
            data.oMf[fid].homogeneous, d.oMf[lb.platform_frame].homogeneous, atol=1e-14
        )


def test_nominal_closed_chain_satisfies_the_constraints(mech):
    cm = mech.constraint_models()
    chain = ClosedChain(mech)
    for p in POINTS:
        q = cm.q(chain.inverse(p).q)
        res, jac = pinocchio_residuals(cm, q)
        assert res.shape == (18,) and jac.shape == (18, 21)
        assert np.max(np.abs(res)) < 1e-10
        # pkmtol's helpers give Pinocchio's numbers
        np.testing.assert_allclose(cm.residuals(q), res, rtol=0, atol=1e-15)
        np.testing.assert_allclose(cm.jacobian(q), jac, rtol=0, atol=1e-15)
    # the same q is not closed on another configuration: the check can fail
    q_open = q.copy()
    q_open[cm.actuated[0]] += 1e-3
    assert np.max(np.abs(pinocchio_residuals(cm, q_open)[0])) > 1e-4


def test_perturbed_closed_chain_satisfies_the_perturbed_constraints(mech):
    nominal = mech.constraint_models()
    home = ClosedChain(mech).inverse(POINTS[1])
    for seed in (1, 2):
        models, offsets = perturbed(mech, 1e-5, seed)
        chain = ClosedChain(mech, models=models, check_limits=False)
        actual = chain.forward(home.q_all[chain.actuated_idx], home.q_all, offsets)
        cm = mech.constraint_models(models)
        q = cm.q(actual.q)
        assert np.max(np.abs(pinocchio_residuals(cm, q)[0])) < 1e-10
        # the errors are in the constraints: the nominal ones see the perturbation (~1e-5)
        assert np.max(np.abs(pinocchio_residuals(nominal, q)[0])) > 1e-7


def test_frame_anchor_jacobian_is_the_derivative_of_the_residual(mech):
    # Pinocchio 4's FrameAnchorConstraintModel: J = +d(log6(oMc1⁻¹ oMc2))/dq at a closed q (the legacy
    # RigidConstraintModel has the opposite sign); central differences, step 1e-6
    cm = mech.constraint_models()
    q = cm.q(ClosedChain(mech).inverse(POINTS[2]).q)
    jac = pinocchio_residuals(cm, q)[1]
    rng = np.random.default_rng(5)
    for _ in range(3):
        d = rng.standard_normal(q.size)
        h = 1e-6
        fd = (cm.residuals(q + h * d) - cm.residuals(q - h * d)) / (2 * h)
        assert np.max(np.abs(fd - jac @ d)) < 1e-7 * np.max(np.abs(jac @ d))
    # the legacy RigidConstraintModel that constraintDynamics takes (pkmtol's rigid_constraints):
    # once each is evaluated (calc), its Jacobian is exactly minus the FrameAnchor one. Without calc
    # getConstraintsJacobian silently returns another matrix: that pitfall is checked too
    data = cm.model.createData()
    rigid = pin.StdVec_RigidConstraintModel()
    for r in cm.rigid_constraints():
        rigid.append(r)
    fresh = pin.StdVec_RigidConstraintData()
    for r in rigid:
        fresh.append(r.createData())
    pin.computeJointJacobians(cm.model, data, q)
    assert np.max(np.abs(pin.getConstraintsJacobian(cm.model, data, rigid, fresh) + jac)) > 1e-2
    rdatas = pin.StdVec_RigidConstraintData()
    for r in rigid:
        rdatas.append(r.createData())
        r.calc(cm.model, data, rdatas[len(rdatas) - 1])
    jr = pin.getConstraintsJacobian(cm.model, data, rigid, rdatas)
    np.testing.assert_allclose(jr, -jac, rtol=0, atol=1e-15)


def _orthonormal(a: np.ndarray) -> np.ndarray:
    u, s, _ = np.linalg.svd(a, full_matrices=False)
    return u[:, s > 1e-9 * s[0]]


@pytest.mark.parametrize("perturb", [False, True], ids=["nominal", "perturbed"])
def test_constraint_jacobian_allows_the_motions_pkmtols_wrenches_allow(mech, perturb):
    """What "spans the same motion space" means here, at each pose:

    * Pinocchio's side: the joint velocities its constraints allow, ``N = null(J)`` with ``J`` from
      ``getConstraintsJacobian``, moved to the platform: ``V = T_1 N_1`` (``T_1`` the reference limb's
      joint twists in K', ``N_1`` its rows of ``N``) — the platform twists of the constrained
      mechanism;
    * pkmtol's side: the twists reciprocal to every constraint wrench, ``null(W_cᵀ)`` with ``W_c``
      from :func:`pkmtol.error_model.separation.separate`;
    * the two subspaces of R⁶ have the same dimension (the mobility, 3 here) and their orthogonal
      projectors differ by less than 1e-9 in the spectral norm (the sine of the largest principal
      angle between them).
    """
    models, offsets = perturbed(mech, 1e-5, 7) if perturb else (None, None)
    chain = ClosedChain(mech, models=models, check_limits=False)
    pset = parameter_set(mech, "urdf")
    nominal = ClosedChain(mech)
    cm = mech.constraint_models(models)
    for p in POINTS:
        pose = nominal.inverse(p)
        if perturb:
            pose = chain.forward(pose.q_all[chain.actuated_idx], pose.q_all, offsets)
        sep = separate(mech, pset, chain, pose)
        jac = pinocchio_residuals(cm, cm.q(pose.q))[1]
        n = null_space(jac)
        v = sep.joint_twists[0] @ n[cm.q_slices[0]]
        a = _orthonormal(v)
        b = null_space(sep.W_c.T)
        assert a.shape[1] == b.shape[1] == 3
        assert np.linalg.norm(a @ a.T - b @ b.T, 2) < 1e-9
        # and the reverse reading: every constraint wrench does no work on those twists
        assert np.max(np.abs(sep.W_c.T @ v)) < 1e-9 * np.max(np.abs(v))


def test_a_wrong_jacobian_fails_the_span_test(mech):
    # planted error: drop limb 4's loop (the one that constrains the platform) from Pinocchio's side
    chain = ClosedChain(mech)
    pose = chain.inverse(POINTS[0])
    sep = separate(mech, parameter_set(mech, "urdf"), chain, pose)
    cm = mech.constraint_models()
    jac = pinocchio_residuals(cm, cm.q(pose.q))[1][:12]
    v = sep.joint_twists[0] @ null_space(jac)[cm.q_slices[0]]
    assert _orthonormal(v).shape[1] == 6 != null_space(sep.W_c.T).shape[1]


def test_platform_inertia_is_counted_once(tmp_path):
    # every limb URDF carries the platform link: with 5 kg on it and 1 kg on each limb's first link,
    # the one model weighs 5 + 4 × 1 kg, not 4 × 6 kg
    folder = tmp_path / "heavy"
    shutil.copytree(SEED, folder)
    inertial = '<inertial><origin xyz="0.01 0 0.02" /><mass value="{m}" />' + (
        '<inertia ixx="0.1" iyy="0.2" izz="0.3" ixy="0" ixz="0" iyz="0" /></inertial>'
    )
    for i in (1, 2, 3, 4):
        path = folder / f"limb{i}.urdf"
        text = path.read_text(encoding="utf-8")
        text = text.replace('<link name="platform">', '<link name="platform">' + inertial.format(m=5))
        text = text.replace(f'<link name="limb{i}_l1">', f'<link name="limb{i}_l1">' + inertial.format(m=1))
        path.write_text(text, encoding="utf-8")
    mech = load_mechanism(folder)
    assert [pin.computeTotalMass(lb.model) for lb in mech.limbs] == [6.0, 6.0, 6.0, 6.0]
    cm = mech.constraint_models()
    assert pin.computeTotalMass(cm.model) == pytest.approx(9.0, abs=1e-12)
    last = [cm.model.frames[f].parentJoint for f in cm.platform_frames]
    masses = [cm.model.inertias[j].mass for j in last]
    assert masses[0] == pytest.approx(5.0) and masses[1:] == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    # the reference limb's last body keeps the platform's full inertia (lever and rotational part)
    ref = mech.limbs[0].model
    np.testing.assert_allclose(cm.model.inertias[last[0]].matrix(), ref.inertias[ref.njoints - 1].matrix())


def test_mjcf_mass_is_the_mjcf_models():
    mech = load_mechanism(MJCF)
    mjcf_model = pin.buildModelFromMJCF(str(MJCF / "robot.xml"))
    assert pin.computeTotalMass(mech.constraint_models().model) == pytest.approx(
        pin.computeTotalMass(mjcf_model), rel=1e-14
    )


def test_joint_names_shared_by_limbs_get_the_limb_name(tmp_path):
    models = [pin.buildModelFromUrdf(str(SEED / f"limb{i}.urdf")) for i in (1, 2, 3, 4)]
    for m in models[1:]:  # every limb's first joint called "u1"
        m.names[1] = "u1"
    models[0].names[1] = "u1"
    mech = Mechanism.from_models(
        "same_names",
        models,
        actuated=[["limb1_p3"], ["limb2_p3"], ["limb3_p3"], []],
        platform_frame="platform",
        reference_point_m=[0.0, 0.0, 0.3],
        task_space=load_mechanism(SEED).task_space,
        homes=[lb.home for lb in load_mechanism(SEED).limbs],
    )
    cm = mech.constraint_models()
    names = list(cm.model.names[1:])
    assert names[0] == "limb1/u1" and names[6] == "limb2/u1" and names[-1] == "limb4/limb4_p3"
    assert len(set(names)) == 21


def test_bad_requests(mech):
    cm = mech.constraint_models()
    with pytest.raises(InvalidRequestError, match="one joint vector per limb"):
        cm.q([np.zeros(6)])
    models = [lb.model for lb in mech.limbs]
    with pytest.raises(URDFError, match="3 limb models for 4 limbs"):
        constraint_models(mech, models[:3])
    with pytest.raises(URDFError, match="not the limb's"):
        constraint_models(mech, [models[1], models[0], models[2], models[3]])
