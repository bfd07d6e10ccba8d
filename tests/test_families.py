"""`pkmtol new`: the families reproduce the bundled robots from their documented dimensions, and a
new variant is written only when it loads and passes the check."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from pkmtol.cli import main
from pkmtol.exceptions import InvalidArgumentError, OutputError, RobotCheckError
from pkmtol.kinematics.robot_folder import new_robot
from pkmtol.model.families import FAMILIES, draft
from pkmtol.model.loader import load_mechanism
from pkmtol.model.robot_files import render_toml, urdfs_from_toml

REPO = Path(__file__).resolve().parents[1]

#: The dimensions docs/robots.md gives for each bundled robot (written out, not the defaults).
DOCUMENTED = {
    "r2rps_ups": dict(
        ups_base=0.5, rps_base=0.45, ups_platform=0.25, rps_platform=0.25, height=0.75, offset=0.3,
        leg_stroke=(0.4, 1.6), centre_stroke=(0.3, 1.6), task_radius=0.6, task_z=(0.9, 1.1),
    ),
    "tricept": dict(
        base_radius=0.45, platform_radius=0.18, height=0.9, offset=0.3, leg_stroke=(0.6, 1.4),
        centre_stroke=(0.5, 1.3), task_radius=0.4, task_z=(1.1, 1.3),
    ),
    "sprint_z3": dict(
        rail_radius=0.3, platform_radius=0.2, rod_length=0.4, slider_height=0.2, offset=0.3,
        slider_stroke=(0.0, 0.5), task_radius=0.15, task_z=(0.8, 0.95),
    ),
    "exechon": dict(
        u_spacing=0.3, s_offset=0.45, upr_platform=0.12, spr_platform=0.18, height=0.9, offset=0.3,
        leg_stroke=(0.6, 1.4), task_radius=0.4, task_z=(1.1, 1.3),
    ),
    "r2rps_ups_wrist": dict(
        ups_base=0.5, rps_base=0.45, ups_platform=0.25, rps_platform=0.25, height=0.75, offset=0.3,
        leg_stroke=(0.4, 1.6), centre_stroke=(0.3, 1.6), c_height=0.15, nose=0.12, tool_length=0.15,
        task_radius=0.3, task_z=(1.15, 1.3), task_center_x=0.19,
    ),
    "tricept_wrist": dict(
        base_radius=0.45, platform_radius=0.18, height=0.9, offset=0.3, leg_stroke=(0.6, 1.4),
        centre_stroke=(0.5, 1.3), c_height=0.15, nose=0.12, tool_length=0.15, task_radius=0.2,
        task_z=(1.35, 1.5), task_center_x=0.19,
    ),
}  # fmt: skip


#: Bundled robots that no family writes, and what writes them (issue 18: loops inside limbs, a planar task).
OTHER_GENERATORS = {
    "delta": "scripts/delta_urdf.py (URDF trees and mechanism.toml; --check in tests/test_loops.py)",
    "fivebar": "its mechanism.toml's D–H tables through scripts/dh_to_urdf.py (tests/test_planar.py)",
    "delta_epr": "scripts/limbs_to_epr.py from robots/delta (--check in tests/test_tree_inputs.py)",
}


def test_every_bundled_robot_has_a_family():
    bundled = {p.parent.name for p in (REPO / "robots").glob("*/mechanism.toml")}
    assert set(FAMILIES) == set(DOCUMENTED)
    assert bundled == set(FAMILIES) | set(OTHER_GENERATORS)
    assert not set(FAMILIES) & set(OTHER_GENERATORS)


@pytest.mark.parametrize("family", sorted(DOCUMENTED))
def test_family_reproduces_the_bundled_robot(family, tmp_path):
    robot = draft(family, **DOCUMENTED[family])
    text = render_toml(robot, family)
    bundled = REPO / "robots" / family
    assert tomllib.loads(text) == tomllib.loads((bundled / "mechanism.toml").read_text(encoding="utf-8"))
    (tmp_path / "mechanism.toml").write_text(text, encoding="utf-8")
    urdfs = urdfs_from_toml(tmp_path)
    assert sorted(p.name for p in urdfs) == sorted(p.name for p in bundled.glob("*.urdf"))
    for path, urdf in urdfs.items():
        assert urdf == (bundled / path.name).read_text(encoding="utf-8"), path.name


def test_pkmtol_new_with_no_dimension_writes_the_bundled_tricept(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines to match (piped output wraps at 100)
    out = tmp_path / "tricept"
    assert main(["new", "tricept", "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "147/147 task-space points reachable: OK" in printed
    assert "constraint wrenches leg1 0, leg2 0, leg3 0, centre 3" in printed
    bundled = REPO / "robots" / "tricept"
    for f in bundled.iterdir():
        if f.suffix == ".urdf":
            assert (out / f.name).read_bytes() == f.read_bytes()
    assert tomllib.loads((out / "mechanism.toml").read_text(encoding="utf-8")) == tomllib.loads(
        (bundled / "mechanism.toml").read_text(encoding="utf-8")
    )


def test_a_variant_is_written_checked_and_loads(tmp_path):
    made = new_robot("tricept", tmp_path / "wide", base_radius=0.55)
    assert made.report.problems == () and made.report.n_reachable == 147
    assert [p.name for p in made.files] == [
        "mechanism.toml",
        "leg1.urdf",
        "leg2.urdf",
        "leg3.urdf",
        "centre.urdf",
    ]
    mech = load_mechanism(tmp_path / "wide")
    assert mech.name == "wide"
    # the U joints moved out to 0.55 m: leg 1's first D–H row carries it
    assert mech.limbs[0].dh.links[0, 2] == pytest.approx(0.55)
    assert "--base-radius 550mm" in made.command  # as `pkmtol new` takes it: with its unit
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wide"]  # no temporary folder left


def test_a_variant_that_fails_the_check_writes_nothing(tmp_path):
    with pytest.raises(RobotCheckError, match=r"117 of 147 task-space points are not reachable") as info:
        new_robot("tricept", tmp_path / "big", task_radius=1.5)
    assert info.value.family == "tricept"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "family, dims, option, needle",
    [
        ("sprint_z3", {"rod_length": 0.05}, "--rod-length", "must be longer than"),
        ("tricept", {"leg_stroke": (2.0, 1.0)}, "--leg-stroke", "MIN MAX"),
        ("tricept", {"base_radius": 2.0}, "--leg-stroke", "outside this stroke"),
        ("exechon", {"height": -1.0}, "--height", "must be > 0"),
        ("r2rps_ups", {"height": float("nan")}, "--height", "finite"),
        ("tricept", {"base_radus": 0.5}, "dimension", "did you mean 'base_radius'"),
        ("tricep", {}, "family", "did you mean 'tricept'"),
    ],
)
def test_bad_dimensions_name_the_option(tmp_path, family, dims, option, needle):
    with pytest.raises(InvalidArgumentError, match=needle) as info:
        new_robot(family, tmp_path / "x", **dims)
    assert info.value.argument == option
    assert list(tmp_path.iterdir()) == []


def test_pkmtol_new_takes_lengths_with_units_and_refuses_bare_numbers(tmp_path, capsys):
    out = tmp_path / "wide"
    argv = ["new", "tricept", "--base-radius", "550mm", "--leg-stroke", "0.6m", "1400mm", "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "--base-radius 550mm" in printed and "--leg-stroke 600mm 1400mm" in printed
    assert load_mechanism(out).limbs[0].dh.links[0, 2] == pytest.approx(0.55)
    # 550 meant mm: refused for its missing unit, not read as 550 m (then a leg-stroke error)
    assert main(["new", "tricept", "--base-radius", "550", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pkmtol: error: --base-radius 550: '550' has no unit") and "550 mm" in err
    assert main(["new", "tricept", "--task-z", "1.1m", "1300", "--out", str(tmp_path / "x")]) == 2
    assert "--task-z 1.1m 1300: '1300' has no unit" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_an_existing_folder_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "taken"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["new", "exechon", "--out", str(out)]) == 2
    assert "exists and is not an empty folder" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    with pytest.raises(OutputError):
        new_robot("exechon", out)
