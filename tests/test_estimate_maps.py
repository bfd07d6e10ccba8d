"""The identification's Jacobian at the estimate against finite differences of the exact machine."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol.calibration.estimate_maps import twist_maps_at
from pkmtol.calibration.gauss_newton import solved_poses
from pkmtol.calibration.machine import Machine
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.error_model.twists import pose_error_twist
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]


def _perturbed_case(robot: str, kind: str, poses: int, seed: int):
    mech = load_mechanism(ROOT / "robots" / robot)
    pset = parameter_set(mech, kind)
    chain = ClosedChain(mech)
    pts = mech.task_space.grid()
    grid = sweep(mech, pset, pts[np.linspace(0, len(pts) - 1, poses).astype(int)], chain)
    # 1 mm and 5 mrad: ten times the manufacturing errors, so the nominal maps are visibly wrong
    sig = np.where(np.array(pset.units) == "m", 1e-3, 5e-3)
    delta = np.random.default_rng(seed).standard_normal(len(pset)) * sig
    q0 = np.array([p.q_all for p in grid.poses])
    return mech, pset, grid, Machine(mech, pset, delta), q0[:, chain.actuated_idx], q0


def _fd_twists(mech, pset, machine, commands, q, h=1e-7):
    """Central differences of the exact platform pose error twist (K') per unit parameter."""
    sols = solved_poses(machine, commands, q)
    base = [pin.SE3(sols.rotation[k], sols.translation[k]) for k in range(len(commands))]
    out = np.empty((len(commands), 6, len(pset)))
    for j in range(len(pset)):
        cols = []
        for sign in (1.0, -1.0):
            d = machine.delta.copy()
            d[j] += sign * h
            s = solved_poses(Machine(mech, pset, d), commands, sols.q)
            moved = [pin.SE3(s.rotation[k], s.translation[k]) for k in range(len(base))]
            cols.append(np.array([pose_error_twist(b, m) for b, m in zip(base, moved, strict=True)]))
        out[:, :, j] = (cols[0] - cols[1]) / (2 * h)
    return sols, out


@pytest.mark.parametrize(
    ("robot", "kind"),
    [("r2rps_ups", "dh"), ("r2rps_ups", "urdf"), ("tricept", "urdf"), ("delta", "urdf")],
)
def test_twist_maps_at_the_estimate_match_finite_differences(robot, kind):
    mech, pset, grid, machine, commands, q = _perturbed_case(robot, kind, poses=4, seed=3)
    sols, fd = _fd_twists(mech, pset, machine, commands, q)
    at = twist_maps_at(machine, sols)
    assert at is not None and at.shape == fd.shape
    scale = np.abs(fd).max()
    assert np.abs(at - fd).max() <= 1e-6 * scale
    # the nominal maps are what the frozen iteration used: off by the errors' first order, here far
    # beyond the check's tolerance (so the check could tell one from the other)
    nominal = np.array([s.twist_map for s in grid.separations])
    assert np.abs(nominal - fd).max() > 1e-3 * scale


def test_twist_maps_at_the_nominal_machine_are_the_error_models():
    mech, pset, grid, _, commands, q = _perturbed_case("tricept", "urdf", poses=3, seed=0)
    nominal = Machine(mech, pset, np.zeros(len(pset)))
    at = twist_maps_at(nominal, solved_poses(nominal, commands, q))
    assert at is not None
    np.testing.assert_allclose(at, np.array([s.twist_map for s in grid.separations]), atol=1e-9)


@pytest.mark.parametrize(("robot", "kind"), [("r2rps_ups_wrist", "dh"), ("tricept_wrist", "urdf")])
def test_hybrid_tcp_twist_at_the_estimate_matches_finite_differences(robot, kind):
    """The whole machine's TCP twist (module shifted to the TCP, and the tool chain's columns)."""
    from pkmtol.calibration.plan import candidate_pool
    from pkmtol.calibration.settings import CalibrationSettings
    from pkmtol.error_model.task import grid_sweep, machine_parameter_set

    mech = load_mechanism(ROOT / "robots" / robot)
    pset = machine_parameter_set(mech, kind)
    grid = grid_sweep(mech, pset)
    pool = candidate_pool(mech, pset, CalibrationSettings(candidates=30), grid=grid)
    idx = np.linspace(0, len(pool) - 1, 4).astype(int)
    commands, q = pool.commands[idx], pool.q[idx]
    sig = np.where(np.array(pset.units) == "m", 1e-3, 5e-3)
    machine = Machine(mech, pset, np.random.default_rng(2).standard_normal(len(pset)) * sig)
    sols, fd = _fd_twists(mech, pset, machine, commands, q)
    at = twist_maps_at(machine, sols)
    assert at is not None and at.shape == fd.shape
    scale = np.abs(fd).max()
    assert np.abs(at - fd).max() <= 1e-6 * scale
    assert np.abs(pool.twist[idx] - fd).max() > 1e-3 * scale  # the nominal TCP maps: visibly off
