"""Mobility and actuation are counted before the home solve (issue 29.3): too few, too many or
misplaced actuators get a message naming how many are needed, and ``pkmtol check`` exits 1."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from pkmtol import ClosedChain, load_mechanism
from pkmtol.cli import main
from pkmtol.exceptions import MobilityError
from pkmtol.kinematics.mobility import count_mobility

REPO = Path(__file__).resolve().parents[1]
SEED = REPO / "robots" / "r2rps_ups"
ROBOTS = sorted(p.parent for p in (REPO / "robots").glob("*/mechanism.toml"))
TOO_FEW = (
    "too few actuators: mobility 3 (21 joints − rank 18 of the closure Jacobian) needs 3 actuated joints, "
    "2 given"
)


def seed_with(tmp_path: Path, actuated: dict[str, str]) -> Path:
    """A seed copy whose limbs' ``actuated`` lists are replaced (limb name → TOML list)."""
    folder = tmp_path / "robot"
    shutil.copytree(SEED, folder)
    toml = folder / "mechanism.toml"
    text = toml.read_text(encoding="utf-8")
    for limb, value in actuated.items():
        head, sep, tail = text.partition(f'name = "{limb}"\nurdf = "{limb}.urdf"\nactuated = ')
        assert sep, limb
        text = head + sep + value + tail[tail.index("\n") :]
    toml.write_text(text, encoding="utf-8")
    return folder


def test_check_with_an_actuator_removed_exits_1_and_names_how_many_are_needed(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines to match (piped output wraps at 100)
    folder = seed_with(tmp_path, {"limb3": "[]"})
    assert main(["check", str(folder)]) == 1  # before: exit 2, "platform frame cannot be made to coincide"
    out = capsys.readouterr().out
    assert "mobility: f = 3  (21 joints - rank 18 of the closure Jacobian at home; 2 actuators)" in out
    assert "task space: not solved" in out
    result = out.rstrip().splitlines()[-1]
    assert result.startswith("result: " + TOO_FEW + " (limb1.limb1_p3, limb2.limb2_p3); actuate 1 more joint")
    # a limb takes one actuator: the candidates are on the limbs without one
    assert "limb3.limb3_p3" in result and "limb1.limb1_u1" not in result


def test_the_home_solve_of_other_commands_raises_the_mobility_error(tmp_path):
    mech = load_mechanism(seed_with(tmp_path, {"limb3": "[]"}))
    with pytest.raises(MobilityError, match="needs 3 actuated joints, 2 given"):
        ClosedChain(mech).home()
    assert main(["allocate", str(tmp_path / "robot"), "--samples", "300", "--no-progress"]) == 2


def test_too_many_actuators(tmp_path):
    mech = load_mechanism(seed_with(tmp_path, {"limb4": '["limb4_p3"]'}))
    mob = ClosedChain(mech).mobility()
    assert (mob.mobility, mob.n_actuators) == (3, 4)
    assert "too many actuators" in mob.problems[0] and "make 1 of them passive" in mob.problems[0]


def test_actuators_that_leave_a_passive_motion(tmp_path):
    # limb 2's spherical joint instead of its leg: the leg's length is then free with the others held
    mech = load_mechanism(seed_with(tmp_path, {"limb2": '["limb2_s4"]'}))
    mob = ClosedChain(mech).mobility()
    assert (mob.mobility, mob.n_actuators, mob.free_motions) == (3, 3, 1)
    assert "do not determine the pose" in mob.problems[0]


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda p: p.name)
def test_every_bundled_robot_is_properly_actuated(robot):
    mech = load_mechanism(robot)
    mob = ClosedChain(mech).mobility()
    assert mob.closed and mob.problems == ()
    assert mob.mobility == mech.n_actuators and mob.free_motions == 0


def test_the_seed_robot_has_the_papers_three_degrees_of_freedom():
    # the paper's R(2-RPS&RP)&UPS: 3 DOF (two rotations and a translation of the platform)
    mob = ClosedChain(load_mechanism(SEED)).mobility()
    assert (mob.n_joints, mob.closure_rank, mob.mobility) == (21, 18, 3)


def test_count_on_a_planar_four_bar():
    # a planar 4-bar (links 1, 2, 2, 2.5; 4 revolutes, 1 loop of 2 planar rows): f = 4 − 3 = 1
    lengths = np.array([2.0, 2.0, 2.5])

    def evaluate(q):  # loop closure: the chain's tip back at the ground pivot (1, 0), and its angle
        angles = np.cumsum(q[:3])
        tip = np.array([np.sum(lengths * np.cos(angles)), np.sum(lengths * np.sin(angles))])
        res = np.array([tip[0] - 1.0, tip[1], 0.0])
        jac = np.zeros((3, 4))
        for k in range(3):
            jac[0, k] = -np.sum(lengths[k:] * np.sin(angles[k:]))
            jac[1, k] = np.sum(lengths[k:] * np.cos(angles[k:]))
        res[2] = np.sum(q) - 2 * np.pi  # the last revolute closes the angle
        jac[2, :] = 1.0
        return res, jac

    q0 = np.array([1.0, 2.0, 1.5, 2 * np.pi - 4.5])
    mob = count_mobility(evaluate, q0, ["a.j1", "b.j2", "c.j3", "d.j4"], [0], task_dof=None)
    assert mob.closed and (mob.closure_rank, mob.mobility, mob.free_motions) == (3, 1, 0)
    none = count_mobility(evaluate, q0, ["a.j1", "b.j2", "c.j3", "d.j4"], [], task_dof=None)
    assert none.problems[0].startswith("too few actuators: mobility 1")
