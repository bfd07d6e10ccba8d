"""Internal loops of a limb: closure residuals and their Jacobians, for one pose or stacked over poses.

A loop of a limb (:class:`~pkmtol.model.limb.LimbLoop`) joins two frames ``a`` and ``b`` of the
limb's tree. Its closure equations, with ``J_a``, ``J_b`` Pinocchio's LOCAL frame Jacobians:

* ``6d``: ``r = log6(oMa⁻¹ oMb)`` (6, in frame a), ``∂r = Jlog6(E) (J_b − Ad(E⁻¹) J_a) dq`` with
  ``E = oMa⁻¹ oMb`` — the closure of two limbs' platform frames, inside one limb;
* ``3d``: ``r = p_b − p_a`` (3, in K), ``∂r = (R_b J_b,v − R_a J_a,v) dq`` (the linear rows of the
  LOCAL_WORLD_ALIGNED Jacobians).

A loop's closure error is the placement error of its frame b, ``oMb · exp6(ε)``; its effect on the
residual is the same expression with ``J_b dq`` replaced by ``ε`` (``6d``) or ``R_b ε_v`` (``3d``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from pkmtol.kinematics import se3_batch
from pkmtol.model.limb import Limb, LimbLoop


def loop_rows(
    loop: LimbLoop, oMa: pin.SE3, oMb: pin.SE3, ja: np.ndarray, jb: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residual, Jacobian and the map of frame b's local motion, of one loop at one pose.

    Args:
        loop: The loop.
        oMa: Placement of frame a in K.
        oMb: Placement of frame b in K.
        ja: Shape (6, k): LOCAL motion of frame a per unit of ``k`` variables (joints, errors).
        jb: Shape (6, k): LOCAL motion of frame b per unit of the same variables.

    Returns:
        ``(r, dr, to_b)``: the residual (rows,) [m, rad], its derivative (rows, k) and the
        matrix (rows, 6) that maps a LOCAL motion of frame b (its closure error ε) to the residual.
    """
    if loop.kind == "6d":
        e = oMa.actInv(oMb)
        jl = pin.Jlog6(e)
        return pin.log6(e).vector, jl @ jb - (jl @ e.toActionMatrixInverse()) @ ja, jl
    ra, rb = oMa.rotation, oMb.rotation
    to_b = np.zeros((3, 6))
    to_b[:, :3] = rb
    return oMb.translation - oMa.translation, rb @ jb[:3] - ra @ ja[:3], to_b


def loop_rows_many(
    loop: LimbLoop, ha: np.ndarray, hb: np.ndarray, ja: np.ndarray, jb: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`loop_rows`'s residual (b, rows) and Jacobian (b, rows, k) for stacked poses.

    Args:
        loop: The loop.
        ha: Shape (b, 4, 4): placements of frame a in K.
        hb: Shape (b, 4, 4): placements of frame b in K.
        ja: Shape (b, 6, k): LOCAL Jacobians of frame a.
        jb: Shape (b, 6, k): LOCAL Jacobians of frame b.

    A ``6d`` loop whose frames are near a half turn apart (where the stacked ``log3`` is not
    reliable) is evaluated by Pinocchio for that pose.
    """
    ra, pa = ha[:, :3, :3], ha[:, :3, 3]
    rb, pb = hb[:, :3, :3], hb[:, :3, 3]
    if loop.kind == "3d":
        return pb - pa, rb @ jb[:, :3] - ra @ ja[:, :3]
    rat = np.swapaxes(ra, 1, 2)
    re = rat @ rb
    pe = (rat @ (pb - pa)[:, :, None])[:, :, 0]
    nu, jl, near = se3_batch.log6_and_jacobian(re, pe)
    jac = jl @ jb - jl @ se3_batch.act_inverse(re, pe, ja)
    for k in np.flatnonzero(near):
        r, d, _ = loop_rows(loop, pin.SE3(ha[k]), pin.SE3(hb[k]), ja[k], jb[k])
        nu[k], jac[k] = r, d
    return nu, jac


def frame_placements(
    model: pin.Model, data: pin.Data, loop: LimbLoop
) -> tuple[pin.SE3, pin.SE3, np.ndarray, np.ndarray]:
    """``(oMa, oMb, J_a, J_b)`` of a loop after ``computeJointJacobians`` on ``data`` (LOCAL)."""
    oma = pin.updateFramePlacement(model, data, loop.frame_a)
    omb = pin.updateFramePlacement(model, data, loop.frame_b)
    ja = pin.getFrameJacobian(model, data, loop.frame_a, pin.LOCAL)
    jb = pin.getFrameJacobian(model, data, loop.frame_b, pin.LOCAL)
    return oma, omb, ja, jb


def loop_gaps(limb: Limb, model: pin.Model, q: np.ndarray) -> list[tuple[LimbLoop, float, float]]:
    """Per loop of ``limb`` at joint values ``q``: ``(loop, translation gap [m], rotation gap [rad])``.

    The rotation gap of a ``3d`` loop is 0 (only its points must coincide).
    """
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    out = []
    for lp in limb.loops:
        oma, omb = data.oMf[lp.frame_a], data.oMf[lp.frame_b]
        dist = float(np.linalg.norm(omb.translation - oma.translation))
        ang = float(np.linalg.norm(pin.log3(oma.rotation.T @ omb.rotation))) if lp.kind == "6d" else 0.0
        out.append((lp, dist, ang))
    return out


def loop_layout(limbs: Sequence[Limb], first_row: int) -> tuple[list[list[tuple[LimbLoop, slice]]], int]:
    """The rows of every limb's loops in a system whose loop rows start at ``first_row``.

    Returns:
        ``(blocks, end)``: per limb, ``(loop, rows)`` for each of its loops, and the row after the last.
    """
    row = first_row
    blocks = []
    for limb in limbs:
        entry = []
        for lp in limb.loops:
            entry.append((lp, slice(row, row + lp.rows)))
            row += lp.rows
        blocks.append(entry)
    return blocks, row
