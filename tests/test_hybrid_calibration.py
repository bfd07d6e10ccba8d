"""Calibration of a hybrid machine (a tracker on the TCP) against exact kinematics (docs/hybrid.md).

The whole machine's calibration reuses the module's pipeline with the TCP frame as its "platform":
the maps are the TCP's (``ToolSeparation``), the machine is the module and the tool chain solved
exactly (:class:`pkmtol.calibration.hybrid_machine.HybridMachine`), the poses are TCP points × tool
axes, and the controller re-solves the whole task (TCP and tool axis) with its identified model.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol.calibration.compensation import controller_commands, pose_errors
from pkmtol.calibration.holdout import holdout_poses
from pkmtol.calibration.hybrid_export import calibrated_files
from pkmtol.calibration.hybrid_machine import HybridMachine
from pkmtol.calibration.hybrid_poses import with_tracker_on
from pkmtol.calibration.identification import identify, identify_with, machine_poses, model_positions
from pkmtol.calibration.instrument_files import instrument_csv
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.maps import pose_maps
from pkmtol.calibration.measurement_files import measurements_csv
from pkmtol.calibration.plan import candidate_pool, make_plan
from pkmtol.calibration.postcal import calibrated_maps
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.calibration.study import calibrate_and_evaluate
from pkmtol.calibration.urdf_export import write_calibrated_folder
from pkmtol.cli import main
from pkmtol.design.exact import grid_reliability
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.design.modes import mode_setup
from pkmtol.error_model.task import grid_sweep, machine_parameter_set
from pkmtol.error_model.tool_sweep import ToolSweep
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism
from pkmtol.statistics import wilson_interval

ROOT = Path(__file__).resolve().parents[1]
HYBRID = ROOT / "robots" / "r2rps_ups_wrist"
PLAN = CalibrationSettings(poses=30, candidates=60)


@pytest.fixture(scope="module")
def hybrid():
    mech = load_mechanism(HYBRID)
    pset = machine_parameter_set(mech, "dh")
    grid = grid_sweep(mech, pset)
    classes = grid.classify()
    settings = CalibrationSettings(candidates=60)
    pool = candidate_pool(mech, pset, settings, grid=grid)
    return mech, pset, grid, classes, settings, pool


def _identify(mech, pset, plan, y):
    return identify(
        mech, pset, plan.ident, plan.H, plan.maps.commands, plan.maps.q, y, plan.targets_m, plan.prior_sigma
    )


def _tilt(rotations, rotation_errors):
    """Angle between the nominal tool axis (z of the TCP frame) and the actual one [rad]."""
    out = []
    for r, th in zip(rotations, rotation_errors, strict=True):
        a, b = r[:, 2], pin.exp3(th) @ r[:, 2]
        out.append(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))
    return np.array(out)


def test_pool_is_the_tcp_task_and_the_nominal_machine_reproduces_it(hybrid):
    """The pool's poses are the TCP's; the nominal machine's exact kinematics put the TCP there."""
    mech, pset, grid, classes, settings, pool = hybrid
    assert isinstance(Machine(mech, pset, np.zeros(len(pset))), HybridMachine)
    assert len(pool) > len(grid.points_m) and pool.task_rows.shape == (len(pool), 5, 6)
    assert pool.commands.shape[1] == 3 + 2  # the module's actuators, then the wrist's
    nominal = Machine(mech, pset, np.zeros(len(pset)))
    sols = nominal.forward_many(pool.commands, pool.q)
    assert sols.ok.all()
    np.testing.assert_allclose(sols.translation, pool.points_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sols.rotation, pool.rotations, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pool.points_m[: len(grid.points_m)], grid.points_m, rtol=0, atol=1e-12)
    # the tool axis (z of the TCP frame) is the target axis of every grid pose
    np.testing.assert_allclose(pool.rotations[: len(grid.points_m), :, 2], grid.axes, rtol=0, atol=1e-12)
    # the default tracker target is the TCP itself
    np.testing.assert_array_equal(settings.targets(mech), np.zeros((1, 3)))


def test_measurement_jacobian_matches_finite_differences_of_the_exact_machine(hybrid):
    """``H`` (the TCP's error model) against central differences of the exact hybrid kinematics."""
    mech, pset, grid, classes, settings, pool = hybrid
    plan = make_plan(mech, pset, classes, CalibrationSettings(controller="full"), pool, poses=20)
    rng = np.random.default_rng(4)
    module = [c for c in plan.ident.columns if c < pset.module_count]
    tool = [c for c in plan.ident.columns if c >= pset.module_count]
    cols = list(rng.choice(module, 8, replace=False)) + tool
    h = 1e-6
    for c in cols:
        d = np.zeros(len(pset))
        d[c] = h
        yp, _ = model_positions(Machine(mech, pset, d), plan.maps.commands, plan.maps.q, plan.targets_m)
        d[c] = -h
        ym, _ = model_positions(Machine(mech, pset, d), plan.maps.commands, plan.maps.q, plan.targets_m)
        fd = ((yp - ym) / (2 * h)).reshape(-1)
        np.testing.assert_allclose(
            plan.H[:, c], fd, rtol=0, atol=1e-7 * max(1.0, np.abs(fd).max()), err_msg=pset.names[c]
        )


def test_actuation_map_is_the_twist_of_every_actuator_offset(hybrid):
    """A command change moves the TCP as the actuator's zero offset does: module's and wrist's."""
    mech, pset, grid, classes, settings, pool = hybrid
    act = [i for i, p in enumerate(pset.parameters) if p.actuator]
    assert [pset.names[i] for i in act[-2:]] == ["wrist.wrist_c.offset", "wrist.wrist_a.offset"]
    np.testing.assert_allclose(pool.actuation, pool.twist[:, :, act], rtol=0, atol=1e-12)


def test_controller_inverse_kinematics_is_the_machines_own(hybrid):
    """The commands a perturbed machine computes for a target put its own TCP there, along the axis."""
    mech, pset, grid, classes, settings, pool = hybrid
    held = pool.subset(np.arange(0, len(pool), 40))
    rng = np.random.default_rng(5)
    for part in (slice(0, pset.module_count), slice(pset.module_count, len(pset))):
        delta = np.zeros(len(pset))
        delta[part] = rng.standard_normal(delta[part].size) * 1e-4
        machine = Machine(mech, pset, delta)
        u, ok = controller_commands(machine, held.points_m, held.q)
        err = pose_errors(machine, u, held.q, held.points_m, held.rotations)
        assert ok.all() and err.solved.all()
        assert np.abs(err.position_m).max() < 1e-11
        assert _tilt(held.rotations, err.rotation_rad).max() < 1e-11
        assert np.abs(u - held.commands).max() > 1e-6  # it did correct the commands


def test_noise_free_identification_recovers_the_base_parameters(hybrid):
    mech, pset, grid, classes, settings, pool = hybrid
    plan = make_plan(mech, pset, classes, settings, pool, poses=40)
    assert plan.ident.rank == plan.pool_rank and plan.ident.rank > 0
    rng = np.random.default_rng(11)
    delta = np.zeros(len(pset))
    scale = np.where(np.array(pset.units) == "m", 1e-4, 5e-4)
    b = plan.ident.base_columns
    assert any(i >= pset.module_count for i in b)  # the wrist's and the tool's parameters are identified
    delta[b] = rng.standard_normal(b.size) * scale[b]
    y, _ = model_positions(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q, plan.targets_m)
    res = _identify(mech, pset, plan, y)
    beta = plan.ident.true_base_values(delta)
    assert res.converged
    assert np.linalg.norm(res.identified - beta) <= 1e-8 * np.linalg.norm(beta)
    assert res.rms_after_m <= 1e-12 < res.rms_before_m


def test_calibrated_machine_matches_the_linear_model_to_second_order(hybrid):
    """Compensatable errors only, no noise: the TCP error left after calibration is ``L δ`` (second order)."""
    mech, pset, grid, classes, settings, pool = hybrid
    plan = make_plan(mech, pset, classes, settings, pool, poses=40)
    ho = holdout_poses(mech, pset, 30, np.random.default_rng(8))
    maps = calibrated_maps(ho.maps, plan.H, plan.ident)
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    direction = np.zeros(len(pset))
    direction[comp] = np.random.default_rng(2).standard_normal(len(comp))
    gaps = []
    for size in (1e-5, 1e-6):
        delta = direction * size
        true = Machine(mech, pset, delta)
        y, _ = model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
        res = _identify(mech, pset, plan, y)
        u, ok = controller_commands(Machine(mech, pset, res.estimate), ho.maps.points_m, ho.maps.q)
        err = pose_errors(true, u, ho.maps.q, ho.maps.points_m, ho.maps.rotations)
        before = pose_errors(true, ho.maps.commands, ho.maps.q, ho.maps.points_m, ho.maps.rotations)
        assert ok.all() and err.solved.all()
        lin_p = np.einsum("kin,n->ki", maps.position, delta)
        lin_r = np.einsum("kin,n->ki", maps.rotation, delta)
        # the TCP position is identified: nothing is left of it to first order
        assert np.abs(lin_p).max() < 1e-9 * size / 1e-5
        assert np.abs(err.position_m).max() < 1e-3 * np.abs(before.position_m).max()
        # the tool axis is not seen by a tracker on the TCP: what is left of it is the linear model's
        gap = np.abs(err.rotation_rad - lin_r).max()
        assert gap <= 1e-3 * np.abs(lin_r).max()
        gaps.append(gap)
    assert gaps[0] / gaps[1] > 5  # second order: a tenth of the errors, a hundredth of the gap


@pytest.fixture(scope="module")
def calibrated_design():
    """``allocate --compensation calibrated --compensate-with module`` of the hybrid (a fast run)."""
    mech = load_mechanism(HYBRID)
    mech = dataclasses.replace(mech, extra={**mech.extra, "tool_scope": "module"})
    opts = DesignOptions(
        compensation="calibrated",
        calibration=PLAN,
        samples=2000,
        verification_poses=100,
        exact_samples=20,
        claim_poses=20,
    )
    return mech, allocate(mech, opts)


def test_calibrated_allocation_tolerances_what_the_calibration_leaves(calibrated_design):
    mech, r = calibrated_design
    assert r.compensation == "calibrated" and isinstance(r.grid, ToolSweep)
    ident = r.calibration_plan.ident
    for c in ident.base_columns:
        assert r.mode_classes[c] == "identified"
        assert np.abs(r.maps.position[:, :, c]).max() <= 1e-12
    assert r.uncompensatable.size > 0
    for i in r.uncompensatable:
        assert r.mode_classes[i] == "toleranced" and np.abs(r.maps.position[:, :, i]).max() > 1e-9
    groups = {r.pset.sub_assembly(i) for i in r.uncompensatable}
    assert groups == {"module", "wrist", "tool"}
    assert np.all(np.isfinite(r.tolerances[r.uncompensatable, r.design_column]))


def test_calibrated_design_point_fails_as_often_as_claimed_on_exact_kinematics(calibrated_design):
    """Machines at the printed tolerances, calibrated by the plan on exact kinematics, at the design point.

    FOSM claims R = Φ(β) at the design point for the linear model with the noise; each machine is
    drawn at the tolerances (the identified errors at their manufacturing σ), measured at the
    plan's poses with 10 µm noise, identified by Gauss–Newton on the exact hybrid, commanded by its
    model's exact inverse kinematics (TCP and tool axis) and measured. The linear prediction of each
    machine's TCP error must match the exact one, and the claimed failure probability must lie in the
    Wilson 95 % interval of the observed fraction.
    """
    mech, r = calibrated_design
    plan, pset = r.calibration_plan, r.pset
    chain = ClosedChain(mech)
    held = pose_maps(r.grid, chain.actuated_idx, mech.reference_point_m).subset(np.array([r.worst_index]))
    setup = mode_setup(mech, pset, r.grid, r.classes, "calibrated", chain, PLAN)
    sigma = np.zeros(len(pset))
    sigma[r.uncompensatable] = r.tolerances[r.uncompensatable, r.design_column]
    sigma[setup.background] = PLAN.manufacturing_sigma(pset)[setup.background]
    acc = calibrated_maps(held, plan.H, plan.ident, plan.prior_sigma)
    N = acc.position_noise
    claim = (
        1.0
        - grid_reliability(acc.position, sigma, r.target_m, acc.noise_m**2 * (N @ N.transpose(0, 2, 1)))[0]
    )
    assert 0.005 < claim < 0.1
    rng = np.random.default_rng(12)
    failures, K, gaps = 0, 200, []
    for _ in range(K):
        delta = rng.standard_normal(len(pset)) * sigma
        noise = rng.standard_normal(plan.H.shape[0]) * PLAN.noise_m
        errs, _ = calibrate_and_evaluate(mech, pset, plan, Machine(mech, pset, delta), noise, held)
        assert errs.solved[0]
        linear = acc.position[0] @ delta + acc.position_noise[0] @ noise
        gaps.append(np.linalg.norm(errs.position_m[0] - linear))
        failures += int(errs.dlambda_m[0] > r.target_m)
    assert max(gaps) < 0.05 * r.target_m
    lo, hi = wilson_interval(failures, K)
    assert lo <= claim <= hi, (failures, K, claim)


def test_cli_plan_writes_the_whole_machines_commands(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    args = ["calibrate", str(HYBRID), "--plan", str(plan), "--random-sets", "1", "--holdout", "20"]
    assert (
        main([*args, "--poses", "30", "--candidates", "40", "--no-figures", "--out", str(tmp_path / "out")])
        == 0
    )
    rows = plan.read_text().splitlines()
    assert rows[0].split(",")[4:] == [
        "wrist.wrist_c [deg]",
        "wrist.wrist_a [deg]",
        "TCP_x [mm]",
        "TCP_y [mm]",
        "TCP_z [mm]",
    ]
    assert len(rows) == 31
    # the plan's TCP is where the nominal machine's exact forward kinematics put it at those commands
    mech = load_mechanism(HYBRID)
    pset = machine_parameter_set(mech, "dh")
    table = np.array([[float(v) for v in r.split(",")[1:]] for r in rows[1:]])
    u = np.hstack([1e-3 * table[:, :3], np.radians(table[:, 3:5])])
    grid = grid_sweep(mech, pset)
    q0 = pose_maps(grid, ClosedChain(mech).actuated_idx, mech.reference_point_m).q
    near = [int(np.argmin(np.linalg.norm(grid.points_m - 1e-3 * t[5:], axis=1))) for t in table]
    sols = Machine(mech, pset, np.zeros(len(pset))).forward_many(u, q0[near])
    assert sols.ok.all()
    np.testing.assert_allclose(sols.translation, 1e-3 * table[:, 5:], rtol=0, atol=1e-6)
    assert "d-optimal" in capsys.readouterr().out


def test_cli_measurements_round_trip_writes_a_loadable_calibrated_hybrid(hybrid, tmp_path, capsys):
    """Simulated tracker data at the TCP → identified parameters → calibrated URDFs of limbs and wrist.

    The calibrated folder loads as a hybrid, and its nominal forward kinematics is the identified
    machine's at the measured commands (TCP position and orientation to 1e-12).
    """
    mech, pset, grid, classes, settings, pool = hybrid
    plan = make_plan(mech, pset, classes, CalibrationSettings(candidates=60), pool, poses=30)
    rng = np.random.default_rng(3)
    delta = np.zeros(len(pset))
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
    y, _ = model_positions(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q, plan.targets_m)
    y = y + rng.standard_normal(y.shape) * 1e-5
    path = tmp_path / "measurements.csv"
    path.write_text(measurements_csv(mech, plan.maps.commands, y))
    out = tmp_path / "out"
    assert main(["calibrate", str(HYBRID), "--measurements", str(path), "--out", str(out)]) == 0
    assert "base parameter" in capsys.readouterr().out
    doc = json.loads((out / "identified.json").read_text())
    assert doc["converged"] and doc["rms_after_m"] < 1.2e-5 < doc["rms_before_m"]
    estimate = np.array([doc["estimate"][n] for n in pset.names])
    assert np.any(estimate[pset.module_count :] != 0.0)  # the wrist and the tool were identified too
    identified = Machine(mech, pset, estimate)
    calibrated = load_mechanism(out / "calibrated")
    assert calibrated.tool is not None and calibrated.tool_directions is not None
    cal_set = machine_parameter_set(calibrated, "urdf")
    nominal = Machine(calibrated, cal_set, np.zeros(len(cal_set)))
    a = identified.forward_many(plan.maps.commands, plan.maps.q)
    b = nominal.forward_many(plan.maps.commands, plan.maps.q - identified.offsets)
    assert a.ok.all() and b.ok.all()
    assert np.abs(a.translation - b.translation).max() <= 1e-12
    assert np.abs(a.rotation - b.rotation).max() <= 1e-12


@pytest.fixture(scope="module")
def on_nose():
    """The hybrid with its tracker on the spindle nose (``[calibration] tracker_on = "nose"``)."""
    mech = with_tracker_on(load_mechanism(HYBRID), "nose")
    pset = machine_parameter_set(mech, "dh")
    grid = grid_sweep(mech, pset)
    classes = grid.classify()
    pool = candidate_pool(mech, pset, CalibrationSettings(candidates=60), grid=grid)
    return mech, pset, classes, pool


def test_nose_tracker_reads_the_spindle_not_the_tool(on_nose):
    """H against finite differences of the exact machine; the tool's own errors do not reach the nose."""
    mech, pset, classes, pool = on_nose
    settings = CalibrationSettings(controller="full")
    np.testing.assert_allclose(settings.targets(mech), [[0.0, 0.0, -mech.tool.length_m]])
    plan = make_plan(mech, pset, classes, settings, pool, poses=20)
    h = 1e-6
    for c in range(pset.module_count, len(pset)):
        d = np.zeros(len(pset))
        d[c] = h
        yp, _ = model_positions(Machine(mech, pset, d), plan.maps.commands, plan.maps.q, plan.targets_m)
        d[c] = -h
        ym, _ = model_positions(Machine(mech, pset, d), plan.maps.commands, plan.maps.q, plan.targets_m)
        fd = ((yp - ym) / (2 * h)).reshape(-1)
        np.testing.assert_allclose(plan.H[:, c], fd, rtol=0, atol=1e-7, err_msg=pset.names[c])
        tool_own = pset.sub_assembly(c) == "tool"
        assert (np.abs(fd).max() < 1e-9) == (tool_own or pset.names[c] == "wrist.δθ_e"), pset.names[c]
    # the nose link's errors (a D–H wrist carries them in the TCP frame) do move the nose
    assert np.abs(plan.H[:, pset.names.index("wrist.δd_3")]).max() > 0.5


def test_nose_calibration_leaves_the_tools_errors_and_matches_the_linear_model(on_nose):
    """Noise-free, compensatable errors: the tool's errors stay, and the exact machine is ``L δ``."""
    mech, pset, classes, pool = on_nose
    plan = make_plan(mech, pset, classes, CalibrationSettings(), pool, poses=40)
    ho = holdout_poses(mech, pset, 20, np.random.default_rng(8))
    maps = calibrated_maps(ho.maps, plan.H, plan.ident)
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta = np.zeros(len(pset))
    delta[comp] = np.random.default_rng(2).standard_normal(len(comp)) * 1e-6
    true = Machine(mech, pset, delta)
    y, _ = model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
    res = _identify(mech, pset, plan, y)
    assert res.converged and res.rms_after_m <= 1e-12
    u, ok = controller_commands(Machine(mech, pset, res.estimate), ho.maps.points_m, ho.maps.q)
    err = pose_errors(true, u, ho.maps.q, ho.maps.points_m, ho.maps.rotations)
    assert ok.all() and err.solved.all()
    lin_p = np.einsum("kin,n->ki", maps.position, delta)
    lin_r = np.einsum("kin,n->ki", maps.rotation, delta)
    # the tool's own errors (run-out, length) are unseen at the nose: the calibration leaves their
    # TCP columns as they were before it
    tool = [i for i in comp if pset.sub_assembly(i) == "tool"]
    assert tool and np.abs(plan.H[:, tool]).max() == 0.0
    before = ho.maps.position_map()
    np.testing.assert_allclose(maps.position[:, :, tool], before[:, :, tool], rtol=0, atol=1e-12)
    dx = pset.names.index("tool.tcp.dx")
    np.testing.assert_allclose(np.linalg.norm(maps.position[:, :, dx], axis=1), 1.0, rtol=1e-12)
    assert np.abs(lin_p).max() > 1e-7
    assert np.abs(err.position_m - lin_p).max() <= 1e-3 * np.abs(lin_p).max()
    assert np.abs(err.rotation_rad - lin_r).max() <= 1e-3 * np.abs(lin_r).max()


def test_cli_tracker_in_its_own_frame_round_trip_on_the_hybrid(hybrid, tmp_path, capsys):
    """Tracker data in the tracker's own frame (``--tracker-frame identify``): the frame and the machine."""
    mech, pset, grid, classes, _, _ = hybrid
    settings = CalibrationSettings(candidates=60, tracker_frame="identify")
    plan = make_plan(mech, pset, classes, settings, candidate_pool(mech, pset, settings, grid=grid))
    inst = plan.instrument
    rng = np.random.default_rng(3)
    delta = np.zeros(len(pset))
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
    pi = inst.draw_nuisance(rng)
    o, R, _ = machine_poses(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q)
    values = inst.perturb(inst.measure(o, R, plan.stations, pi), rng.standard_normal((len(o), 3)) * 1e-5)
    path = tmp_path / "session.csv"
    path.write_text(measurements_csv(mech, plan.maps.commands, values.reshape(len(values), 1, 3)))
    out = tmp_path / "out"
    assert (
        main(
            [
                "calibrate",
                str(HYBRID),
                "--measurements",
                str(path),
                "--tracker-frame",
                "identify",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert "nuisance parameter" in capsys.readouterr().out
    doc = json.loads((out / "identified.json").read_text())
    assert doc["converged"] and doc["rms_after_in_sigma"] < 1.5
    estimate = np.array([doc["estimate"][n] for n in pset.names])
    identified = Machine(mech, pset, estimate)
    calibrated = load_mechanism(out / "calibrated")
    cal_set = machine_parameter_set(calibrated, "urdf")
    a = identified.forward_many(plan.maps.commands, plan.maps.q)
    b = Machine(calibrated, cal_set, np.zeros(len(cal_set))).forward_many(
        plan.maps.commands, plan.maps.q - identified.offsets
    )
    assert np.abs(a.translation - b.translation).max() <= 1e-12
    assert np.abs(a.rotation - b.rotation).max() <= 1e-12


def test_cli_simulate_on_the_hybrid_agrees_with_its_linear_model(tmp_path, capsys):
    """``pkmtol calibrate <hybrid> --simulate``: exact study rows against the linear L δ + N ν rows."""
    out = tmp_path / "out"
    args = [
        "calibrate",
        str(HYBRID),
        "--simulate",
        "--machines",
        "3",
        "--holdout",
        "20",
        "--random-sets",
        "1",
    ]
    assert main([*args, "--candidates", "60", "--no-figures", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "calibration study on exact kinematics: 3 machines × 20 held-out random poses" in text
    doc = json.loads((out / "study.json").read_text())
    before = doc["before_calibration"]["mean_dlambda_m"]
    for case in doc["cases"]:
        assert not case["unconverged_machines"]
        assert case["linear_model_valid"] and case["row_gap_exact_linear_m"] < 0.05 * doc["target_m"]
        assert case["exact"]["mean_dlambda_m"] < 0.05 * before  # the TCP is calibrated
        assert case["exact"]["mean_tilt_rad"] > 1e-4  # a tracker on the TCP leaves the tool axis


def test_cli_allocate_calibrated_hybrid(tmp_path, capsys):
    """``pkmtol allocate <hybrid> --compensation calibrated``: what calibration leaves, by sub-assembly."""
    out = tmp_path / "out"
    args = ["allocate", str(HYBRID), "--compensation", "calibrated", "--compensate-with", "module"]
    fast = ["--samples", "1000", "--verification-poses", "50", "--exact-samples", "10", "--no-figures"]
    assert main([*args, *fast, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "compensation: calibrated" in text and "Tolerances by sub-assembly" in text
    doc = json.loads((out / "allocation.json").read_text())
    classes = {p["class_in_mode"] for p in doc["parameters"]}
    assert {"identified", "toleranced"} <= classes


@pytest.fixture(scope="module")
def six_d(hybrid):
    """The hybrid's plans with a 6D probe (``tracker-6d``) on the TCP frame: registered or identified."""
    mech, pset, grid, classes, _, _ = hybrid
    out = {}
    for frame in ("registered", "identify"):
        st = CalibrationSettings(candidates=60, instrument="tracker-6d", tracker_frame=frame)
        out[frame] = make_plan(mech, pset, classes, st, candidate_pool(mech, pset, st, grid=grid), poses=30)
    return out


def _six_d_values(mech, pset, plan, delta, nuisance=None):
    inst = plan.instrument
    o, R, _ = machine_poses(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q)
    pi = np.zeros(inst.nuisance_count) if nuisance is None else nuisance
    return inst.measure(o, R, plan.stations, pi)


def test_six_d_probe_on_the_tcp_reads_its_position_and_the_tool_frame(hybrid, six_d):
    """The probe's values are the TCP and the TCP frame's orientation; H against the exact machine's FD."""
    mech, pset, grid, classes, _, _ = hybrid
    plan = six_d["registered"]
    inst = plan.instrument
    np.testing.assert_array_equal(inst.point_m, np.zeros(3))  # on the TCP, not on the module's P
    zero = np.zeros(len(pset))
    y0 = _six_d_values(mech, pset, plan, zero)
    np.testing.assert_allclose(y0[:, :3], plan.maps.points_m, rtol=0, atol=1e-12)
    for k in (0, 7, 29):  # the orientation is the TCP frame's: its z is the tool axis
        np.testing.assert_allclose(pin.exp3(y0[k, 3:]), plan.maps.rotations[k], rtol=0, atol=1e-12)
    assert plan.H.shape[0] == 6 * len(plan.maps)
    rng = np.random.default_rng(4)
    module = [c for c in plan.ident.columns if c < pset.module_count]
    tool = [c for c in plan.ident.columns if c >= pset.module_count]
    cols = list(rng.choice(module, 8, replace=False)) + tool
    h = 1e-6
    for c in cols:
        vals = []
        for sign in (1, -1):
            d = zero.copy()
            d[c] = sign * h
            vals.append(inst.residual(_six_d_values(mech, pset, plan, d), y0))
        fd = ((vals[0] - vals[1]) / (2 * h)).reshape(-1)
        np.testing.assert_allclose(
            plan.system.machine[:, c],
            fd,
            rtol=0,
            atol=1e-7 * max(1.0, np.abs(fd).max()),
            err_msg=pset.names[c],
        )
    # the orientation rows see the tool's tilt in the spindle, which a point on the TCP does not
    rx = pset.names.index("tool.tcp.rx")
    assert np.abs(plan.system.machine[:, rx]).max() > 0.5
    assert rx in plan.ident.columns


@pytest.mark.parametrize("frame", ["registered", "identify"])
def test_six_d_noise_free_identification_recovers_the_base_parameters(hybrid, six_d, frame):
    """Base-parameter errors at manufacturing size (and a random tracker placement): ≤ 1e-8 (1e-7)."""
    mech, pset, *_ = hybrid
    plan = six_d[frame]
    inst = plan.instrument
    rng = np.random.default_rng(11)
    delta = np.zeros(len(pset))
    scale = np.where(np.array(pset.units) == "m", 1e-4, 5e-4)
    b = plan.ident.base_columns
    assert any(i >= pset.module_count for i in b)
    delta[b] = rng.standard_normal(b.size) * scale[b]
    pi = inst.draw_nuisance(rng)
    y = _six_d_values(mech, pset, plan, delta, pi)
    res = identify_with(mech, pset, plan.ident, plan.maps, inst, y, None)
    beta = plan.ident.true_base_values(delta)
    assert res.converged
    bound = 1e-8 if inst.nuisance_count == 0 else 1e-7  # a frame: the second-order gap of test_instruments
    assert np.linalg.norm(res.identified - beta) <= bound * np.linalg.norm(beta)
    assert res.weighted_rms < 1e-6


def test_six_d_calibration_takes_the_tool_axis_out(hybrid, six_d):
    """Against one point on the TCP, the 6D probe sees the tool axis: more combinations, far less tilt.

    Noise-free, compensatable errors at 1e-6: the exact machine after calibration is ``L δ`` (the
    linear model of the 6D plan), and the tilt left is a small fraction of what a point leaves.
    """
    mech, pset, grid, classes, settings, pool = hybrid
    point = make_plan(mech, pset, classes, settings, pool, poses=30)
    plan = six_d["registered"]
    assert plan.ident.rank > point.ident.rank
    ho = holdout_poses(mech, pset, 20, np.random.default_rng(8))
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta = np.zeros(len(pset))
    delta[comp] = np.random.default_rng(2).standard_normal(len(comp)) * 1e-6
    true = Machine(mech, pset, delta)
    tilts = {}
    for name, p in (("point", point), ("6d", plan)):
        errs, ident = calibrate_and_evaluate(mech, pset, p, true, np.zeros(p.H.shape[0]), ho.maps)
        assert ident.converged and errs.solved.all()
        maps = calibrated_maps(ho.maps, p.H, p.ident)
        lin_p = np.einsum("kin,n->ki", maps.position, delta)
        lin_r = np.einsum("kin,n->ki", maps.rotation, delta)
        assert np.abs(errs.position_m - lin_p).max() <= 1e-3 * np.abs(delta).max()
        assert np.abs(errs.rotation_rad - lin_r).max() <= 1e-3 * max(np.abs(lin_r).max(), np.abs(delta).max())
        tilts[name] = _tilt(ho.maps.rotations, errs.rotation_rad).max()
    assert tilts["point"] > 1e-7 and tilts["6d"] < 1e-3 * tilts["point"]


def test_cli_six_d_measurements_round_trip_on_the_hybrid(hybrid, six_d, tmp_path, capsys):
    """A 6D probe's session file of the whole machine → identified errors → a loadable calibrated hybrid."""
    mech, pset, grid, classes, _, _ = hybrid
    plan = six_d["registered"]
    inst = plan.instrument
    rng = np.random.default_rng(3)
    delta = np.zeros(len(pset))
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
    values = _six_d_values(mech, pset, plan, delta)
    values = inst.perturb(values, rng.standard_normal(values.shape) * inst.noise[None, :])
    path = tmp_path / "session.csv"
    path.write_text(instrument_csv(mech, inst, plan.maps.commands, values, plan.stations))
    assert path.read_text().splitlines()[0].endswith("rx [mrad],ry [mrad],rz [mrad]")
    out = tmp_path / "out"
    args = ["calibrate", str(HYBRID), "--instrument", "tracker-6d", "--measurements", str(path)]
    assert main([*args, "--out", str(out)]) == 0
    assert "instrument tracker-6d" in capsys.readouterr().out
    doc = json.loads((out / "identified.json").read_text())
    assert doc["converged"] and doc["rms_after_in_sigma"] < 1.5
    estimate = np.array([doc["estimate"][n] for n in pset.names])
    assert estimate[pset.names.index("tool.tcp.rx")] != 0.0  # the tool's tilt is seen by the probe
    identified = Machine(mech, pset, estimate)
    calibrated = load_mechanism(out / "calibrated")
    cal_set = machine_parameter_set(calibrated, "urdf")
    a = identified.forward_many(plan.maps.commands, plan.maps.q)
    b = Machine(calibrated, cal_set, np.zeros(len(cal_set))).forward_many(
        plan.maps.commands, plan.maps.q - identified.offsets
    )
    assert np.abs(a.translation - b.translation).max() <= 1e-12
    assert np.abs(a.rotation - b.rotation).max() <= 1e-12


def test_cli_allocate_calibrated_hybrid_with_nothing_toleranced_says_so(tmp_path, capsys, monkeypatch):
    """The whole machine's calibration identifies every error: the report says so, and prints no NaN."""
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines: piped prose wraps at 100 columns
    out = tmp_path / "out"
    args = ["allocate", str(HYBRID), "--compensation", "calibrated", "--method", "fosm"]
    fast = ["--samples", "1000", "--verification-poses", "50", "--exact-samples", "10", "--no-figures"]
    assert main([*args, *fast, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "allocation.json").read_text())
    assert not [p for p in doc["parameters"] if p["class_in_mode"] == "toleranced"]
    for report in (text, (out / "allocation.md").read_text()):
        assert re.search(r"\bnan\b", report) is None
        assert "σ[Δλ_j] over the 525 grid points: no toleranced parameter" in report
        assert "no tolerance to compare (the new method tolerances no parameter)" in report
        assert "largest: no toleranced parameter (what is left is the tracker noise's)" in report
        assert "(TCP, pose 0): no toleranced parameter" in report
    rows = [line.split() for line in text.splitlines()]
    shares = [r[-1] for r in rows if len(r) == 6 and r[0] in ("module", "wrist", "tool") and r[2] == "0"]
    assert shares == ["-", "-", "-"]  # the share of nothing: not "0.0", not "nan"


def test_tricept_wrist_calibrates_with_its_rank_tolerance():
    """The Tricept's hybrid with ``rank_tolerance = 1e-4`` (docs/hybrid.md): it converges, as predicted.

    A noisy calibration on the exact machine leaves at held-out poses what ``L δ + N ν`` predicts.
    """
    mech = load_mechanism(ROOT / "robots" / "tricept_wrist")
    pset = machine_parameter_set(mech, "dh")
    grid = grid_sweep(mech, pset)
    classes = grid.classify()
    settings = CalibrationSettings(candidates=60, rank_tolerance=1e-4)
    plan = make_plan(mech, pset, classes, settings, candidate_pool(mech, pset, settings, grid=grid))
    ho = holdout_poses(mech, pset, 20, np.random.default_rng(4))
    maps = calibrated_maps(ho.maps, plan.H, plan.ident)
    rng = np.random.default_rng(7)
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    for _ in range(2):
        delta = np.zeros(len(pset))
        delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
        noise = rng.standard_normal(plan.H.shape[0]) * settings.noise_m
        errs, ident = calibrate_and_evaluate(mech, pset, plan, Machine(mech, pset, delta), noise, ho.maps)
        assert ident.converged and errs.solved.all()
        linear = np.einsum("kin,n->ki", maps.position, delta) + np.einsum(
            "kiM,M->ki", maps.position_noise, noise
        )
        assert np.abs(errs.position_m - linear).max() < 0.05 * mech.target_m
        assert np.linalg.norm(errs.position_m, axis=1).mean() < 0.5 * mech.target_m


def test_locked_wrist_calibration_is_the_tcp_position_task(tmp_path):
    """3-axis work (the wrist locked): three task rows, the module's actuators, exact = linear."""
    mech = load_mechanism(HYBRID)
    locked = mech.tool.with_locked({"wrist_c": np.pi / 2, "wrist_a": np.pi / 4})
    mech = dataclasses.replace(mech, tool=locked, tool_directions=None)
    pset = machine_parameter_set(mech, "dh")
    grid = grid_sweep(mech, pset)
    classes = grid.classify()
    settings = CalibrationSettings(candidates=30)
    pool = candidate_pool(mech, pset, settings, grid=grid)
    assert pool.task_rows.shape[1:] == (3, 6) and pool.commands.shape[1] == 3
    plan = make_plan(mech, pset, classes, settings, pool)
    ho = holdout_poses(mech, pset, 20, np.random.default_rng(4))
    maps = calibrated_maps(ho.maps, plan.H, plan.ident)
    rng = np.random.default_rng(9)
    sigma = np.where(np.array(pset.units) == "m", 1e-5, 5e-5) * np.array([c != "absorbed" for c in classes])
    delta = rng.standard_normal(len(pset)) * sigma
    noise = rng.standard_normal(plan.H.shape[0]) * settings.noise_m
    errs, ident = calibrate_and_evaluate(mech, pset, plan, Machine(mech, pset, delta), noise, ho.maps)
    assert ident.converged and errs.solved.all()
    linear = maps.position @ delta + maps.position_noise @ noise
    assert np.abs(linear).max() > 2e-6  # the noise and what the calibration cannot see
    assert np.abs(errs.position_m - linear).max() < 1e-3 * mech.target_m  # second order (50 nm)
    # its calibrated folder keeps the wrist locked, and its kinematics is the identified machine's
    urdfs, toml = calibrated_files(mech, pset, ident.estimate)
    for path, data in write_calibrated_folder(tmp_path / "calibrated", urdfs, toml):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    calibrated = load_mechanism(tmp_path / "calibrated")
    assert calibrated.tool.actuated == () and calibrated.tool_directions is None
    cal_set = machine_parameter_set(calibrated, "urdf")
    identified = Machine(mech, pset, ident.estimate)
    a = identified.forward_many(plan.maps.commands, plan.maps.q)
    b = Machine(calibrated, cal_set, np.zeros(len(cal_set))).forward_many(
        plan.maps.commands, plan.maps.q - identified.offsets
    )
    assert np.abs(a.translation - b.translation).max() <= 1e-12
    assert np.abs(a.rotation - b.rotation).max() <= 1e-12


def test_cli_measurements_of_a_tracker_on_the_nose(on_nose, tmp_path, capsys):
    """``--tracker-on nose --measurements``: the spindle's readings identify the machine (not the tool)."""
    mech, pset, classes, pool = on_nose
    plan = make_plan(mech, pset, classes, CalibrationSettings(), pool, poses=30)
    rng = np.random.default_rng(5)
    delta = np.zeros(len(pset))
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
    y, _ = model_positions(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q, plan.targets_m)
    path = tmp_path / "measurements.csv"
    path.write_text(measurements_csv(mech, plan.maps.commands, y + rng.standard_normal(y.shape) * 1e-5))
    out = tmp_path / "out"
    assert (
        main(
            ["calibrate", str(HYBRID), "--tracker-on", "nose", "--measurements", str(path), "--out", str(out)]
        )
        == 0
    )
    capsys.readouterr()
    doc = json.loads((out / "identified.json").read_text())
    assert doc["converged"] and doc["rms_after_m"] < 1.2e-5 < doc["rms_before_m"]
    estimate = np.array([doc["estimate"][n] for n in pset.names])
    tool = [i for i in range(len(pset)) if pset.sub_assembly(i) == "tool"]
    assert np.all(estimate[tool] == 0.0)  # the tool's own errors are not seen at the nose
    # the identified machine's nose is where the tracker saw it, to the noise
    fit, _ = model_positions(Machine(mech, pset, estimate), plan.maps.commands, plan.maps.q, plan.targets_m)
    assert np.sqrt(np.mean((fit - y) ** 2)) < 2e-5
