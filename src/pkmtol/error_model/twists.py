"""Error twists at a pose: the raw error columns of a limb (Pinocchio's kinematic regressor), frames K and K'.

Twists are ``[v; ω]``; "local" is the platform frame, K' has its origin at the platform point O'
and the axes of K (Pinocchio's LOCAL_WORLD_ALIGNED).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pkmtol.model.limb import Limb

_EYE6 = np.eye(6)


def raw_columns_local(
    limb: Limb, model: pin.Model, data: pin.Data, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, pin.SE3]:
    """Raw error columns and joint twists of a limb at ``q``, in the platform frame.

    Returns:
        ``(raw, jac, oMp)``: ``raw`` (6, 6·(nq+1) + nq) maps raw errors to the platform pose error
        ``δ`` (``oMp_actual = oMp · exp6(δ)``, local frame); ``jac`` (6, nq) the local frame
        Jacobian; ``oMp`` the platform placement.
    """
    fid = limb.platform_frame
    pin.computeJointJacobians(model, data, q)
    oMp = pin.updateFramePlacement(model, data, fid).copy()
    jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL)
    n_reg = 6 * limb.nq
    raw = np.empty((6, n_reg + 6 + limb.nq))
    raw[:, :n_reg] = pin.computeFrameKinematicRegressor(model, data, fid, pin.LOCAL)
    raw[:, n_reg : n_reg + 6] = _EYE6
    raw[:, n_reg + 6 :] = jac
    return raw, jac, oMp


def to_k_prime(rotation: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Express local-frame twists (6, k) in K' (origin O', axes of K): ``diag(R, R) · local``."""
    out = np.empty_like(local)
    out[:3] = rotation @ local[:3]
    out[3:] = rotation @ local[3:]
    return out


def pose_error_twist(nominal: pin.SE3, actual: pin.SE3) -> np.ndarray:
    """Pose error ``$_t = diag(R, R) log6(X_nom⁻¹ X_act)`` in K' (6,) [m, rad]."""
    d = pin.log6(nominal.actInv(actual)).vector
    r = nominal.rotation
    return np.concatenate([r @ d[:3], r @ d[3:]])
