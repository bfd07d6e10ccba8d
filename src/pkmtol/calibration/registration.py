"""The errors a machine is left with once the workpiece is registered to it (a rigid fit removed).

A ballbar, a probed artifact and a tracker whose frame is identified cannot see where the machine
stands in K (docs/instruments.md): they calibrate its shape. A shop that calibrates that way
locates the workpiece by the machine itself (probing the part's datums: work offsets, a fixture
alignment), so a rigid motion of the whole machine does not reach the part. What is left is the
error field minus its best rigid motion: ``e_k − (t + ω × (p_k − p̄))`` at the held-out targets
``p_k``, with ``(t, ω)`` the least-squares fit over them, and the rotations minus ``ω``. This
module computes that figure; Δλ in K is not changed by it (docs/instruments.md, "Decisions").
"""

from __future__ import annotations

import numpy as np

from pkmtol.calibration.compensation import PoseErrors
from pkmtol.calibration.instruments.base import skew


def registered(errors: PoseErrors, points_m: np.ndarray) -> PoseErrors:
    """``errors`` at targets ``points_m`` (m, 3) with their least-squares rigid motion removed.

    The fit is the linearised rigid motion ``e ≈ t + ω × (p − p̄)`` over the solved targets (an
    exact rigid motion differs from it by ``|ω|² |p − p̄| / 2``: 0.3 µm at 1 mrad over 0.6 m);
    unsolved rows stay NaN.

    Returns:
        The registered errors (position [m] and rotation [rad] in K, as ``errors``).
    """
    pos, rot = np.asarray(errors.position_m, dtype=float), np.asarray(errors.rotation_rad, dtype=float)
    ok = np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(rot), axis=1)
    if ok.sum() < 3:
        return errors
    p = np.asarray(points_m, dtype=float)
    lever = p - p[ok].mean(axis=0)
    A = np.zeros((len(p), 3, 6))
    A[:, :, :3] = np.eye(3)
    A[:, :, 3:] = -skew(lever)  # ω × r = −[r]× ω
    fit = np.linalg.lstsq(A[ok].reshape(-1, 6), pos[ok].reshape(-1), rcond=None)[0]
    moved = np.einsum("kab,b->ka", A, fit)
    return PoseErrors(
        position_m=np.where(ok[:, None], pos - moved, np.nan),
        rotation_rad=np.where(ok[:, None], rot - fit[3:], np.nan),
        solved=errors.solved & ok,
    )
