"""The example scripts in scripts/ run (as a user would, in a subprocess, with small sample
counts) and print the numbers the library computes."""

from __future__ import annotations

import base64
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from process_checks import alive

from pkmtol import ClosedChain, load_mechanism
from pkmtol.model.mechanism import check_home

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = REPO / "scripts"
SEED = REPO / "robots" / "r2rps_ups"


def run(script: str, *args: str) -> str:
    proc = subprocess.run(
        [sys.executable, str(SCRIPTS / script), *args], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def load_script(name: str):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def table_body(text: str, header_start: str) -> list[list[str]]:
    """Rows (split on 2+ spaces) of the text table whose header starts with ``header_start``."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header_start))
    rows = []
    for line in lines[start + 2 :]:
        if not line.strip():
            break
        rows.append(re.split(r"\s{2,}", line.strip()))
    return rows


# --- your own pin.Model limbs ------------------------------------------------------------------


def test_own_models_build_a_closed_mechanism():
    mech = load_script("example_own_models").build_mechanism()
    check_home(mech)  # every platform frame at the same pose at home
    assert [lb.name for lb in mech.limbs] == ["column", "leg1", "leg2", "leg3"]
    assert [lb.nq for lb in mech.limbs] == [3, 6, 6, 6]
    assert [len(lb.actuated) for lb in mech.limbs] == [0, 1, 1, 1]
    for lb in mech.limbs:  # O' at (0, 0, 0.8) m with the axes of K
        data = lb.model.createData()
        pin.framesForwardKinematics(lb.model, data, lb.home)
        np.testing.assert_allclose(data.oMf[lb.platform_frame].translation, [0, 0, 0.8], atol=1e-12)
        np.testing.assert_allclose(data.oMf[lb.platform_frame].rotation, np.eye(3), atol=1e-12)


def test_own_models_print_the_tolerance_table():
    out = run("example_own_models.py", "--samples", "300", "--exact-samples", "4")
    assert "171 error parameters (urdf set), 18 uncompensatable" in out
    rows = table_body(out, "No.")
    assert len(rows) == 18
    # only the passive UP column is constrained, so only its errors are uncompensatable
    assert all(r[1].startswith("column.") for r in rows)
    betas = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    for r in rows:  # σ_i · β is constant along each row (printed to 4 decimals)
        tol = np.array([float(c.lstrip("±")) for c in r[4 : 4 + betas.size]])  # then the share columns
        expected = tol[1] / betas  # from the β = 1 column
        assert np.all(np.abs(tol - expected) <= 5e-5 * (1 + 1 / betas) + 1e-12), r


# --- Pinocchio's constrained dynamics on a toleranced machine ------------------------------------

MJCF_SEED = REPO / "tests" / "data" / "r2rps_ups_mjcf"


def _number(text: str, pattern: str) -> float:
    m = re.search(pattern, text)
    assert m is not None, pattern
    return float(m.group(1))


def test_constrained_dynamics_example_hands_the_perturbed_machine_to_pinocchio():
    out = run("example_constrained_dynamics.py", "--samples", "300", "--exact-samples", "4", "--seed", "3")
    assert "one pin.Model (nq = 21) + 3 FrameAnchorConstraintModels" in out
    assert "18 uncompensatable errors toleranced" in out
    # the drawn machine is closed on its own (perturbed) constraints and visibly not on the nominal ones
    assert _number(out, r"perturbed constraints ([\d.e+-]+)") < 1e-10
    assert _number(out, r"nominal constraints ([\d.e+-]+)") > 1e-7
    # constrained dynamics keeps the loops closed: J a = 0, and one step leaves them closed to 2nd order
    assert _number(out, r"max \|J a\| \(FrameAnchor Jacobian\): ([\d.e+-]+)") < 1e-8
    assert _number(out, r"closure residual max \|log6\| ([\d.e+-]+)") < 1e-8
    assert _number(out, r"P moved ([\d.]+) um") > 0


def test_constrained_dynamics_step_obeys_the_equations_of_motion():
    example = load_script("example_constrained_dynamics")
    mech = load_mechanism(MJCF_SEED)
    cm = mech.constraint_models()
    q = cm.q(ClosedChain(mech).inverse(np.array([0.2, -0.3, 1.0])).q)
    step = example.one_step(cm, q, 50.0, 1e-3, mech.reference_point_m)
    model, data = cm.model, cm.model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    gravity = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
    rigid = pin.StdVec_RigidConstraintModel()
    for r in cm.rigid_constraints():
        rigid.append(r)
    pin.computeJointJacobians(model, data, q)
    rdatas = pin.StdVec_RigidConstraintData()
    for r in rigid:
        rdatas.append(r.createData())
        r.calc(model, data, rdatas[len(rdatas) - 1])  # getConstraintsJacobian needs the evaluated data
    jr = pin.getConstraintsJacobian(model, data, rigid, rdatas)
    # M a + g(q) = tau + Jᵀ λ (at rest), with the legacy Jacobian the loop forces belong to
    residual = mass @ step.a + gravity - step.tau - jr.T @ step.lambda_c
    assert np.max(np.abs(residual)) < 1e-9 * np.max(np.abs(step.tau))
    assert np.max(np.abs(cm.jacobian(q) @ step.a)) < 1e-8
    assert step.tau[list(cm.actuated)].tolist() == [50.0, 50.0, 50.0]
    # P's acceleration, by finite differences of P along the step's motion (from rest: Δp ≈ a dt²)
    assert np.max(np.abs(step.p_move_m - step.a_p * 1e-6)) < 1e-3 * np.max(np.abs(step.a_p * 1e-6))


def test_constrained_dynamics_example_refuses_a_massless_mechanism():
    proc = subprocess.run(
        [sys.executable, str(SCRIPTS / "example_constrained_dynamics.py"), str(SEED)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert proc.returncode == 2
    assert "has no mass" in proc.stderr and "tests/data/r2rps_ups_mjcf" in proc.stderr


# --- your own MeshcatVisualizer -----------------------------------------------------------------


def _meshcat_commands(html: str) -> list[dict]:
    umsgpack = pytest.importorskip("umsgpack")
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def test_meshcat_example_draws_into_your_own_visualizer(tmp_path):
    pytest.importorskip("meshcat")
    html = tmp_path / "scene.html"
    out = run("example_meshcat.py", "--out", str(html), "--samples", "300")
    m = re.search(r"(\d+) error spheres.*meshcat server (\d+) stopped", out, re.S)
    assert m is not None and m.group(1) == "147"
    assert not alive(int(m.group(2)))
    commands = _meshcat_commands(html.read_text(encoding="utf-8"))
    paths = [c.get("path", "") for c in commands]
    for limb in ("limb1", "limb2", "limb3", "limb4"):
        assert any(p.startswith(f"/meshcat/my_robot/{limb}/visuals/") for p in paths)
    assert not any(p.startswith("/meshcat/pkmtol/robot") for p in paths)  # the robot is yours
    spheres = {p for p in paths if re.fullmatch(r"/meshcat/pkmtol/error_spheres/\d+", p)}
    assert len(spheres) == 147
    # every limb's platform visual is drawn at the same (closed) pose
    platforms = [
        np.array(c["matrix"], dtype=float).reshape(4, 4)
        for c in commands
        if c.get("type") == "set_transform"
        and re.fullmatch(r"/meshcat/my_robot/limb\d/visuals/platform_0", c["path"])
    ]
    assert len(platforms) == 4
    for t in platforms[1:]:
        np.testing.assert_allclose(t, platforms[0], atol=1e-9)
