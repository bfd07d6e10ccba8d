"""The probe on a plane artifact: what a face sees and cannot see, and noise-free recovery.

The Jacobians against finite differences and the CSV round trip of this artifact are in
tests/test_instruments.py and tests/test_instruments_cli.py (case ``probe, plane artifact``).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol.calibration.identification import identify_with, machine_poses
from pkmtol.calibration.instruments import instrument_for
from pkmtol.calibration.instruments.base import unseen_nuisance
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.plan import candidate_pool, make_plan
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.cli import main
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import InvalidRequestError, MechanismFormatError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"


@pytest.fixture(scope="module")
def seed():
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    grid = sweep(mech, pset, mech.task_space.grid(), chain)
    return mech, pset, chain, grid, grid.classify()


def _touches(inst):
    """Every candidate touch of ``inst`` as platform poses at the nominal orientation (identity)."""
    c = inst.candidates(np.zeros((0, 3)), np.random.default_rng(0))
    rot = np.tile(np.eye(3), (len(c.points_m), 1, 1))
    return c.points_m - inst.point_m, rot, c.stations


def test_a_face_does_not_see_its_in_plane_motion_and_the_plate_names_it(seed):
    mech = seed[0]
    settings = CalibrationSettings(instrument="probe", artifact="plane", artifact_faces=("+z",))
    plate = instrument_for(settings, mech)
    origin, rot, st = _touches(plate)
    base = plate.measure(origin, rot, st, np.zeros(6))
    np.testing.assert_allclose(base, plate.radius_m, atol=1e-15)  # planned touches lie on the face
    for j, moved in ((0, True), (1, True), (5, True), (2, False), (3, False), (4, False)):
        alpha = np.zeros(6)
        alpha[j] = 1e-3
        change = np.abs(plate.measure(origin, rot, st, alpha) - base).max()
        assert (change < 1e-15) if moved else (change > 1e-5), (j, change)
    names = unseen_nuisance(plate, plate.nuisance_rows(origin, rot, st, np.zeros(6)))
    assert [n.split(" ")[0] for n in names] == ["artifact.dx", "artifact.dy", "artifact.rz"]
    assert "rotation about the artifact's z" in names[2]


def test_the_block_fixes_the_whole_pose_of_the_artifact(seed):
    block = instrument_for(CalibrationSettings(instrument="probe", artifact="plane"), seed[0])
    assert block.face_names == ("+z", "+x", "-x", "+y", "-y")
    origin, rot, st = _touches(block)
    assert unseen_nuisance(block, block.nuisance_rows(origin, rot, st, np.zeros(6))) == []
    # two faces with independent normals leave the translation along their common line
    two = np.isin(st, [0, 1])
    names = unseen_nuisance(block, block.nuisance_rows(origin[two], rot[two], st[two], np.zeros(6)))
    assert [n.split(" ")[0] for n in names] == ["artifact.dy"]


def test_noise_free_identification_recovers_the_base_parameters(seed):
    """The block's D-optimal plan, a random true set-up of the artifact (0.5 mm, 1 mrad).

    Base-parameter errors at manufacturing size (0.1 mm, 0.5 mrad): ≤ 1e-8 relative (5.6e-9
    measured; 1.5e-9 at half the size). The sphere's and the ballbar's bound is 1e-7
    (tests/test_instruments.py): their plans leave a weaker rigid-motion coupling.
    """
    mech, pset, chain, grid, classes = seed
    st = CalibrationSettings(instrument="probe", artifact="plane")
    plan = make_plan(mech, pset, classes, st, candidate_pool(mech, pset, st, chain, grid=grid))
    inst = plan.instrument
    assert plan.ident.rank == plan.pool_rank == 22 and plan.system.nuisance_rank == 6
    assert set(np.unique(plan.stations)) == {0, 1, 2, 3, 4}  # three touches of every face at least
    rng = np.random.default_rng(11)
    delta = np.zeros(len(pset))
    scale = np.where(np.array(pset.units) == "m", 1e-4, 5e-4)
    b = plan.ident.base_columns
    delta[b] = rng.standard_normal(b.size) * scale[b]
    pi = inst.draw_nuisance(rng)
    o, R, _ = machine_poses(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q)
    y = inst.measure(o, R, plan.stations, pi)
    res = identify_with(mech, pset, plan.ident, plan.maps, inst, y, None)
    beta = plan.ident.true_base_values(delta)
    assert res.converged
    assert np.linalg.norm(res.identified - beta) <= 1e-8 * np.linalg.norm(beta)
    assert res.weighted_rms < 1e-6
    # the artifact's pose is the drawn one to the size of the machine's errors (a global rigid
    # motion is shared by both)
    gap = pin.log6(inst.pose(pi).inverse() * inst.pose(res.nuisance)).vector
    assert np.abs(gap[:3]).max() < 2e-4 and np.abs(gap[3:]).max() < 1e-3


def test_plan_output_names_what_a_plate_cannot_fix(tmp_path, capsys, monkeypatch):
    """A surface plate alone (the top face): the plan names its in-plane translation and rotation."""
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines: piped prose wraps at 100 columns
    robot = tmp_path / "robot"
    shutil.copytree(SEED, robot)
    with (robot / "mechanism.toml").open("a", encoding="utf-8") as f:
        f.write('\n[calibration]\ninstrument = "probe"\nartifact = "plane"\nartifact_faces = ["+z"]\n')
    args = ["calibrate", str(robot), "--poses", "60", "--out", str(tmp_path / "o"), "--no-figures"]
    assert main(args + ["--random-sets", "0"]) == 0
    text = capsys.readouterr().out
    assert "probe on a plane artifact: faces +z, tip radius 1 mm" in text
    assert (
        "the poses do not fix 3 of the probe's 6 nuisance directions: artifact.dx (translation along "
        "the artifact's x); artifact.dy (translation along the artifact's y); artifact.rz (rotation "
        "about the artifact's z)"
    ) in text


@pytest.mark.parametrize(
    ("kw", "culprit"),
    [
        ({"artifact": "cube"}, "unknown artifact 'cube'"),
        ({"artifact_faces": ("+z", "+w")}, "artifact_faces must be distinct faces"),
        ({"artifact_faces": ("+z", "+z")}, "artifact_faces must be distinct faces"),
        ({"artifact_faces": ()}, "artifact_faces must be distinct faces"),
    ],
)
def test_bad_artifact_settings_are_named(kw, culprit):
    with pytest.raises(InvalidRequestError, match=culprit):
        CalibrationSettings(instrument="probe", **kw)


def test_sphere_centres_given_to_a_plane_artifact_are_refused(seed):
    st = CalibrationSettings(instrument="probe", artifact="plane", stations_m=((0.0, 0.0, 1.0),))
    with pytest.raises(InvalidRequestError, match="stations_m places the spheres"):
        instrument_for(st, seed[0])


def test_the_artifact_keys_of_the_table_are_read_and_checked(tmp_path):
    from pkmtol.calibration.settings import settings_from_table

    st = settings_from_table({"artifact": "plane", "artifact_faces": ["+z", "+x"]}, tmp_path / "m.toml")
    assert st.artifact == "plane" and st.artifact_faces == ("+z", "+x")
    assert st.artifact_radius_m == 1e-3 and st.approach_directions == 100
    assert CalibrationSettings().artifact_radius_m == 0.0137
    with pytest.raises(MechanismFormatError, match="calibration.artifact_faces"):
        settings_from_table({"artifact_faces": "+z"}, tmp_path / "m.toml")
