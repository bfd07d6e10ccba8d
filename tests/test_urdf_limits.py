"""URDF joints without a range (CAD exports): revolute and continuous joints are read over [−π, π]
with a named warning, a prismatic joint is refused with a named error (issues 24.5, 26.2)."""

from __future__ import annotations

import math
import shutil
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from pkmtol import load_mechanism
from pkmtol.exceptions import MissingLimitError, MissingLimitWarning
from pkmtol.kinematics.check import check_mechanism
from pkmtol.model.urdf_xml import fill_missing_limits

REPO = Path(__file__).resolve().parents[1]
SEED = REPO / "robots" / "r2rps_ups"
# limb 1's three spherical-wrist revolutes carry [−π, π] in the seed's URDF and D–H table
S_LIMITS = '<limit lower="-3.141592653589793" upper="3.141592653589793"'


def seed_copy(tmp_path: Path, file: str, old: str, new: str, count: int) -> Path:
    folder = tmp_path / "robot"
    shutil.copytree(SEED, folder)
    path = folder / file
    text = path.read_text(encoding="utf-8")
    assert text.count(old) == count
    path.write_text(text.replace(old, new), encoding="utf-8")
    return folder


def load_with_warnings(folder: Path) -> tuple[object, list[MissingLimitWarning]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mech = load_mechanism(folder)
    return mech, [w.message for w in caught if isinstance(w.message, MissingLimitWarning)]


def test_revolute_limit_without_a_range_is_read_as_plus_minus_pi_and_named(tmp_path):
    folder = seed_copy(tmp_path, "limb1.urdf", S_LIMITS, "<limit", 3)
    mech, caught = load_with_warnings(folder)
    assert [w.joint for w in caught] == ["limb1_s4", "limb1_s5", "limb1_s6"]
    assert all(w.limb == "limb1" and (w.lower, w.upper) == (-math.pi, math.pi) for w in caught)
    assert "assumed [-3.14159, 3.14159] rad" in str(caught[0]) and "<limit lower=" in str(caught[0])
    limb = mech.limbs[0]
    np.testing.assert_array_equal(limb.model.lowerPositionLimit[3:], [-math.pi] * 3)
    np.testing.assert_array_equal(limb.model.upperPositionLimit[3:], [math.pi] * 3)
    # urdfdom alone reads them as [0, 0]; with ±π every grid point is reached again
    report = check_mechanism(mech)
    assert report.n_reachable == len(report.points) == 147


def test_a_missing_side_only_gets_its_default():
    root = ET.fromstring(
        '<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
        '<parent link="a"/><child link="b"/><limit lower="-2.0" effort="5" velocity="1"/></joint></robot>'
    )
    with pytest.warns(MissingLimitWarning, match="assumed \\[-2, 3.14159\\] rad") as caught:
        assert fill_missing_limits(root, "l", None)
    limit = root.find("joint/limit")
    assert (float(limit.get("lower")), float(limit.get("upper"))) == (-2.0, math.pi)
    assert limit.get("effort") == "5" and caught[0].message.joint == "j"


def test_continuous_joint_is_read_as_revolute_over_plus_minus_pi(tmp_path):
    old = '<joint name="limb1_s4" type="revolute">'
    folder = seed_copy(tmp_path, "limb1.urdf", old, old.replace("revolute", "continuous"), 1)
    mech, caught = load_with_warnings(folder)
    assert [w.joint for w in caught] == ["limb1_s4"] and "is continuous" in str(caught[0])
    limb = mech.limbs[0]
    assert limb.model.nq == 6 and limb.joint_kinds[3] == "R"
    assert (limb.model.lowerPositionLimit[3], limb.model.upperPositionLimit[3]) == (-math.pi, math.pi)


def test_prismatic_joint_without_a_range_is_refused_with_the_way_to_set_it(tmp_path):
    folder = seed_copy(tmp_path, "limb4.urdf", '<limit lower="0.3" upper="1.6"', "<limit", 1)
    with pytest.raises(MissingLimitError) as err:
        load_mechanism(folder)
    assert err.value.joint == "limb4_p3" and err.value.limb == "limb4"
    assert "stroke" in str(err.value) and '<limit lower="0.4" upper="1.6"' in str(err.value)


def test_prismatic_joint_without_a_limit_element_is_refused(tmp_path):
    old = '    <limit lower="0.3" upper="1.6" effort="1000" velocity="1" />\n'
    folder = seed_copy(tmp_path, "limb4.urdf", old, "", 1)
    with pytest.raises(MissingLimitError, match="limb4_p3"):
        load_mechanism(folder)


def test_bounded_joints_give_no_warning():
    _, caught = load_with_warnings(SEED)
    assert caught == []
