"""The planar task (``task.kind = "planar"``) on the 5-bar linkage; the new robots through the pipeline."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pkmtol.cli import main
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.separation import separate
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import MechanismFormatError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
FIVEBAR = ROOT / "robots" / "fivebar"
DELTA = ROOT / "robots" / "delta"
SMALL = ["--samples", "400", "--exact-samples", "5", "--verification-poses", "40", "--no-progress"]


@pytest.fixture(scope="module")
def fivebar():
    mech = load_mechanism(FIVEBAR)
    return mech, ClosedChain(mech)


def test_urdfs_are_the_dh_tables():
    run = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "dh_to_urdf.py"), str(FIVEBAR), "--check"],
        capture_output=True,
    )
    assert run.returncode == 0, run.stderr


def test_planar_task_counts_the_in_plane_error_only(fivebar):
    """J and J_total have no out-of-plane row; the in-plane part is the position rows of the twist map."""
    mech, chain = fivebar
    np.testing.assert_allclose(mech.task_normal, [0.0, 0.0, 1.0])
    np.testing.assert_allclose(mech.task_projection, np.diag([1.0, 1.0, 0.0]))
    ps = parameter_set(mech, "dh")
    grid = sweep(mech, ps, mech.task_space.grid(), chain)
    assert np.abs(grid.J[:, 2]).max() == 0.0 and np.abs(grid.J_total[:, 2]).max() == 0.0
    sep = grid.separations[5]
    # the in-plane rows: P's error from the twist (P at the platform origin, l = 0)
    np.testing.assert_allclose(sep.J_total[:2], sep.twist_map[:2], atol=1e-15)
    classes = grid.classify()
    # the out-of-plane errors are seen by constraint wrenches (an assembly error) but move P out of
    # the plane only: their sensitivity is 0 everywhere; the in-plane lengths of the left arm are
    # uncompensatable (its in-plane constraint force), those of the right arm compensatable
    cls = dict(zip(ps.names, classes, strict=True))
    assert cls["δd_{2,1}"] == cls["δφ_{2,1}"] == "uncompensatable"
    assert np.abs(grid.J[:, :, ps.names.index("δd_{2,1}")]).max() < 1e-12
    assert cls["δa_{2,1}"] == "uncompensatable" and cls["δa_{2,2}"] == "compensatable"
    assert cls["ξ_{a,1}"] == cls["ξ_{a,2}"] == "compensatable"
    assert grid.redundancy == 3


def test_planar_error_against_exact_kinematics(fivebar):
    """In-plane errors (the ones a planar machine assembles with), Eq. 25 correction, exact solve:
    the in-plane error of P is J η to ≤ 1e-3, second order (10× smaller at η/10)."""
    mech, chain = fivebar
    ps = parameter_set(mech, "urdf")
    in_plane = np.array(
        [n.endswith((".dx", ".dy", ".rz")) or n.endswith(".offset") for n in ps.names], dtype=bool
    )
    rng = np.random.default_rng(3)
    q = chain.home()
    for p in mech.task_space.sample(rng, 8):
        pose = chain.inverse(p, q)
        sep = separate(mech, ps, chain, pose)
        eta0 = np.where(in_plane, rng.normal(0.0, 1.0, len(ps)), 0.0)
        assert np.abs(sep.incompatible_map @ eta0).max() < 1e-12  # such errors assemble
        rel = []
        for size in (1e-5, 1e-6):
            eta = eta0 * size
            eps, offsets = ps.perturbation(eta, mech)
            pert = ClosedChain(mech, perturbed_limb_models(mech, eps), check_limits=False)
            u = pose.q_all[chain.actuated_idx] + sep.correction @ eta
            actual = pert.forward(u, pose.q_all, offsets)
            exact = mech.task_error(actual.p_m - pose.p_m)
            assert abs(exact[2]) == 0.0
            # relative to the pose error: the compensation can leave P's error much smaller than it
            size_t = float(np.linalg.norm(sep.uncompensated_map @ eta))
            rel.append(np.linalg.norm(exact - sep.J @ eta) / size_t)
        assert rel[1] <= 1e-3
        assert rel[0] / rel[1] == pytest.approx(10.0, rel=0.1)


def test_planar_task_format_is_checked(tmp_path):
    folder = shutil.copytree(FIVEBAR, tmp_path / "fivebar")
    toml = folder / "mechanism.toml"
    text = toml.read_text(encoding="utf-8")
    toml.write_text(text.replace("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]"), encoding="utf-8")
    with pytest.raises(MechanismFormatError, match="task.normal"):
        load_mechanism(folder)
    toml.write_text(
        text.replace("z_m = [0.0, 0.0]", "z_m = [0.0, 0.1]").replace("layers = 1", "layers = 2"),
        encoding="utf-8",
    )
    with pytest.raises(MechanismFormatError, match="one plane of normal"):
        load_mechanism(folder)
    toml.write_text(text.replace('kind = "planar"', 'kind = "orientation"'), encoding="utf-8")
    with pytest.raises(MechanismFormatError, match="'planar'"):
        load_mechanism(folder)


@pytest.mark.parametrize("robot", [FIVEBAR, DELTA], ids=["fivebar", "delta"])
def test_new_robots_run_through_the_whole_pipeline(tmp_path, capsys, robot):
    """check, errors, allocate, calibrate and show on the 5-bar and the Delta."""
    assert main(["check", str(robot)]) == 0
    assert "result: OK" in capsys.readouterr().out
    assert main(["errors", str(robot), "--json", str(tmp_path / "errors.json")]) == 0
    errors = json.loads((tmp_path / "errors.json").read_text(encoding="utf-8"))
    assert len(errors["parameters"]) > 0
    out = tmp_path / "alloc"
    assert main(["allocate", str(robot), "--out", str(out), "--no-figures", *SMALL]) == 0
    alloc = json.loads((out / "allocation.json").read_text(encoding="utf-8"))
    assert alloc["verification"]
    cal = tmp_path / "cal"
    assert (
        main(
            [
                "calibrate",
                str(robot),
                "--out",
                str(cal),
                "--no-figures",
                "--random-sets",
                "1",
                "--poses",
                "20",
            ]
        )
        == 0
    )
    assert (cal / "calibration_plan.json").is_file()
    html = tmp_path / "scene.html"
    assert main(["show", str(robot), "--html", str(html), "--samples", "200"]) == 0
    assert html.stat().st_size > 10_000
