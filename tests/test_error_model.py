"""The error model against exact kinematics (DESIGN.md, "The truth test") and finite differences."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from truth_checks import compensatable_residual_ratios, linear_mismatches

from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.separation import null_space, separate
from pkmtol.error_model.sweep import sweep
from pkmtol.error_model.twists import raw_columns_local
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = sorted(p.parent for p in (ROOT / "robots").glob("*/mechanism.toml"))
SEED = ROOT / "robots" / "r2rps_ups"

TABLE_IV_ETA_C = [
    "δθ_{1,4}",
    "δd_{1,4}",
    "δa_{1,4}",
    "δφ_{1,4}",
    "δd_{2,4}",
    "δa_{2,4}",
    "δφ_{2,4}",
    "δd_{3,4}",
    "δa_{3,4}",
    "δφ_{3,4}",
    "δθ_{4,4}",
    "δa_{4,4}",
    "δφ_{4,4}",
    "δθ_{e,4}",
]


@pytest.fixture(scope="module")
def seed():
    mech = load_mechanism(SEED)
    return mech, ClosedChain(mech)


@pytest.fixture(scope="module")
def seed_classes(seed):
    mech, chain = seed
    out = {}
    for kind in ("dh", "urdf"):
        ps = parameter_set(mech, kind)
        out[kind] = (ps, sweep(mech, ps, mech.task_space.grid(), chain).classify())
    return out


def _compatible_basis(mech, ps, chain) -> np.ndarray:
    """Orthonormal basis (n, k) of the errors whose incompatible part vanishes at every grid pose.

    An over-constrained mechanism assembles (to first order) only with these errors; stacked over
    the task-space grid, the incompatible maps leave the errors with which it assembles *and moves*.
    """
    grid = sweep(mech, ps, mech.task_space.grid(), chain)
    return null_space(np.vstack([s.incompatible_map for s in grid.separations]))


def _assemble(mech, ps, pose, sep, eta, u):
    """Make first-order-compatible errors ``eta`` assemble exactly near ``pose`` with actuators ``u``.

    The closure equations of an over-constrained mechanism are redundant: with compatible errors
    they are consistent only to first order, and Newton cannot close the O(η²) rest. Move ``eta``
    along the incompatible directions of this pose (the row space of ``sep.incompatible_map``, as
    many as the redundancy) by the second-order amount ``D α`` that closes them: Newton on the
    passive joints and ``α`` together (square), ``∂r/∂α`` by finite differences.

    Returns:
        ``(eta + D α, q)``: the corrected errors and the closed joint values.
    """
    _, sv, vt = np.linalg.svd(sep.incompatible_map)
    d = vt[: int(np.sum(sv > 1e-9 * sv[0]))].T
    act = ClosedChain(mech).actuated_idx
    free = np.ones(pose.q_all.size, dtype=bool)
    free[act] = False
    q, alpha, h = pose.q_all.copy(), np.zeros(d.shape[1]), 1e-7

    def closure(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        eps, offsets = ps.perturbation(eta + d @ a, mech)
        pert = ClosedChain(mech, perturbed_limb_models(mech, eps), check_limits=False)
        qa = q.copy()
        qa[act] = u + offsets[act]
        res, jac = pert._evaluate(qa, None)
        return res.copy(), jac[:, free].copy()

    for _ in range(20):
        res, jac_q = closure(alpha)
        if np.max(np.abs(res)) < 1e-14:
            break
        jac_a = np.column_stack([(closure(alpha + h * e)[0] - res) / h for e in np.eye(alpha.size)])
        step = np.linalg.solve(np.hstack([jac_q, jac_a]), res)
        q[free] -= step[: free.sum()]
        alpha -= step[free.sum() :]
    assert np.max(np.abs(res)) < 1e-14
    return eta + d @ alpha, q


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda p: p.name)
@pytest.mark.parametrize("kind", ["urdf", "dh"])
def test_truth_steps_1_2(robot, kind):
    """Exact pose error of a perturbed mechanism = W^-T [Λξ + Gη; G_c η_c]; after Eq. 25 = W^-T [0; G_c η_c].

    Over-constrained mechanisms (redundant wrenches) assemble only with compatible errors: η is
    drawn in the null space of the incompatible maps stacked over the grid, then closed exactly
    at the pose by a second-order correction (``_assemble``, docs/theory.md).
    """
    mech = load_mechanism(robot)
    if kind == "dh" and any(lb.dh is None for lb in mech.limbs):
        pytest.skip("no D–H tables")
    ps = parameter_set(mech, kind)
    chain = ClosedChain(mech)
    rng = np.random.default_rng(7)
    points = mech.task_space.sample(rng, 20)
    q = chain.home()
    worst1 = worst2 = 0.0
    compatible = None
    for p in points:
        pose = chain.inverse(p, q)
        sep = separate(mech, ps, chain, pose)
        eta = rng.normal(0.0, 1e-5, len(ps))
        u = pose.q_all[chain.actuated_idx]
        q_start = pose.q_all
        if sep.redundancy > 0:
            if compatible is None:
                compatible = _compatible_basis(mech, ps, chain)
            drawn = compatible @ (compatible.T @ eta)
            assert np.linalg.norm(sep.incompatible_map @ drawn) <= 1e-9 * np.linalg.norm(sep.Y_c @ drawn)
            eta, q_start = _assemble(mech, ps, pose, sep, drawn, u)
            assert np.linalg.norm(eta - drawn) <= 1e-4 * np.linalg.norm(drawn)  # second order only
        r1, r2 = linear_mismatches(mech, ps, chain, pose, sep, eta, q_start)
        worst1, worst2 = max(worst1, r1), max(worst2, r2)
    assert worst1 <= 1e-3
    assert worst2 <= 1e-3


@pytest.mark.parametrize("kind", ["urdf", "dh"])
def test_truth_step_3_compensatable_errors_vanish(seed, seed_classes, kind):
    """Only compensatable errors + the Eq. 25 correction: residual ≤ 1e-3 of the uncorrected error."""
    mech, chain = seed
    ps, classes = seed_classes[kind]
    rng = np.random.default_rng(11)
    ratios = compensatable_residual_ratios(mech, chain, ps, classes, mech.task_space.sample(rng, 20), rng)
    assert max(ratios) <= 1e-3


@pytest.mark.parametrize("kind", ["urdf", "dh"])
def test_error_columns_match_finite_differences(seed, kind):
    """Every parameter's local error column = central difference of the perturbed limb's platform pose."""
    mech, _ = seed
    ps = parameter_set(mech, kind)
    rng = np.random.default_rng(3)
    h = 1e-6
    for i, limb in enumerate(mech.limbs):
        q = limb.home + rng.normal(0, 0.1, limb.nq)
        data = limb.model.createData()
        raw, _, oMp = raw_columns_local(limb, limb.model, data, q)
        cols = raw @ ps.selections[i]
        for k in range(cols.shape[1]):
            fd = []
            for sign in (1.0, -1.0):
                eta = np.zeros(len(ps))
                eta[ps.slices[i].start + k] = sign * h
                eps, offsets = ps.perturbation(eta, mech)
                model = perturbed_limb_models(mech, eps)[i]
                d = model.createData()
                qi = q + offsets[sum(lb.nq for lb in mech.limbs[:i]) :][: limb.nq]
                pin.framesForwardKinematics(model, d, qi)
                fd.append(pin.log6(oMp.actInv(d.oMf[limb.platform_frame])).vector)
            np.testing.assert_allclose(
                (fd[0] - fd[1]) / (2 * h), cols[:, k], atol=1e-7, err_msg=ps.names[ps.slices[i].start + k]
            )


def test_table_iv_uncompensatable_set(seed_classes):
    ps, classes = seed_classes["dh"]
    unc = [n for n, c in zip(ps.names, classes, strict=True) if c == "uncompensatable"]
    assert unc == TABLE_IV_ETA_C


@pytest.mark.parametrize("kind", ["urdf", "dh"])
def test_only_limb4_is_uncompensatable(seed, seed_classes, kind):
    mech, _ = seed
    ps, classes = seed_classes[kind]
    limbs = {ps.parameters[i].limb for i, c in enumerate(classes) if c == "uncompensatable"}
    assert limbs == {3}
    # the passive joints' zero offsets of limb 4 (and the offset along its slide) are absorbed
    assert classes[ps.names.index("δθ_{2,4}" if kind == "dh" else "limb4.limb4_u1.offset")] == "absorbed"
    # every actuator offset is compensatable
    assert all(classes[i] == "compensatable" for i, p in enumerate(ps.parameters) if p.actuator)


def test_limb4_constraint_wrenches_span_closed_form(seed):
    """W_c of limb 4 spans the paper's §4.2 closed form ($wc,1,4 = (0; n1), ...)."""
    mech, chain = seed
    ps = parameter_set(mech, "dh")
    rng = np.random.default_rng(5)
    q = chain.home()
    limb = mech.limbs[3]
    for p in mech.task_space.sample(rng, 10):
        pose = chain.inverse(p, q)
        sep = separate(mech, ps, chain, pose)
        wc = sep.W_c[:, sep.constraint_limb == 3]
        assert wc.shape[1] == 3
        data = limb.model.createData()
        pin.forwardKinematics(limb.model, data, pose.q[3])
        z1, z2, z3 = (data.oMi[j].rotation[:, 2] for j in (1, 2, 3))
        xi3 = pose.q[3][2]
        # The paper prints n_{2,4} = ẑ_{1,4} × ẑ_{3,4}; for a U joint ẑ_1 ⟂ ẑ_2 and the slide
        # ẑ_3 ⟂ ẑ_2, so that product is parallel to ẑ_2 and the printed basis would have rank 2.
        # The constraint force it means is the one perpendicular to both ẑ_2 and the slide.
        assert np.linalg.norm(np.cross(np.cross(z1, z3), z2)) < 1e-12
        n1, n2 = np.cross(z1, z2), np.cross(z2, z3)
        closed = np.column_stack(
            [np.r_[np.zeros(3), n1], np.r_[z2, -xi3 * np.cross(z3, z2)], np.r_[n2, -xi3 * np.cross(z3, n2)]]
        )
        assert np.linalg.matrix_rank(closed, tol=1e-9) == 3
        # each closed-form wrench lies in span(W_c) and vice versa
        proj = wc @ np.linalg.lstsq(wc, closed, rcond=None)[0]
        np.testing.assert_allclose(proj, closed, atol=1e-10)
        assert np.linalg.matrix_rank(np.hstack([wc, closed]), tol=1e-9) == 3


def test_wrenches_are_reciprocal(seed):
    """Constraint wrenches annihilate all joint twists of their limb; actuation wrenches the passive ones."""
    mech, chain = seed
    ps = parameter_set(mech, "urdf")
    pose = chain.inverse(mech.task_space.grid()[20], chain.home())
    sep = separate(mech, ps, chain, pose)
    for k, i in enumerate(sep.constraint_limb):
        np.testing.assert_allclose(sep.W_c[:, k] @ sep.joint_twists[i], 0.0, atol=1e-12)
    for k, i in enumerate(sep.actuated_limb):
        passive = list(mech.limbs[i].passive)
        np.testing.assert_allclose(sep.W_a[:, k] @ sep.joint_twists[i][:, passive], 0.0, atol=1e-12)
        assert sep.Lambda_a[k] > 1e-3


def test_truth_residual_is_second_order(seed):
    """The linear model's error shrinks in proportion to the perturbation: it is exact to first order.

    With η scaled by 1/10 the relative mismatch must drop by 10 (± 5 %), at every pose — a wrong
    column would leave a size-independent mismatch instead.
    """
    mech, chain = seed
    ps = parameter_set(mech, "dh")
    rng = np.random.default_rng(13)
    q = chain.home()
    for p in mech.task_space.sample(rng, 5):
        pose = chain.inverse(p, q)
        sep = separate(mech, ps, chain, pose)
        eta0 = rng.normal(0.0, 1.0, len(ps))
        rel = [linear_mismatches(mech, ps, chain, pose, sep, eta0 * size)[1] for size in (1e-5, 1e-6)]
        assert rel[0] / rel[1] == pytest.approx(10.0, rel=0.05)
