"""Mechanism descriptions: every robot loads (Pinocchio and yourdfpy), URDFs match their D–H
tables, bad input raises a distinct pkmtol error naming the culprit, and ``pkmtol check`` reports
the seed robot's structure."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from pkmtol import Mechanism, TaskSpace, load_mechanism
from pkmtol.cli import main
from pkmtol.exceptions import (
    MechanismFormatError,
    PlatformMismatchError,
    UnknownJointError,
    URDFError,
)
from pkmtol.kinematics.check import check_mechanism

REPO = Path(__file__).resolve().parents[1]
SEED = REPO / "robots" / "r2rps_ups"
ROBOTS = sorted(p.parent for p in (REPO / "robots").glob("*/mechanism.toml"))


def copy_robot(tmp_path: Path, old: str = "", new: str = "") -> Path:
    """A copy of the seed robot in ``tmp_path`` with ``old`` replaced by ``new`` in its TOML."""
    folder = tmp_path / "robot"
    shutil.copytree(SEED, folder)
    if old:
        toml = folder / "mechanism.toml"
        text = toml.read_text(encoding="utf-8")
        assert text.count(old) == 1, f"{old!r} must occur exactly once in the seed TOML"
        toml.write_text(text.replace(old, new), encoding="utf-8")
    return folder


# --- every robot loads ----------------------------------------------------------------------


def test_robots_folder_is_not_empty():
    assert SEED in ROBOTS


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda p: p.name)
def test_robot_loads_with_pinocchio(robot):
    mech = load_mechanism(robot)
    assert len(mech.limbs) >= 2
    assert mech.n_joints == sum(limb.model.nq for limb in mech.limbs)
    for limb in mech.limbs:
        assert limb.model.nq == limb.model.nv == limb.model.njoints - 1
        assert set(limb.joint_kinds) <= {"R", "P"}
        assert len(limb.actuated) <= 1
        assert limb.urdf_path is not None and limb.urdf_path.is_file()
    assert len(mech.task_space.grid()) > 0


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda p: p.name)
def test_robot_limbs_load_with_yourdfpy_and_agree_with_pinocchio(robot):
    mech = load_mechanism(robot)
    bases = set()
    tree_home = {n: float(v) for lb in mech.limbs for n, v in zip(lb.joint_names, lb.home, strict=True)}
    for limb in mech.limbs:
        urdf = yourdfpy.URDF.load(str(limb.urdf_path))
        bases.add(urdf.base_link)
        if len(urdf.actuated_joint_names) > limb.nq:  # a limb cut from one URDF tree (docs/closed-loop.md)
            assert set(limb.joint_names) <= set(urdf.actuated_joint_names)
            _same_tree_kinematics(urdf, limb, tree_home)
            continue
        assert tuple(urdf.actuated_joint_names) == limb.joint_names
        for k, name in enumerate(limb.joint_names):
            joint = urdf.joint_map[name]
            assert joint.type == ("revolute" if limb.joint_kinds[k] == "R" else "prismatic")
            assert joint.limit.lower == pytest.approx(limb.model.lowerPositionLimit[k], abs=1e-12)
            assert joint.limit.upper == pytest.approx(limb.model.upperPositionLimit[k], abs=1e-12)
        # forward kinematics of both readers agree at home
        urdf.update_cfg(limb.home)
        platform = limb.model.frames[limb.platform_frame].name
        data = limb.model.createData()
        pin.framesForwardKinematics(limb.model, data, limb.home)
        np.testing.assert_allclose(
            urdf.get_transform(platform, urdf.base_link),
            data.oMf[limb.platform_frame].homogeneous,
            atol=1e-12,
        )
    assert len(bases) == 1, f"limbs have different root links: {bases}"


def _same_tree_kinematics(urdf, limb, tree_home) -> None:
    """A limb cut from a URDF tree: its joints' types, limits and frames at home are the tree's."""
    for k, name in enumerate(limb.joint_names):
        joint = urdf.joint_map[name]
        assert joint.type == ("revolute" if limb.joint_kinds[k] == "R" else "prismatic")
        assert joint.limit.lower == pytest.approx(limb.model.lowerPositionLimit[k], abs=1e-12)
        assert joint.limit.upper == pytest.approx(limb.model.upperPositionLimit[k], abs=1e-12)
    urdf.update_cfg([tree_home.get(n, 0.0) for n in urdf.actuated_joint_names])
    data = limb.model.createData()
    pin.forwardKinematics(limb.model, data, limb.home)
    for j, name in enumerate(limb.joint_names, 1):
        np.testing.assert_allclose(
            urdf.get_transform(urdf.joint_map[name].child, urdf.base_link),
            data.oMi[j].homogeneous,
            atol=1e-12,
        )


def test_seed_robot_description():
    mech = load_mechanism(SEED)
    assert mech.name == "r2rps_ups"
    assert [limb.name for limb in mech.limbs] == ["limb1", "limb2", "limb3", "limb4"]
    assert [limb.nq for limb in mech.limbs] == [6, 6, 6, 3]
    assert [[limb.joint_names[a] for a in limb.actuated] for limb in mech.limbs] == [
        ["limb1_p3"],
        ["limb2_p3"],
        ["limb3_p3"],
        [],
    ]
    assert mech.limbs[0].joint_kinds == ("R", "R", "P", "R", "R", "R")
    assert mech.limbs[3].joint_kinds == ("R", "R", "P")
    np.testing.assert_array_equal(mech.reference_point_m, [0.0, 0.0, 0.3])
    assert mech.target_m == pytest.approx(5e-5)
    assert mech.betas == (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
    assert mech.design_beta == 2.0
    grid = mech.task_space.grid()
    assert grid.shape == (147, 3)
    np.testing.assert_allclose(sorted(set(np.round(grid[:, 2], 12))), [0.9, 1.0, 1.1])
    assert np.max(np.hypot(grid[:, 0], grid[:, 1])) == pytest.approx(0.6)
    assert int(mech.task_space.on_rim().sum()) == 3 * 24
    assert all(limb.dh is not None for limb in mech.limbs)


# --- the URDFs cannot drift from the D–H tables ---------------------------------------------


def run_generator_check(folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(REPO / "scripts" / "dh_to_urdf.py"), str(folder), "--check"],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_generated_urdfs_match_the_dh_tables():
    result = run_generator_check(SEED)
    assert result.returncode == 0, result.stderr


def test_generator_check_fails_on_an_edited_urdf(tmp_path):
    folder = copy_robot(tmp_path)
    assert run_generator_check(folder).returncode == 0  # the copy itself is fine
    urdf = folder / "limb2.urdf"
    text = urdf.read_text(encoding="utf-8")
    assert text.count('xyz="0 0 -0.45"') == 1
    urdf.write_text(text.replace('xyz="0 0 -0.45"', 'xyz="0 0 -0.46"'), encoding="utf-8")
    result = run_generator_check(folder)
    assert result.returncode == 1
    assert "limb2.urdf" in result.stderr
    assert "limb1.urdf" not in result.stderr
    assert "regenerate with" in result.stderr


# --- bad input: a distinct error naming the culprit ------------------------------------------


def test_missing_urdf(tmp_path):
    folder = copy_robot(tmp_path)
    (folder / "limb2.urdf").unlink()
    with pytest.raises(URDFError) as info:
        load_mechanism(folder)
    assert type(info.value) is URDFError
    assert info.value.limb == "limb2"
    assert info.value.path == folder / "limb2.urdf"
    assert str(info.value).startswith(f"limb 'limb2' ({folder / 'limb2.urdf'}): file not found")


def test_malformed_urdf_xml(tmp_path):
    folder = copy_robot(tmp_path)
    urdf = folder / "limb3.urdf"
    urdf.write_text(urdf.read_text(encoding="utf-8")[:-30], encoding="utf-8")  # cut the end off
    with pytest.raises(URDFError) as info:
        load_mechanism(folder)
    assert type(info.value) is URDFError
    assert info.value.limb == "limb3"
    assert "limb 'limb3'" in str(info.value)
    assert "limb3.urdf" in str(info.value)
    assert "malformed XML" in str(info.value)


def test_limbs_with_different_root_links(tmp_path):
    folder = copy_robot(tmp_path)
    urdf = folder / "limb3.urdf"
    urdf.write_text(urdf.read_text(encoding="utf-8").replace('"base"', '"ground"'), encoding="utf-8")
    with pytest.raises(URDFError) as info:
        load_mechanism(folder)
    assert info.value.limb == "limb3"
    assert "its root link is 'ground' but limb 'limb1' starts at 'base'" in str(info.value)


def test_unknown_actuated_joint(tmp_path):
    folder = copy_robot(tmp_path, 'actuated = ["limb2_p3"]', 'actuated = ["limb2_slide"]')
    with pytest.raises(UnknownJointError) as info:
        load_mechanism(folder)
    assert type(info.value) is UnknownJointError
    assert (info.value.limb, info.value.joint) == ("limb2", "limb2_slide")
    assert "limb2_p3" in info.value.available
    assert str(info.value).startswith(
        "limb 'limb2': joint 'limb2_slide' listed as actuated is not in limb2.urdf (joints: "
    )


def test_platform_frames_do_not_coincide_at_home(tmp_path):
    # limb 3's leg 100 mm longer than needed for its platform frame to meet the others
    folder = copy_robot(
        tmp_path,
        "home = [0.0, -0.26060, 0.77621, 0.0, 0.0, 0.26060]",
        "home = [0.0, -0.26060, 0.87621, 0.0, 0.0, 0.26060]",
    )
    with pytest.raises(PlatformMismatchError) as info:
        load_mechanism(folder)
    assert type(info.value) is PlatformMismatchError
    assert info.value.limb == "limb3"
    assert info.value.distance_m == pytest.approx(0.1, abs=1e-5)
    assert info.value.angle_rad == pytest.approx(0.0, abs=1e-9)
    assert str(info.value).startswith(
        "limb 'limb3': its platform frame cannot be made to coincide with limb 'limb1' "
        "(closest mismatch 100 mm"
    )


MISSING_KEYS = [
    ('name = "r2rps_ups"\n', "", "name", "missing"),
    ("radius_m = 0.6", "", "task_space.radius_m", "missing"),
    ('urdf = "limb3.urdf"', "", "limbs[2].urdf", "missing"),
    ("position_m = [0.0, 0.0, 0.3]", "", "reference_point.position_m", "missing"),
]
MISTYPED_VALUES = [
    (
        "radius_m = 0.6",
        'radius_m = "0.6"',
        "task_space.radius_m",
        "expected float or int, got str '0.6'",
    ),
    ("layers = 3", "layers = 3.0", "task_space.layers", "expected int, got float 3.0"),
    (
        'actuated = ["limb2_p3"]',
        'actuated = "limb2_p3"',
        "limbs[1].actuated",
        "expected list, got str",
    ),
    (
        "position_m = [0.0, 0.0, 0.3]",
        "position_m = [0.0, 0.3]",
        "reference_point.position_m",
        "expected a list of 3 numbers",
    ),
    ('kind = "cylinder"', 'kind = "sphere"', "task_space.kind", "unknown kind 'sphere'"),
    (
        "rings = [8, 16, 24]",
        "rings = [8, 16.5, 24]",
        "task_space.rings",
        "expected a list of integers",
    ),
    (
        "rings = [8, 16, 24]",
        'rings = [8, "16", [24]]',
        "task_space.rings",
        "expected a list of numbers",
    ),
    ("beta = [0.5, 1.0,", 'beta = ["0.5x", 1.0,', "design.beta", "expected a list of numbers"),
    (
        'target = "0.05 mm"',
        'target = "0.05 furlong"',
        "design.target",
        "design.target: unknown unit 'furlong'",
    ),
]


@pytest.mark.parametrize(("old", "new", "key", "problem"), MISSING_KEYS + MISTYPED_VALUES)
def test_toml_with_a_missing_or_mistyped_key(tmp_path, old, new, key, problem):
    folder = copy_robot(tmp_path, old, new)
    with pytest.raises(MechanismFormatError) as info:
        load_mechanism(folder)
    assert type(info.value) is MechanismFormatError
    assert info.value.key == key
    assert str(info.value).startswith(f"{folder / 'mechanism.toml'}: key '{key}': {problem}")


def test_folder_without_mechanism_toml(tmp_path):
    with pytest.raises(MechanismFormatError) as info:
        load_mechanism(tmp_path)
    assert "mechanism.toml" in str(info.value) and "file not found" in str(info.value)


def test_from_models_names_an_unknown_actuated_joint():
    mech = load_mechanism(SEED)
    models = [limb.model for limb in mech.limbs]
    actuated = [["limb1_p3"], ["limb2_p3"], ["limb3_px"], []]
    with pytest.raises(UnknownJointError) as info:
        Mechanism.from_models(
            "copy",
            models,
            actuated,
            "platform",
            [0, 0, 0.3],
            TaskSpace(kind="points", points_m=np.zeros((1, 3))),
            homes=[limb.home for limb in mech.limbs],
        )
    assert (info.value.limb, info.value.joint) == ("limb3", "limb3_px")
    assert "is not in the model" in str(info.value)


def test_from_models_rebuilds_the_seed_robot():
    mech = load_mechanism(SEED)
    copy = Mechanism.from_models(
        "copy",
        [limb.model for limb in mech.limbs],
        [[limb.joint_names[a] for a in limb.actuated] for limb in mech.limbs],
        "platform",
        mech.reference_point_m,
        mech.task_space,
        limb_names=[limb.name for limb in mech.limbs],
        homes=[limb.home for limb in mech.limbs],
    )
    assert check_mechanism(copy).mobility == 3


# --- pkmtol check -------------------------------------------------------------------------


def test_check_report_of_the_seed_robot():
    report = check_mechanism(load_mechanism(SEED))
    assert report.n_joints == 21
    assert report.closure_rank == 18
    assert report.mobility == 3
    assert [limb.constraint_count for limb in report.limbs] == [0, 0, 0, 3]
    assert report.n_reachable == 147
    assert report.problems == ()
    worst = report.worst("inverse")
    assert worst is not None
    assert np.hypot(*worst.target_m[:2]) == pytest.approx(0.6)  # on the rim, as in the paper
    assert 1.0 < worst.inverse_condition < 1e3
    # every solution is inside the URDF limits
    for limb in report.limbs:
        for joint in limb.joints:
            assert joint.lower <= joint.grid_min <= joint.grid_max <= joint.upper


def test_cli_check_seed_robot(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines to match (piped output wraps at 100)
    assert main(["check", str(SEED)]) == 0
    out = capsys.readouterr().out
    assert "reachable: 147/147 points" in out
    assert "mobility: f = 3  (21 joints - rank 18 of the closure Jacobian at home; 3 actuators)" in out
    assert (
        "constraint wrenches per limb (6 - rank of its joint twists at home): "
        "limb1 0, limb2 0, limb3 0, limb4 3"
    ) in out
    assert re.search(r"limb1  limb1\.urdf  actuated: limb1_p3  constraint wrenches: 0", out)
    assert re.search(r"limb4  limb4\.urdf  actuated: none \(passive limb\)  constraint wrenches: 3", out)
    # joint rows carry their units: the actuated leg in mm, a revolute in deg
    assert re.search(r"limb1_p3\s+P\*\s+mm\s+400\.000\s+1600\.000", out)
    assert re.search(r"limb4_u1\s+R\s+deg\s+-90\.000\s+90\.000", out)
    assert "3 layers x (1 + 8 + 16 + 24) = 147 points" in out
    assert re.search(r"inverse kinematics .* worst at P = \(.*\) mm", out)
    assert out.rstrip().endswith("result: OK")


def test_cli_check_lists_unreachable_points_and_exits_1(tmp_path, capsys):
    folder = copy_robot(tmp_path, "radius_m = 0.6", "radius_m = 1.5")  # legs max out at 1.6 m
    assert main(["check", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "reachable: 80/147 points" in out
    assert "joint 'limb3_p3' would be at 1.64967, outside its limits [0.4, 1.6]" in out
    assert "... and 57 more unreachable points" in out
    assert "result: 67 of 147 task-space points are not reachable" in out


def test_cli_reports_a_pkmtol_error_with_exit_code_2(tmp_path, capsys):
    folder = copy_robot(tmp_path)
    (folder / "limb2.urdf").unlink()
    assert main(["check", str(folder)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("pkmtol: error: limb 'limb2' (")
    assert "file not found" in captured.err


def test_format_doc_example_is_the_seed_robot_file():
    doc = (REPO / "docs" / "mechanism-format.md").read_text(encoding="utf-8")
    example = doc.split("```toml\n", 1)[1].split("```", 1)[0]
    assert example == (SEED / "mechanism.toml").read_text(encoding="utf-8")
