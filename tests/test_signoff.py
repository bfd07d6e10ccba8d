"""The seed robot's sign-off numbers in every compensation mode: shares, stack-ups, capability, drawing."""

from __future__ import annotations

import csv
import io
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from pkmtol.design.job import DesignOptions, allocate
from pkmtol.design.signoff import sign_off, verified_sigma
from pkmtol.design.stackup import worst_case_norm_vertices
from pkmtol.exceptions import InvalidRequestError, MechanismFormatError
from pkmtol.model.drawing import DrawingSettings, read_drawing
from pkmtol.model.loader import load_mechanism
from pkmtol.present.report_tables import contribution_rows, drawing_rows, share_cells
from pkmtol.present.tables import summary_text, table_rows, to_csv, to_json

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"
FAST = {"samples": 1000, "exact_samples": 5, "verification_poses": 100, "claim_poses": 30}
#: The sign-off numbers below are those of the one-pose FOSM design (its shares are equal there).
FOSM = {**FAST, "method": "fosm"}


@pytest.fixture(scope="module")
def mech():
    return load_mechanism(ROBOT)


@pytest.fixture(scope="module")
def ideal(mech):
    return allocate(mech, DesignOptions(**FOSM))


@pytest.fixture(scope="module")
def calibrated(mech):
    return allocate(mech, DesignOptions(**FOSM, compensation="calibrated"))


@pytest.fixture(scope="module")
def traditional(mech):
    return allocate(mech, DesignOptions(**FOSM, compensation="none"))


def test_shares_of_the_fosm_design_are_equal_at_the_design_point(ideal):
    """Equal effect (Eq. 19): at the design point each of the n = 14 errors holds 1/14 of E[Δλ²]."""
    so = sign_off(ideal)
    c = so.contributions
    assert c.columns.size == 14 and so.design_index == ideal.worst_index
    np.testing.assert_allclose(c.at_design, 1 / 14, rtol=1e-9)
    assert c.noise_at_design == 0.0
    # ... and E[Δλ²] there is (Δλ*/β)²: FOSM's design equation
    assert math.sqrt(c.mean_square[so.design_index]) == pytest.approx(ideal.target_m / ideal.design_beta)
    # elsewhere the shares differ: δa_{1,4} reaches 35.8 % at grid pose 5
    k = ideal.pset.names.index("δa_{1,4}")
    pos = list(c.columns).index(k)
    assert c.worst[pos] == pytest.approx(0.358, abs=5e-4) and c.worst_pose[pos] == 5
    # from the mode's maps, exactly
    maps = ideal.maps
    s = verified_sigma(ideal)
    expected = (np.linalg.norm(maps.position[:, :, c.columns], axis=1) * s[c.columns]) ** 2
    np.testing.assert_allclose(c.shares, expected / expected.sum(axis=1)[:, None], rtol=1e-12)


def test_stack_up_and_capability_at_the_design_point(ideal):
    so = sign_off(ideal)
    w, cols = so.design_index, so.columns
    t = 3.0 * verified_sigma(ideal)[cols]
    L = ideal.maps.position[w][:, cols]
    # the worst case over the ±3σ box, checked by brute force over its 2¹⁴ vertices
    assert so.stackup.worst_case_m[w] == pytest.approx(worst_case_norm_vertices(L, t).value, rel=1e-12)
    assert so.stackup.worst_case_m[w] == pytest.approx(241.42e-6, abs=0.01e-6)
    # RSS of ±3σ is 3 × RMS, and FOSM's β·RMS is Δλ* at the design point
    assert so.stackup.rss_m[w] == pytest.approx(3 * ideal.target_m / ideal.design_beta, rel=1e-9)
    assert so.fosm_m[w] == pytest.approx(ideal.target_m, rel=1e-9)
    assert so.stackup.rss_m[w] <= so.stackup.worst_case_m[w] <= so.stackup.arithmetic_m[w]
    # the exact PPM is the claimed-vs-true table's exact reliability at the worst pose
    claim = next(c for c in ideal.claims if c.beta == ideal.design_beta)
    assert so.capability.ppm[w] == pytest.approx(1e6 * (1 - claim.exact_worst), abs=1e-3)
    assert so.capability.ppm[w] == pytest.approx(27086, abs=1)
    assert so.capability.cpk[w] == pytest.approx(0.766, abs=1e-3)
    # the exact Φ(2) quantile exceeds Δλ*: FOSM is slightly optimistic there (R = 97.29 % < 97.72 %)
    assert so.capability.quantile[w] == pytest.approx(51.40e-6, abs=0.01e-6)
    assert sign_off(ideal) is so  # cached


def test_drawing_callouts_of_the_seed_robot(ideal):
    so = sign_off(ideal)
    by = {d.name: d for d in so.drawings}
    assert len(by) == 14
    for d in so.drawings:
        assert d.tolerance == pytest.approx(3.0 * d.sigma)
    # limb 4 is a UP limb about O: its lengths are offsets of intersecting axes
    assert {n for n, d in by.items() if d.unit == "m"} == {n for n, d in by.items() if d.kind == "position"}
    assert by["δa_{1,4}"].zone_m == pytest.approx(2 * by["δa_{1,4}"].tolerance)
    phi = by["δφ_{1,4}"]  # the twist between the base z and limb4_u1's axis, nominally 90°
    assert (phi.kind, phi.feature, phi.datum, phi.about_datum) == (
        "perpendicularity",
        "limb4_u1",
        "base z",
        False,
    )
    theta = by["δθ_{1,4}"]  # a rotation about the base z: the axis swings about the datum
    assert (theta.kind, theta.about_datum) == ("angularity", True)
    assert theta.zone_m == pytest.approx(0.1 * math.tan(theta.tolerance))
    assert phi.nominal_angle_rad == pytest.approx(math.pi / 2)
    assert phi.zone_m == pytest.approx(0.1 * math.tan(phi.tolerance))
    assert by["δφ_{4,4}"].kind == "parallelism" and by["δθ_{e,4}"].kind == "angular position"
    rows = drawing_rows(ideal)
    assert rows[0][4:7] == ["share [%]", "worst share [%] (pose)", "callout"] and len(rows) == 15
    assert all(row[4] == "7.1" for row in rows[1:])
    assert any("perpendicularity of limb4_u1's axis to base z" in r[-1] for r in rows)
    assert any("angularity of limb4_u1's axis about base z's axis" in r[-1] for r in rows)


def test_drawing_convention_and_feature_lengths(mech):
    settings = DrawingSettings(convention="uniform", feature_lengths_m={"limb4_u1": 0.25})
    r = allocate(mech, DesignOptions(**FOSM, drawing=settings))
    so = sign_off(r)
    assert so.drawing.factor == pytest.approx(math.sqrt(3))
    phi = next(d for d in so.drawings if d.name == "δφ_{1,4}")
    assert phi.tolerance == pytest.approx(math.sqrt(3) * phi.sigma)
    assert phi.feature_length_m == 0.25 and phi.zone_m == pytest.approx(0.25 * math.tan(phi.tolerance))
    w = so.design_index
    # the worst case is homogeneous in t: √3/3 of the ±3σ one
    assert so.stackup.worst_case_m[w] == pytest.approx(241.42e-6 * math.sqrt(3) / 3, abs=0.01e-6)
    assert "√3" in summary_text(r)


def test_after_calibration_the_noise_has_its_share_and_the_maps_are_L(calibrated):
    so = sign_off(calibrated)
    c = so.contributions
    assert 0.0 < c.noise_at_design < 1.0
    np.testing.assert_allclose(c.shares.sum(axis=1) + c.noise_share, 1.0, rtol=1e-12)
    maps = calibrated.maps
    noise = maps.noise_m**2 * np.sum(maps.position_noise[so.design_index] ** 2)
    assert c.noise_at_design == pytest.approx(noise / c.mean_square[so.design_index], rel=1e-12)
    assert noise == pytest.approx(calibrated.noise_variance_m2, rel=1e-12)
    # the post-calibration map, not the ideal J: an identified error has no share
    assert not np.allclose(maps.position, calibrated.grid.J)
    assert all(calibrated.mode_classes[i] == "toleranced" for i in c.columns)
    rows = contribution_rows(calibrated)
    assert any(r[1] == "tracker noise" for r in rows)
    assert so.tilt_contributions is not None  # the tilt is reported after a calibration
    np.testing.assert_allclose(
        so.tilt_contributions.shares.sum(axis=1) + so.tilt_contributions.noise_share, 1.0, rtol=1e-9
    )


def test_traditional_mode_grades_the_lengths_of_limbs_1_to_3(traditional):
    so = sign_off(traditional)
    by = {d.name: d for d in so.drawings}
    a = by["δa_{1,1}"]  # a_1 = b_1 = 0.5 m
    assert a.kind == "size" and a.nominal_m == pytest.approx(0.5)
    assert a.it is not None and a.it.size_range_mm == (400, 500)
    assert a.it.it_um <= 2e6 * a.tolerance
    assert by["δa_{7,1}"].nominal_m == pytest.approx(0.25)  # e_1 = 0.25 m
    assert by["ξ_{a,1}"].kind == "joint zero"
    assert so.contributions.columns.size == 48


def test_every_tolerance_table_has_the_share_column(ideal):
    rows = table_rows(ideal)
    assert rows[0][-2:] == ["share [%]", "worst share [%] (pose)"]
    assert all(r[-2] == "7.1" for r in rows[1:])
    text = summary_text(ideal)
    for heading in ("Contributions to E[Δλ²]", "Stack-up of the drawing tolerances", "Process capability"):
        assert heading in text
    assert "new share [%]" in text and "Drawing tolerances" in text
    data = json.loads(to_json(ideal))
    sj = data["signoff"]
    assert sj["capability"]["ppm_exact"][ideal.worst_index] == pytest.approx(27086, abs=1)
    assert len(sj["drawing"]) == 14 and sj["convention"]["factor"] == 3.0
    np.testing.assert_allclose(sj["contributions"]["share_design_point"], 1 / 14, rtol=1e-9)
    table = list(csv.reader(io.StringIO(to_csv(ideal))))
    assert table[0][-3:] == ["share_percent", "worst_share_percent", "worst_share_pose"]
    row = next(r for r in table if r[0] == "δa_{1,4}")
    assert float(row[-3]) == pytest.approx(100 / 14, rel=1e-5) and row[-1] == "5"
    assert share_cells(ideal, tilt=True)  # the tilt's shares are available too


def test_method_design_shares(mech):
    r = allocate(mech, DesignOptions(**FAST, method="exact", criterion="worst"))
    so = sign_off(r)
    np.testing.assert_allclose(verified_sigma(r)[r.uncompensatable], r.method_design.sigma)
    # a uniform scale of the equal-effect shape keeps the shares equal
    np.testing.assert_allclose(so.contributions.at_design, 1 / 14, rtol=1e-9)
    text = summary_text(r)
    assert "design: the 'exact' design" in text


def test_orientation_target_gives_tilt_capability(mech):
    r = allocate(mech, DesignOptions(**FOSM, orientation_target_rad=2e-4))
    so = sign_off(r)
    assert so.tilt_capability is not None and so.tilt_contributions is not None
    assert so.tilt_capability.target == 2e-4
    assert "Δα [µrad]" in summary_text(r)


def test_drawing_table_is_read_and_checked(tmp_path, mech):
    joints = ["limb4_u1", "limb1_platform_attach"]
    s = read_drawing(
        {"convention": "normal", "k": 2, "feature_length": "50 mm", "feature_lengths": {"limb4_u1": "80 mm"},
         "nominals": {"δd_{2,4}": "250 mm"}},
        "m.toml",
        joints,
    )  # fmt: skip
    assert (s.k, s.feature_length_m, s.feature_length("limb4_u1"), s.feature_length("x")) == (
        2.0,
        0.05,
        0.08,
        0.05,
    )
    assert s.nominals_m == {"δd_{2,4}": 0.25}
    assert s.short_label == "±t = 2σ" and "95.45 %" in s.label
    for table, key, match in (
        ({"convnetion": "normal"}, "drawing.convnetion", "did you mean 'convention'"),
        ({"convention": "gauss"}, "drawing", "unknown drawing convention"),
        ({"convention": 3}, "drawing.convention", "expected"),
        ({"k": "3"}, "drawing.k", "number"),
        ({"k": 0}, "drawing", "positive"),
        ({"feature_length": 0.1}, "drawing.feature_length", "unit"),
        ({"feature_length": "1 parsec"}, "drawing.feature_length", "unit"),
        (
            {"feature_lengths": {"limb4_u9": "1 mm"}},
            "drawing.feature_lengths.limb4_u9",
            "did you mean 'limb4_u1'",
        ),
        ({"feature_lengths": "80 mm"}, "drawing.feature_lengths", "table"),
        ({"nominals": {"δd_{2,4}": "-5 mm"}}, "drawing", "≥ 0"),
    ):
        with pytest.raises(MechanismFormatError, match=match) as err:
            read_drawing(table, "m.toml", joints)
        assert err.value.key == key
    with pytest.raises(InvalidRequestError, match="k"):
        DrawingSettings(k=math.nan)
    # through the loader: nominals give a size with an IT grade, and an unknown name is refused
    folder = tmp_path / "robot"
    shutil.copytree(ROBOT, folder)
    text = (folder / "mechanism.toml").read_text(encoding="utf-8")
    (folder / "mechanism.toml").write_text(
        text + '\n[drawing]\nk = 3\n[drawing.nominals]\n"δd_{2,4}" = "250 mm"\n', encoding="utf-8"
    )
    m = load_mechanism(folder)
    assert m.extra["drawing"].nominals_m == {"δd_{2,4}": 0.25}
    d = next(x for x in sign_off(allocate(m, DesignOptions(**FOSM))).drawings if x.name == "δd_{2,4}")
    assert d.kind == "size" and d.it is not None and d.it.size_range_mm == (180, 250)
    (folder / "mechanism.toml").write_text(
        text + '\n[drawing.nominals]\n"δd_{9,4}" = "25 mm"\n', encoding="utf-8"
    )
    with pytest.raises(MechanismFormatError, match="no such error parameter"):
        sign_off(allocate(load_mechanism(folder), DesignOptions(**FOSM)))


def test_drawing_keys_are_registered_with_the_key_registry():
    """Once the mechanism key registry exists (model/keys.py), [drawing] and its keys are in it."""
    keys = pytest.importorskip("pkmtol.model.keys")
    from pkmtol.model.drawing import TABLE_KEYS

    assert "drawing" in keys.KNOWN_KEYS[""]
    assert keys.KNOWN_KEYS["drawing"] == frozenset(TABLE_KEYS)
    assert keys.KNOWN_KEYS["drawing.feature_lengths"] == keys.ANY
    assert keys.KNOWN_KEYS["drawing.nominals"] == keys.ANY
