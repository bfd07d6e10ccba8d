"""Registering the workpiece: an error field's best rigid motion removed (calibration/registration.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pkmtol.calibration.compensation import PoseErrors
from pkmtol.calibration.registration import registered


def _field(rng, m=50):
    points = rng.uniform(-0.6, 0.6, (m, 3)) + np.array([0.0, 0.0, 1.0])
    shape = rng.standard_normal((m, 3)) * 1e-5
    rot = rng.standard_normal((m, 3)) * 1e-5
    return points, shape, rot


def test_an_exact_rigid_motion_is_removed_to_its_second_order():
    rng = np.random.default_rng(0)
    points, _, _ = _field(rng)
    motion = pin.SE3(pin.exp3(np.array([1e-3, -5e-4, 8e-4])), np.array([2e-4, -1e-4, 3e-4]))
    moved = np.array([motion.act(p) for p in points])
    rot = np.tile(pin.log3(motion.rotation), (len(points), 1))
    out = registered(PoseErrors(moved - points, rot, np.ones(len(points), dtype=bool)), points)
    # |ω|² |r| / 2 with |ω| = 1.4 mrad, |r| ≤ 0.9 m: ≤ 1 µm
    assert np.nanmax(np.linalg.norm(out.position_m, axis=1)) < 1e-6
    assert np.nanmax(np.abs(out.rotation_rad)) < 1e-7  # ω fitted from the positions: |ω|² again


def test_a_rigid_motion_added_to_any_field_does_not_change_what_is_left():
    rng = np.random.default_rng(1)
    points, shape, rot = _field(rng)
    t, w = rng.standard_normal(3) * 1e-4, rng.standard_normal(3) * 1e-4
    rigid = t + np.cross(w, points - points.mean(axis=0))
    ok = np.ones(len(points), dtype=bool)
    a = registered(PoseErrors(shape, rot, ok), points)
    b = registered(PoseErrors(shape + rigid, rot + w, ok), points)
    np.testing.assert_allclose(b.position_m, a.position_m, atol=1e-18)
    np.testing.assert_allclose(b.rotation_rad, a.rotation_rad, atol=1e-18)
    # and what is left is orthogonal to every rigid motion over the targets
    assert abs(np.sum(a.position_m)) < 1e-17 * len(points) + 1e-15
    assert np.linalg.norm(a.position_m) < np.linalg.norm(shape)


def test_unsolved_targets_stay_nan_and_do_not_enter_the_fit():
    rng = np.random.default_rng(2)
    points, shape, rot = _field(rng)
    ok = np.ones(len(points), dtype=bool)
    bad = shape.copy()
    bad[3] = np.nan
    out = registered(PoseErrors(bad, rot, ok), points)
    assert np.isnan(out.position_m[3]).all() and not out.solved[3]
    keep = np.arange(len(points)) != 3
    ref = registered(PoseErrors(shape[keep], rot[keep], ok[keep]), points[keep])
    np.testing.assert_allclose(out.position_m[keep], ref.position_m, atol=1e-18)
