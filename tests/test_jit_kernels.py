"""The compiled kernels (numba, the ``fast`` extra) against the batched solver's numpy path.

The same closure rows, Jacobians and inverses to round-off on every bundled robot, nominal and
perturbed, inverse and forward; the same solutions and errors from whole solves; and the switch
that turns the kernels off."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol.error_model.parameters import parameter_set
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.kinematics import acceleration
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.continuation import continuation
from pkmtol.kinematics.frame_tables import FrameTables
from pkmtol.kinematics.stacked_solve import newton_steps
from pkmtol.model.loader import load_mechanism

jit_kernels = pytest.importorskip("pkmtol.kinematics.jit_kernels", reason="numba is not installed")

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = sorted(p.parent for p in (ROOT / "robots").glob("*/mechanism.toml"))


@pytest.fixture(scope="module", params=ROBOTS, ids=lambda p: p.name)
def robot(request):
    mech = load_mechanism(request.param)
    chain = ClosedChain(mech)
    grid = mech.task_space.grid()
    return mech, chain, grid, continuation(BatchChain(mech, chain=chain), grid, chain.home())


def systems(batch: BatchChain, q, targets, perturbation=None):
    """``_system`` at ``q`` with the kernels and without: two (res, jac, near) triples."""
    ev = batch.frames.evaluate(q, np.arange(len(q)), perturbation)
    with_kernels = batch._system(ev, targets)
    original = acceleration.kernels
    acceleration.kernels = lambda: None
    try:
        without = batch._system(ev, targets)
    finally:
        acceleration.kernels = original
    return with_kernels, without


def test_closure_rows_match_the_numpy_path(robot):
    mech, chain, grid, sols = robot
    batch = BatchChain(mech, chain=chain)
    rng = np.random.default_rng(0)
    q = sols.q[sols.ok] + rng.standard_normal((int(sols.ok.sum()), batch.n_joints)) * 0.05
    targets = grid[sols.ok] + rng.standard_normal((len(q), 3)) * 0.01
    for t in (targets, None):  # inverse (task rows) and forward problems
        (res, jac, near), (res_np, jac_np, near_np) = systems(batch, q, t)
        np.testing.assert_allclose(res, res_np, rtol=0, atol=1e-13)
        np.testing.assert_allclose(jac, jac_np, rtol=0, atol=1e-12 * np.abs(jac_np).max())
        assert near.tolist() == near_np.tolist()
        assert not near.any()


def test_closure_rows_match_the_numpy_path_on_perturbed_machines(robot):
    mech, chain, _, sols = robot
    batch = BatchChain(mech, chain=chain, check_limits=False)
    pset = parameter_set(mech, "urdf")
    rng = np.random.default_rng(1)
    q = sols.q[sols.ok][:20]
    eps, _ = pset.perturbations(rng.standard_normal((len(q), len(pset))) * 1e-3, mech)
    perturbation = batch.frames.perturb(eps, len(q))
    (res, jac, near), (res_np, jac_np, near_np) = systems(batch, q, None, perturbation)
    assert np.abs(res_np).max() > 1e-5  # the errors open the closures
    np.testing.assert_allclose(res, res_np, rtol=0, atol=1e-13)
    np.testing.assert_allclose(jac, jac_np, rtol=0, atol=1e-12 * np.abs(jac_np).max())
    assert near.tolist() == near_np.tolist()


def test_a_half_turn_is_flagged_as_in_numpy():
    # two limbs whose platform frames are a half turn (minus 1e-4 rad) and a quarter turn apart
    rng = np.random.default_rng(2)
    b = 2
    h = np.zeros((2, b, 4, 4))
    h[:, :] = np.eye(4)
    h[1, 0, :3, :3] = pin.exp3(np.array([0.0, 0.0, np.pi - 1e-4]))
    h[1, 1, :3, :3] = pin.exp3(np.array([np.pi / 2, 0.0, 0.0]))
    h[1, :, :3, 3] = rng.standard_normal((b, 3))
    padded = rng.standard_normal((2, b, 6, 3))
    res, jac, near = np.zeros((b, 6)), np.zeros((b, 6, 6)), np.zeros(b, dtype=bool)
    jit_kernels.closure_rows(h, padded, np.array([0, 3, 6]), np.zeros(3), np.zeros((0, 3)), 6, res, jac, near)
    assert near.tolist() == [True, False]
    # the quarter turn's rows are Pinocchio's log6 and Jacobian
    e = pin.SE3(h[1, 1])
    np.testing.assert_allclose(res[1], pin.log6(e).vector, rtol=0, atol=1e-14)
    jl = pin.Jlog6(e)
    np.testing.assert_allclose(jac[1][:, 3:], jl @ padded[1, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(jac[1][:, :3], -(jl @ e.toActionMatrixInverse()) @ padded[0, 1], atol=1e-12)


def test_inverses_match_numpy_and_flag_singular_matrices():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((30, 21, 21)) + 4.0 * np.eye(21)
    a[7, :, 4] = 0.0  # a zero column: singular
    out = np.empty_like(a)
    singular = np.zeros(len(a), dtype=bool)
    jit_kernels.inverses(a, out, singular)
    assert np.flatnonzero(singular).tolist() == [7]
    ok = ~singular
    np.testing.assert_allclose(out[ok], np.linalg.inv(a[ok]), rtol=0, atol=1e-13 * np.abs(out[ok]).max())


def test_the_python_sources_compute_what_the_compiled_kernels_do():
    rng = np.random.default_rng(4)
    a = rng.standard_normal((3, 6, 6))
    out, out_py = np.empty_like(a), np.empty_like(a)
    flags, flags_py = np.zeros(3, dtype=bool), np.zeros(3, dtype=bool)
    jit_kernels.inverses(a, out, flags)
    jit_kernels.inverses.py_func(a, out_py, flags_py)
    np.testing.assert_allclose(out_py, out, rtol=1e-13, atol=0)
    for theta in (1e-6, 0.3, 1.0, 3.0):
        axis = rng.standard_normal(3)
        e = pin.SE3(pin.exp3(theta * axis / np.linalg.norm(axis)), rng.standard_normal(3))
        nu, jl, nu_py, jl_py = np.empty(6), np.empty((6, 6)), np.empty(6), np.empty((6, 6))
        jit_kernels._log6(e.rotation, e.translation, nu, jl)
        jit_kernels._log6.py_func(e.rotation, e.translation, nu_py, jl_py)
        np.testing.assert_allclose(nu_py, nu, rtol=0, atol=1e-15)
        np.testing.assert_allclose(jl_py, jl, rtol=0, atol=1e-14)
        np.testing.assert_allclose(nu, pin.log6(e).vector, rtol=0, atol=1e-13)
    assert jit_kernels._coefficients.py_func(0.7) == pytest.approx(jit_kernels._coefficients(0.7), rel=1e-15)


def test_solutions_are_those_of_the_numpy_path(robot, monkeypatch):
    mech, chain, grid, sols = robot
    pset = parameter_set(mech, "urdf")
    rng = np.random.default_rng(5)
    q0 = sols.q[sols.ok][:24]
    eta = rng.standard_normal((len(q0), len(pset))) * 1e-5
    eps, offsets = pset.perturbations(eta, mech)
    u = q0[:, chain.actuated_idx]
    fwd = BatchChain(mech, check_limits=False).forward(u, q0, offsets, eps)
    monkeypatch.setattr(acceleration, "kernels", lambda: None)
    ref = continuation(BatchChain(mech, chain=ClosedChain(mech)), grid, chain.home())
    fwd_ref = BatchChain(mech, check_limits=False).forward(u, q0, offsets, eps)
    for got, want in ((sols, ref), (fwd, fwd_ref)):
        assert [type(e).__name__ for e in got.errors] == [type(e).__name__ for e in want.errors]
        ok = want.ok
        np.testing.assert_allclose(got.q[ok], want.q[ok], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.condition[ok], want.condition[ok], rtol=1e-9)
        np.testing.assert_allclose(got.system_inverse[ok], want.system_inverse[ok], rtol=0, atol=1e-9)
    assert sols.ok.sum() > 0.9 * len(grid)


def test_the_kernels_can_be_turned_off(monkeypatch):
    load = acceleration.kernels.__wrapped__  # without the per-process cache
    monkeypatch.delenv(acceleration.ENVIRONMENT, raising=False)
    assert load() is jit_kernels
    for off in ("0", "off", "False", " no "):
        monkeypatch.setenv(acceleration.ENVIRONMENT, off)
        assert load() is None
    for on in ("1", "", "yes", "ON"):
        monkeypatch.setenv(acceleration.ENVIRONMENT, on)
        assert load() is jit_kernels
    monkeypatch.setenv(acceleration.ENVIRONMENT, "fals")
    with pytest.raises(InvalidArgumentError, match=r"PKMTOL_JIT = 'fals': set it to 0 .* or 1"):
        load()
    monkeypatch.setenv(acceleration.ENVIRONMENT, "1")
    monkeypatch.setitem(sys.modules, "pkmtol.kinematics.jit_kernels", None)  # as without numba
    assert load() is None

    def no_cache_directory(name):
        raise RuntimeError(f"cannot cache function: no locator available for file '{name}'")

    monkeypatch.setattr(acceleration.importlib, "import_module", no_cache_directory)
    assert load() is None


def test_frames_are_pinocchios_nominal_and_perturbed(robot):
    mech = robot[0]
    models = [lb.model for lb in mech.limbs]
    frames = [(i, lb.platform_frame) for i, lb in enumerate(mech.limbs)] + [
        (i, f) for i, lb in enumerate(mech.limbs) for lp in lb.loops for f in (lp.frame_a, lp.frame_b)
    ]
    tables = FrameTables.of(models, frames)
    rng = np.random.default_rng(6)
    b, n = 12, len(tables.parent)
    q = rng.uniform(-1.0, 1.0, (b, n))
    eps = rng.standard_normal((b, n, 6)) * 1e-3
    eps[0] = 0.0  # a nominal machine in the table: exactly the nominal placements
    table = tables.perturbed(jit_kernels, eps)
    np.testing.assert_array_equal(table[0], tables.placements[0])
    offsets = np.cumsum([0] + [m.nq for m in models])
    machines = []
    for s in range(b):
        limbs = []
        for i, m in enumerate(models):
            pm = m.copy()
            for j in range(1, m.njoints):
                pm.jointPlacements[j] = m.jointPlacements[j] * pin.exp6(eps[s, offsets[i] + j - 1])
                np.testing.assert_allclose(
                    table[s, offsets[i] + j - 1], pm.jointPlacements[j].homogeneous, atol=1e-15
                )
            limbs.append(pm)
        machines.append(limbs)
    rows = np.array([0, 3, 5, 11])
    for tab, which, perturbed in (
        (tables.placements, np.zeros(b, dtype=np.int64), False),
        (table, np.arange(b), True),
    ):
        h, jac = tables.evaluate(jit_kernels, q, rows, tab, which)
        for pos, s in enumerate(rows):
            for f, (i, fid) in enumerate(frames):
                m = machines[s][i] if perturbed else models[i]
                data = m.createData()
                pin.computeJointJacobians(m, data, q[s, offsets[i] : offsets[i + 1]])
                np.testing.assert_allclose(
                    h[f, pos], pin.updateFramePlacement(m, data, fid).homogeneous, atol=1e-14
                )
                want = pin.getFrameJacobian(m, data, fid, pin.LOCAL)
                np.testing.assert_allclose(jac[f, pos, :, : m.nq], want, atol=1e-14)
                assert not jac[f, pos, :, m.nq :].any()


def test_newton_steps_match_lapack_and_flag_singular_matrices():
    rng = np.random.default_rng(7)
    a = rng.standard_normal((40, 21, 21)) + 4.0 * np.eye(21)
    a[3, :, 4] = 0.0  # a zero column: singular, solved in the least-squares sense as numpy's path does
    r = rng.standard_normal((40, 21))
    steps = np.empty_like(r)
    singular = np.zeros(len(a), dtype=bool)
    jit_kernels.solve_steps(a, r, steps, singular)
    assert np.flatnonzero(singular).tolist() == [3]
    ok = ~singular
    np.testing.assert_allclose(
        steps[ok], np.linalg.solve(a[ok], r[ok][..., None])[..., 0], rtol=1e-10, atol=1e-12
    )
    compiled = newton_steps(a, r, compiled=True)
    np.testing.assert_allclose(compiled, newton_steps(a, r), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(compiled[3], np.linalg.lstsq(a[3], r[3], rcond=None)[0], rtol=0, atol=1e-12)


def test_frames_of_every_kind_of_one_dof_joint_are_pinocchios():
    # unaligned and x/y/z revolute and prismatic joints, a branch (a tree limb) and a frame on the
    # root, in the second of two limbs (its joints start after the first limb's)
    rng = np.random.default_rng(8)

    def placement():
        return pin.SE3(pin.exp3(rng.standard_normal(3)), rng.standard_normal(3))

    def unit():
        v = rng.standard_normal(3)
        return v / np.linalg.norm(v)

    model = pin.Model()
    parent = 0
    for k, joint in enumerate(
        [pin.JointModelRX(), pin.JointModelRevoluteUnaligned(unit()), pin.JointModelPY()]
        + [pin.JointModelPrismaticUnaligned(unit())]
    ):
        parent = model.addJoint(parent, joint, placement(), f"j{k}")
    branch = model.addJoint(2, pin.JointModelRZ(), placement(), "b0")  # off the second joint
    branch = model.addJoint(branch, pin.JointModelPX(), placement(), "b1")
    tip = model.addFrame(pin.Frame("tip", parent, 0, placement(), pin.FrameType.OP_FRAME))
    side = model.addFrame(pin.Frame("side", branch, 0, placement(), pin.FrameType.OP_FRAME))
    base = model.addFrame(pin.Frame("base", 0, 0, placement(), pin.FrameType.OP_FRAME))
    first = build_first_limb(rng)
    models = [first, model]
    frames = [(0, first.nframes - 1), (1, tip), (1, side), (1, base), (0, 0)]
    tables = FrameTables.of(models, frames)
    offsets = [0, first.nq, first.nq + model.nq]
    q = rng.uniform(-2.0, 2.0, (5, offsets[-1]))
    eps = rng.standard_normal((5, offsets[-1], 6)) * 1e-2
    nominal = (tables.placements, np.zeros(5, dtype=np.int64))
    for tab, which in (nominal, (tables.perturbed(jit_kernels, eps), np.arange(5))):
        h, jac = tables.evaluate(jit_kernels, q, np.arange(5), tab, which)
        for s in range(5):
            for f, (i, fid) in enumerate(frames):
                m = models[i].copy()
                for j in range(1, m.njoints):
                    m.jointPlacements[j] = pin.SE3(tab[which[s], offsets[i] + j - 1])
                data = m.createData()
                pin.computeJointJacobians(m, data, q[s, offsets[i] : offsets[i + 1]])
                want = pin.updateFramePlacement(m, data, fid).homogeneous
                np.testing.assert_allclose(h[f, s], want, atol=1e-13)
                want_jac = pin.getFrameJacobian(m, data, fid, pin.LOCAL)
                np.testing.assert_allclose(jac[f, s, :, : m.nq], want_jac, atol=1e-13)


def build_first_limb(rng: np.random.Generator) -> pin.Model:
    """A three-joint serial limb (RY, PZ, RX) ending in a frame."""
    model = pin.Model()
    parent = 0
    for k, joint in enumerate([pin.JointModelRY(), pin.JointModelPZ(), pin.JointModelRX()]):
        parent = model.addJoint(
            parent, joint, pin.SE3(pin.exp3(rng.standard_normal(3)), rng.standard_normal(3)), f"a{k}"
        )
    model.addFrame(
        pin.Frame(
            "end",
            parent,
            0,
            pin.SE3(pin.exp3(rng.standard_normal(3)), rng.standard_normal(3)),
            pin.FrameType.OP_FRAME,
        )
    )
    return model


def test_a_subset_of_machines_keeps_its_placements_on_either_path(robot, monkeypatch):
    # the second solve of failed problems takes a subset of the machines onto slot models
    mech, chain, _, sols = robot
    pset = parameter_set(mech, "urdf")
    eta = np.random.default_rng(9).standard_normal((6, len(pset))) * 1e-4
    eps, _ = pset.perturbations(eta, mech)
    index = np.array([4, 1])
    compiled = BatchChain(mech, check_limits=False).frames
    sub = compiled.slots_of(compiled.perturb(eps, 6), index)
    monkeypatch.setattr(acceleration, "kernels", lambda: None)
    plain = BatchChain(mech, check_limits=False).frames
    full = plain.perturb(eps, 6)
    sub_plain = plain.slots_of(full, index)
    for i in range(len(mech.limbs)):
        for pos, k in enumerate(index):
            assert sub_plain.models[i][pos] is full.models[i][k]
            for j in range(1, mech.limbs[i].model.njoints):
                np.testing.assert_allclose(
                    sub.models[i][pos].jointPlacements[j].homogeneous,
                    sub_plain.models[i][pos].jointPlacements[j].homogeneous,
                    atol=1e-15,
                )
        assert (sub.attach[i] is None) == (sub_plain.attach[i] is None)
        if sub.attach[i] is not None:
            np.testing.assert_array_equal(sub.attach[i], sub_plain.attach[i])


def test_a_misspelt_switch_is_refused_by_the_command(tmp_path):
    env = {**os.environ, acceleration.ENVIRONMENT: "maybe"}
    out = tmp_path / "out"
    cmd = [
        sys.executable,
        "-m",
        "pkmtol.cli",
        "allocate",
        str(ROOT / "robots" / "r2rps_ups"),
        "--out",
        str(out),
    ]
    run = subprocess.run([*cmd, "--no-figures", "--no-progress"], capture_output=True, text=True, env=env)
    assert run.returncode != 0
    assert "PKMTOL_JIT = 'maybe': set it to 0" in run.stderr
    assert "Traceback" not in run.stderr
    assert not (out / "allocation.json").exists()
