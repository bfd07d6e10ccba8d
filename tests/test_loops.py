"""Loops inside limbs: the Delta, a slider-crank in a limb, the reduction to limb-wise ones, derivatives.

The truth test (DESIGN.md) on mechanisms whose loops do not all close on the platform; the general
layer against today's on every bundled robot; finite differences of every new derivative (the loop
rows, their error columns, the eliminated columns E' and the motion space T̃).
"""

from __future__ import annotations

import shutil

import numpy as np
import pinocchio as pin
import pytest
from loop_robots import ROOT, delta_script, delta_variant, merged, slider_crank_variant
from truth_checks import compensatable_residual_ratios, linear_mismatches

from pkmtol.error_model.limb_motion import loop_motion, raw_rows_many, to_k_prime_many
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.separation import separate
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.error_model.twists import pose_error_twist
from pkmtol.exceptions import LoopMismatchError, MechanismFormatError, URDFError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.loops import frame_placements, loop_rows
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.loader import load_mechanism

ROBOTS = sorted(p.parent for p in (ROOT / "robots").glob("*/mechanism.toml"))
DELTA = ROOT / "robots" / "delta"


@pytest.fixture(scope="module")
def delta():
    mech = load_mechanism(DELTA)
    return mech, ClosedChain(mech)


@pytest.fixture(scope="module")
def variants(tmp_path_factory):
    """The loop mechanisms of the truth test: the Delta (3d), its 6d variant, the slider-crank seed robot."""
    base = tmp_path_factory.mktemp("loops")
    return {
        "delta": DELTA,
        "delta_6d": delta_variant(base / "delta_6d", "6d"),
        "slider_crank": slider_crank_variant(base / "slider_crank"),
    }


# --- the truth test on mechanisms with loops inside limbs ----------------------------------------


@pytest.mark.parametrize("name", ["delta", "delta_6d", "slider_crank"])
def test_truth_test_on_loops_inside_limbs(variants, name):
    """Exact pose error = twist_map η, and after Eq. 25 = uncompensated_map η; second order in η.

    At 20 random poses with η ~ 1e-6 both mismatches are ≤ 1e-3, and at every pose they are 10 times
    their size at η ~ 1e-5 (± 10 %): the linear model is exact to first order.
    """
    mech = load_mechanism(variants[name])
    ps = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    rng = np.random.default_rng(7)
    q = chain.home()
    worst = 0.0
    for p in mech.task_space.sample(rng, 20):
        pose = chain.inverse(p, q)
        sep = separate(mech, ps, chain, pose)
        eta0 = rng.normal(0.0, 1.0, len(ps))
        rel = [linear_mismatches(mech, ps, chain, pose, sep, eta0 * size) for size in (1e-5, 1e-6)]
        worst = max(worst, *rel[1])
        assert rel[0][0] / rel[1][0] == pytest.approx(10.0, rel=0.1)
        assert rel[0][1] / rel[1][1] == pytest.approx(10.0, rel=0.1)
    assert worst <= 1e-3


@pytest.mark.parametrize("name", ["delta", "slider_crank"])
def test_compensatable_errors_vanish_after_eq25(variants, name):
    """Truth test step 3: only compensatable errors, corrected: ≤ 1e-3 of the uncorrected pose error."""
    mech = load_mechanism(variants[name])
    ps = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    classes = sweep(mech, ps, mech.task_space.grid(), chain).classify()
    rng = np.random.default_rng(11)
    ratios = compensatable_residual_ratios(mech, chain, ps, classes, mech.task_space.sample(rng, 10), rng)
    assert max(ratios) <= 1e-3


# --- the Delta -------------------------------------------------------------------------------------


def test_delta_files_are_those_the_script_writes():
    for path, text in delta_script().generate(DELTA).items():
        assert path.read_text(encoding="utf-8") == text, f"{path} is stale: run python scripts/delta_urdf.py"


def test_delta_classes(delta):
    """The parallelogram errors: what is absorbed, compensatable, uncompensatable (docs/robots.md)."""
    mech, chain = delta
    ps = parameter_set(mech, "urdf")
    grid = sweep(mech, ps, mech.task_space.grid(), chain)
    cls = dict(zip(ps.names, grid.classify(), strict=True))
    counts = {c: list(cls.values()).count(c) for c in ("absorbed", "compensatable", "uncompensatable")}
    assert counts == {"absorbed": 105, "compensatable": 25, "uncompensatable": 65}
    for i in (1, 2, 3):
        a = f"arm{i}"
        # the motor's zero, and every error that moves the whole arm along the actuated motion
        assert cls[f"{a}.{a}_mot.offset"] == "compensatable"
        assert cls[f"{a}.{a}_mot.ry"] == "compensatable"
        assert cls[f"{a}.{a}_platform_attach.dz"] == "compensatable"
        # a rod's length and the elbow's width tilt the platform: seen by the arm's constraint couple
        assert cls[f"{a}.rod2.dz"] == "uncompensatable"
        assert cls[f"{a}.{a}_rod1_s1.dz"] == "uncompensatable"
        assert cls[f"{a}.{a}_rod1_u1.dx"] == "uncompensatable"
        # the point of rod 2 across the rod, every passive joint's zero, a shift along a U's own axis
        assert cls[f"{a}.rod2.dx"] == cls[f"{a}.rod2.dy"] == "absorbed"
        assert cls[f"{a}.{a}_rod2_u1.offset"] == cls[f"{a}.{a}_rod1_s3.offset"] == "absorbed"
        assert cls[f"{a}.{a}_rod1_u2.dy"] == "absorbed"
    # the platform only translates: no error class leaves the compensated twist a rotation-free part
    pose = grid.poses[0]
    sep = grid.separations[0]
    assert sep.W_c.shape[1] == 3 and np.linalg.matrix_rank(sep.W_c[3:], tol=1e-9) == 3
    assert np.allclose(sep.W_c[:3], 0.0, atol=1e-12)  # each arm's constraint wrench is a pure couple
    np.testing.assert_allclose(pose.oMp.rotation, np.eye(3), atol=1e-12)


def test_delta_loop_mismatch_names_the_loop(tmp_path):
    folder = shutil.copytree(DELTA, tmp_path / "delta")
    toml = folder / "mechanism.toml"
    text = toml.read_text(encoding="utf-8")
    toml.write_text(
        text.replace('frames = ["arm2_rod2_socket"', 'frames = ["arm2_rod1_end_x"', 1), encoding="utf-8"
    )
    with pytest.raises(URDFError, match="no frame 'arm2_rod1_end_x'"):
        load_mechanism(folder)
    # rod 2 of arm 3 ending 5 mm short: its loop is open at home
    urdf = folder / "arm3.urdf"
    body = urdf.read_text(encoding="utf-8")
    toml.write_text(text, encoding="utf-8")
    marker = '<joint name="arm3_rod2_end_fix" type="fixed">\n    <origin xyz="0 0 0.8"'
    assert marker in body
    urdf.write_text(body.replace(marker, marker.replace("0.8", "0.795")), encoding="utf-8")
    with pytest.raises(LoopMismatchError, match=r"limb 'arm3': its loop 'rod2' .*\(gap 5 mm"):
        load_mechanism(folder)


# --- the general layer reduces to the limb-wise one ---------------------------------------------


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda p: p.name)
def test_general_layer_reduces_to_the_limb_wise_one(robot):
    """Every limb through the loop-elimination path (T̃, E'): today's maps and classes to 1e-10."""
    mech = load_mechanism(robot)
    ps = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    points = mech.task_space.grid()[::6]
    today = sweep(mech, ps, points, chain)
    general = [separate(mech, ps, chain, pose, general=True) for pose in today.poses]
    for a, b in zip(today.separations, general, strict=True):
        for field in ("twist_map", "correction", "uncompensated_map", "J", "J_total", "actuation_map"):
            np.testing.assert_allclose(
                getattr(b, field), getattr(a, field), rtol=0, atol=1e-10, err_msg=field
            )
        np.testing.assert_allclose(b.Lambda_a, a.Lambda_a, rtol=1e-10)
        assert b.redundancy == a.redundancy
    again = Sweep(points, today.poses, tuple(general), today.J, today.J_total, today.W_condition)
    assert again.classify() == today.classify()


@pytest.mark.parametrize(
    ("robot", "into", "other"), [("r2rps_ups", 0, 3), ("r2rps_ups", 2, 3), ("tricept", 1, 3)]
)
def test_a_limb_rewritten_as_an_internal_loop_gives_the_same_mechanism(robot, into, other):
    """A passive limb merged into another as a branch closed by a 6D loop: same poses (1e-12), same
    twist maps (1e-10) for the same parameters (renamed).

    The split is not compared: the merged limb is actuated *and* constrained, so its actuation
    wrench is orthogonal to more constraint wrenches than the original limb's (docs/theory.md).
    """
    mech = load_mechanism(ROOT / "robots" / robot)
    other_mech, rename = merged(mech, into, other)
    ps, pg = parameter_set(mech, "urdf"), parameter_set(other_mech, "urdf")
    assert len(ps) == len(pg)
    idx = [pg.names.index(rename[n]) for n in ps.names]
    c, cg = ClosedChain(mech), ClosedChain(other_mech)
    q, qg = c.home(), cg.home()
    for p in mech.task_space.grid()[::7]:
        pose, pose_g = c.inverse(p, q), cg.inverse(p, qg)
        np.testing.assert_allclose(pose_g.oMp.homogeneous, pose.oMp.homogeneous, rtol=0, atol=1e-12)
        s, sg = separate(mech, ps, c, pose), separate(other_mech, pg, cg, pose_g)
        np.testing.assert_allclose(sg.twist_map[:, idx], s.twist_map, rtol=0, atol=1e-10)
        np.testing.assert_allclose(sg.J_total[:, idx], s.J_total, rtol=0, atol=1e-10)


# --- finite differences of the new derivatives -------------------------------------------------


def _loop_limbs(variants):
    out = []
    for name in ("delta", "delta_6d", "slider_crank"):
        mech = load_mechanism(variants[name])
        out += [(mech, i) for i, lb in enumerate(mech.limbs) if lb.loops][:1]
    return out


def _loop_residual(limb, model, q):
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    rows = [loop_rows(lp, *frame_placements(model, data, lp)) for lp in limb.loops]
    return np.concatenate([r[0] for r in rows]), np.vstack([r[1] for r in rows])


def test_loop_rows_match_finite_differences(variants):
    """∂r/∂q of 6D (log6 · Jlog6) and 3D (p_b − p_a) loops, away from closure too."""
    rng = np.random.default_rng(4)
    h = 1e-6
    for mech, i in _loop_limbs(variants):
        limb = mech.limbs[i]
        q = limb.home + rng.normal(0.0, 0.05, limb.nq)  # the loops are open here
        res, jac = _loop_residual(limb, limb.model, q)
        assert np.abs(res).max() > 1e-3
        fd = np.column_stack(
            [
                (
                    _loop_residual(limb, limb.model, q + h * e)[0]
                    - _loop_residual(limb, limb.model, q - h * e)[0]
                )
                / (2 * h)
                for e in np.eye(limb.nq)
            ]
        )
        np.testing.assert_allclose(jac, fd, atol=1e-8)


def test_raw_error_columns_of_loops_match_finite_differences(variants):
    """The platform columns E_P and the loop columns D of every raw error (joint origins, attachment,
    loop frame b, offsets) against central differences of the perturbed limb models."""
    rng = np.random.default_rng(5)
    h = 1e-6
    for mech, i in _loop_limbs(variants):
        limb = mech.limbs[i]
        q = limb.home + rng.normal(0.0, 0.05, limb.nq)
        e_p, _, _, d, _ = raw_rows_many(limb, limb.model, limb.model.createData(), q[None])
        data = limb.model.createData()
        pin.framesForwardKinematics(limb.model, data, q)
        oMp = data.oMf[limb.platform_frame].copy()
        for k in range(limb.n_raw):
            fd_p, fd_r = [], []
            for sign in (1.0, -1.0):
                raw = np.zeros(limb.n_raw)
                raw[k] = sign * h
                eps = [np.zeros((lb.n_origins, 6)) for lb in mech.limbs]
                eps[i] = raw[: 6 * limb.n_origins].reshape(-1, 6)
                model = perturbed_limb_models(mech, eps)[i]
                qk = q + raw[6 * limb.n_origins :]
                dk = model.createData()
                pin.framesForwardKinematics(model, dk, qk)
                fd_p.append(pin.log6(oMp.actInv(dk.oMf[limb.platform_frame])).vector)
                fd_r.append(_loop_residual(limb, model, qk)[0])
            np.testing.assert_allclose((fd_p[0] - fd_p[1]) / (2 * h), e_p[0, :, k], atol=1e-8, err_msg=str(k))
            np.testing.assert_allclose((fd_r[0] - fd_r[1]) / (2 * h), d[0, :, k], atol=1e-8, err_msg=str(k))


def _reclose(limb, model, q, free):
    """Close the limb's loops by minimum-norm Gauss–Newton steps on the joints ``free``."""
    q = q.copy()
    for _ in range(30):
        res, jac = _loop_residual(limb, model, q)
        if np.abs(res).max() < 1e-15:
            break
        q[free] -= np.linalg.pinv(jac[:, free]) @ res
    return q


def test_motion_space_and_eliminated_columns_match_finite_differences(variants):
    """T̃ and E' against exact re-closure of the limb's loops (minimum-norm passive motion).

    E'_k: perturb raw error k, close the loops again with the actuator held; T̃_0: move the actuator,
    close again; T̃'s passive columns: move the passive joints along T̃'s null-space basis, close again.
    """
    rng = np.random.default_rng(6)
    h = 1e-6
    for mech, i in _loop_limbs(variants):
        limb = mech.limbs[i]
        chain = ClosedChain(mech)
        pose = chain.inverse(mech.task_space.sample(rng, 1)[0], chain.home())
        q = pose.q[i]
        rot = pose.oMp.rotation[None]
        sel = np.eye(limb.n_raw)
        lm = loop_motion(limb, limb.model, limb.model.createData(), q[None], rot, sel, pose.p_m[None])
        passive = np.array(limb.passive)

        def twist(model, qk, pose=pose, limb=limb):
            d = model.createData()
            pin.framesForwardKinematics(model, d, qk)
            return pose_error_twist(pose.oMp, d.oMf[limb.platform_frame])

        # E': each raw error, the loops closed again by the passive joints
        for k in range(limb.n_raw):
            fd = []
            for sign in (1.0, -1.0):
                raw = np.zeros(limb.n_raw)
                raw[k] = sign * h
                eps = [np.zeros((lb.n_origins, 6)) for lb in mech.limbs]
                eps[i] = raw[: 6 * limb.n_origins].reshape(-1, 6)
                model = perturbed_limb_models(mech, eps)[i]
                qk = _reclose(limb, model, q + raw[6 * limb.n_origins :], passive)
                fd.append(twist(model, qk))
            np.testing.assert_allclose(
                (fd[0] - fd[1]) / (2 * h), lm.errors[0][:, k], atol=1e-7, err_msg=str(k)
            )
        # T̃_0: the actuator moved, the loops closed again
        a = limb.actuated[0]
        fd = []
        for sign in (1.0, -1.0):
            qk = q.copy()
            qk[a] += sign * h
            fd.append(twist(limb.model, _reclose(limb, limb.model, qk, passive)))
        np.testing.assert_allclose((fd[0] - fd[1]) / (2 * h), lm.twists[0][:, 0], atol=1e-7)
        # the passive columns: closed passive motions (their joint directions from the loops' null space)
        _, jac = _loop_residual(limb, limb.model, q)
        _, sv, vt = np.linalg.svd(jac[:, passive])
        null = vt[int(np.sum(sv > 1e-9 * sv[0])) :].T
        j_p = to_k_prime_many(
            rot,
            np.array(
                pin.computeFrameJacobian(
                    limb.model, limb.model.createData(), q, limb.platform_frame, pin.LOCAL
                )
            )[None],
        )[0]
        for v in null.T:
            fd = []
            for sign in (1.0, -1.0):
                qk = q.copy()
                qk[passive] += sign * h * v
                fd.append(twist(limb.model, _reclose(limb, limb.model, qk, passive)))
            np.testing.assert_allclose((fd[0] - fd[1]) / (2 * h), j_p[:, passive] @ v, atol=1e-7)
        # which span T̃'s passive columns: the same motion space
        span = lm.twists[0][:, 1:]
        moves = j_p[:, passive] @ null
        assert np.linalg.matrix_rank(np.hstack([span, moves]), tol=1e-9) == np.linalg.matrix_rank(
            span, tol=1e-9
        )


# --- model and format checks -----------------------------------------------------------------------


def test_a_tree_without_loops_and_a_stray_branch_are_refused(tmp_path):
    folder = shutil.copytree(DELTA, tmp_path / "delta")
    toml = folder / "mechanism.toml"
    text = toml.read_text(encoding="utf-8")
    start = text.index("[[limbs.loops]]")
    end = text.index("[[limbs]]", start)
    toml.write_text(text[:start] + text[end:], encoding="utf-8")
    with pytest.raises(URDFError, match="branches: a limb without internal loops must be a serial chain"):
        load_mechanism(folder)
    # a branch whose end is in no loop
    toml.write_text(
        text.replace(
            'frames = ["arm1_rod2_socket", "arm1_rod2_end"]', 'frames = ["arm1_rod2_socket", "arm1_rod1"]'
        ),
        encoding="utf-8",
    )
    with pytest.raises(URDFError, match="joint 'arm1_rod2_u1' lies on no path"):
        load_mechanism(folder)
    toml.write_text(text.replace('type = "3d"', 'type = "2d"', 1), encoding="utf-8")
    with pytest.raises(MechanismFormatError, match=r"limbs\[0\]\.loops\[0\]\.type"):
        load_mechanism(folder)
    toml.write_text(
        text.replace(
            'frames = ["arm1_rod2_socket", "arm1_rod2_end"]', 'frames = ["arm1_rod2_end", "platform"]'
        ),
        encoding="utf-8",
    )
    with pytest.raises(URDFError, match="is the platform frame or another loop's"):
        load_mechanism(folder)
    toml.write_text(text.replace('name = "rod2"', 'name = "arm1_mot"', 1), encoding="utf-8")
    with pytest.raises(URDFError, match="also a joint, frame or loop name"):
        load_mechanism(folder)
    toml.write_text(
        text.replace('frames = ["arm1_rod2_socket", "arm1_rod2_end"]', 'frames = ["arm1_rod2_socket"]'),
        encoding="utf-8",
    )
    with pytest.raises(MechanismFormatError, match="expected two frame names"):
        load_mechanism(folder)


# --- the closed-loop imports: loops inside limbs, point loops ----------------------------------


def _script(name: str):
    import importlib.util
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("form", ["limbs_to_closed_loop", "limbs_to_mjcf"])
def test_delta_read_from_one_tree_is_the_same_mechanism(tmp_path, delta, form):
    """The Delta written as one URDF tree (3d loops in the sidecar) or one MJCF file (<connect>):
    the cut gives each arm its rod-2 loop back, the same poses (1e-12), twist maps, corrections and
    J (1e-10) and classes, parameters renamed (loops and attachments take the tree's loop names)."""
    mech, chain = delta
    for name, text in _script(form).generate(DELTA).items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    tree = load_mechanism(tmp_path)
    assert [lb.name for lb in tree.limbs] == ["arm1", "arm2", "arm3"]
    assert [(lp.kind, lp.frame_names) for lb in tree.limbs for lp in lb.loops] == [
        ("3d", (f"arm{i}_rod2_socket", f"arm{i}_rod2_end")) for i in (1, 2, 3)
    ]
    ps, pt = parameter_set(mech, "urdf"), parameter_set(tree, "urdf")
    assert len(ps) == len(pt)
    rename = {}
    for a, b in zip(mech.limbs, tree.limbs, strict=True):
        for old, new in [(a.attach_name, b.attach_name)] + [
            (la.name, lb_.name) for la, lb_ in zip(a.loops, b.loops, strict=True)
        ]:
            for comp in ("dx", "dy", "dz", "rx", "ry", "rz"):
                rename[f"{a.name}.{old}.{comp}"] = f"{b.name}.{new}.{comp}"
    idx = [pt.names.index(rename.get(n, n)) for n in ps.names]
    tchain = ClosedChain(tree)
    points = mech.task_space.grid()[::9]
    a, b = sweep(mech, ps, points, chain), sweep(tree, pt, points, tchain)
    for sa, sb in zip(a.separations, b.separations, strict=True):
        np.testing.assert_allclose(sb.pose.q_all, sa.pose.q_all, rtol=0, atol=1e-12)
        for field in ("twist_map", "correction", "J", "J_total"):
            np.testing.assert_allclose(getattr(sb, field)[:, idx], getattr(sa, field), rtol=0, atol=1e-10)
    assert [b.classify()[k] for k in idx] == a.classify()


# --- export: the mechanism as one tree plus constraint models ----------------------------------


def test_delta_exports_its_internal_loops_as_point_anchors(delta):
    """One pin.Model plus 2 frame anchors (arms 2, 3 on the platform) and 3 point anchors (the rods 2):
    pkmtol's closed solutions, nominal and perturbed, satisfy them; their Jacobian allows the platform
    motions pkmtol's constraint wrenches allow (the translations)."""
    from pkmtol.error_model.separation import null_space

    mech, chain = delta
    cm = mech.constraint_models()
    assert [type(c).__name__ for c in cm.constraints] == ["FrameAnchorConstraintModel"] * 2 + [
        "PointAnchorConstraintModel"
    ] * 3
    assert [c.name for c in cm.constraints][2:] == ["arm1.rod2", "arm2.rod2", "arm3.rod2"]
    ps = parameter_set(mech, "urdf")
    pose = chain.inverse(np.array([0.2, -0.1, -0.95]), chain.home())
    q = cm.q(pose.q)
    res = cm.residuals(q)
    assert res.shape == (21,) and np.abs(res).max() < 1e-12
    jac = cm.jacobian(q)
    n = null_space(jac)
    data = mech.limbs[0].model.createData()
    j0 = pin.computeFrameJacobian(
        mech.limbs[0].model, data, pose.q[0], mech.limbs[0].platform_frame, pin.LOCAL
    )
    v = to_k_prime_many(pose.oMp.rotation[None], np.array(j0)[None])[0] @ n[cm.q_slices[0]]
    u, s, _ = np.linalg.svd(v, full_matrices=False)
    a = u[:, s > 1e-9 * s[0]]
    sep = separate(mech, ps, chain, pose)
    b = null_space(sep.W_c.T)
    assert a.shape[1] == b.shape[1] == 3
    assert np.linalg.norm(a @ a.T - b @ b.T, 2) < 1e-9
    # a perturbed Delta, closed by pkmtol, closes Pinocchio's perturbed constraints (and not the nominal)
    eta = np.random.default_rng(1).normal(0.0, 1e-5, len(ps))
    eps, offsets = ps.perturbation(eta, mech)
    models = perturbed_limb_models(mech, eps)
    actual = ClosedChain(mech, models, check_limits=False).forward(
        pose.q_all[chain.actuated_idx], pose.q_all, offsets
    )
    assert np.abs(mech.constraint_models(models).residuals(cm.q(actual.q))).max() < 1e-12
    assert np.abs(cm.residuals(cm.q(actual.q))).max() > 1e-7


def test_delta_calibrated_urdfs_carry_the_loop_errors(tmp_path, delta):
    """Calibrated URDFs of the Delta (every raw error, loops' too) reload as the perturbed machine."""
    from pkmtol.calibration.machine import Machine
    from pkmtol.calibration.urdf_export import calibrated_toml, calibrated_urdfs

    mech, chain = delta
    ps = parameter_set(mech, "urdf")
    estimate = np.random.default_rng(2).normal(0.0, 1e-4, len(ps))
    for name, text in calibrated_urdfs(mech, ps, estimate).items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    (tmp_path / "mechanism.toml").write_text(calibrated_toml(mech, ps, estimate), encoding="utf-8")
    calibrated = load_mechanism(tmp_path)
    assert [lp.name for lb in calibrated.limbs for lp in lb.loops] == ["rod2"] * 3
    machine = Machine(mech, ps, estimate)
    pose = chain.inverse(np.array([0.15, 0.1, -0.9]), chain.home())
    u = pose.q_all[chain.actuated_idx]
    truth = machine.forward(u, pose.q_all)
    cchain = ClosedChain(calibrated, check_limits=False)
    # the zero offsets are in the calibrated joint origins: the same readings, readings = actual − offset
    again = cchain.forward(u, truth.q_all - machine.offsets)
    np.testing.assert_allclose(again.p_m, truth.p_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(again.oMp.rotation, truth.oMp.rotation, rtol=0, atol=1e-12)
