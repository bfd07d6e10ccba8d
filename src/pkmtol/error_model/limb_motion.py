"""A limb with internal loops seen from the platform: its motion space T̃ and effective error columns E'.

At a pose, a limb's loop rows are ``C dq + D δ = 0`` (``C`` the loops' joint Jacobian, ``D`` their
raw-error columns, :mod:`pkmtol.kinematics.loops`) and its platform twist is
``$ = J_P dq + E_P δ`` (K'). With ``p`` the passive joints and ``C_p⁺`` the pseudo-inverse of their
columns (SVD ``C_p = U S Vᵀ``, rank ``r``):

* the limb's **motion space** ``T̃ = J_P Z``: ``Z``'s first column moves the actuator by 1 and the
  passive joints by ``−C_p⁺ C_a`` (the loops stay closed), the others are a basis ``V[:, r:]`` of the
  passive motions that keep the loops closed (``null(C_p)``);
* the **effective error columns** ``E' = E_P − J_P,p C_p⁺ D``: the platform twist of an error once
  the passive joints have closed the loops again. The choice of that passive motion is free up to
  ``null(C_p)``, i.e. up to a twist in ``T̃``, which every actuation and constraint wrench of the
  limb annihilates: the separation does not depend on it;
* rows ``U[:, r:]ᵀ D`` (when the loops' equations are dependent, ``r`` < rows): the part of an error
  no joint motion of the limb can close — an assembly error inside the limb, like the
  over-constrained mechanisms' incompatible part (docs/theory.md, "General loops").

Then :func:`~pkmtol.error_model.separation.separate` treats ``(T̃, E')`` as it treats a serial
limb's ``(T, E)``, the actuator being column 0 of ``T̃``. A limb without loops has ``T̃ = T`` (its
columns reordered, actuator first) and ``E' = E``; ``separate`` gives it today's path, and the
reduction test runs it through this one too (``separate(..., general=True)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import MobilityError
from pkmtol.kinematics.loops import loop_rows_many
from pkmtol.model.limb import Limb

#: Relative singular-value threshold for the rank of the loops' passive columns.
LOOP_RANK_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class LoopMotion:
    """A limb's motion space and effective error columns at ``b`` poses (K', SI units).

    Attributes:
        twists: Shape (b, 6, k): ``T̃``; column 0 is the actuated motion when the limb is actuated.
        errors: Shape (b, 6, m): ``E'`` per parameter of the limb (the set's selection applied).
        incompatible: Shape (b, rows − r, m): the loops' part no joint motion closes.
        actuated: ``(0,)`` for an actuated limb, else ``()`` (the column of T̃ that is actuated).
        bad: Shape (b,): poses where the rank differs from the others' (the per-pose path decides).
    """

    twists: np.ndarray
    errors: np.ndarray
    incompatible: np.ndarray
    actuated: tuple[int, ...]
    bad: np.ndarray


def raw_rows_many(
    limb: Limb, model: pin.Model, data: pin.Data, qs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Raw platform columns and loop rows of a limb with loops at poses ``qs`` (b, nq), local frames.

    Returns:
        ``(E_P, J_P, C, D, rotations)``: ``E_P`` (b, 6, n_raw) the platform pose error per raw error
        (platform frame), ``J_P`` (b, 6, nq) its LOCAL Jacobian, ``C`` (b, rows, nq) and ``D``
        (b, rows, n_raw) the loop rows (:func:`~pkmtol.kinematics.loops.loop_rows_many`), and the
        platform rotations (b, 3, 3).
    """
    b, nq, n_raw = len(qs), limb.nq, limb.n_raw
    n_reg = 6 * nq
    off = 6 * limb.n_origins
    e_p = np.zeros((b, 6, n_raw))
    e_p[:, :, n_reg : n_reg + 6] = np.eye(6)
    rot = np.empty((b, 3, 3))
    sides = [[np.zeros((b, 6, n_raw)) for _ in range(2)] for _ in limb.loops]
    placements = [[np.empty((b, 4, 4)) for _ in range(2)] for _ in limb.loops]
    for n, lp in enumerate(limb.loops):
        for side, f in enumerate((lp.frame_a, lp.frame_b)):
            if f in limb.attach_frames:  # a loop side on the platform frame moves with its attachment
                sides[n][side][:, :, n_reg : n_reg + 6] = np.eye(6)
    for k in range(b):
        pin.computeJointJacobians(model, data, qs[k])
        rot[k] = pin.updateFramePlacement(model, data, limb.platform_frame).rotation
        e_p[k, :, :n_reg] = pin.computeFrameKinematicRegressor(model, data, limb.platform_frame, pin.LOCAL)
        e_p[k, :, off:] = pin.getFrameJacobian(model, data, limb.platform_frame, pin.LOCAL)
        for n, lp in enumerate(limb.loops):
            for side, f in enumerate((lp.frame_a, lp.frame_b)):
                placements[n][side][k] = pin.updateFramePlacement(model, data, f).homogeneous
                sides[n][side][k, :, :n_reg] = pin.computeFrameKinematicRegressor(model, data, f, pin.LOCAL)
                sides[n][side][k, :, off:] = pin.getFrameJacobian(model, data, f, pin.LOCAL)
    rows_c, rows_d = [np.zeros((b, 0, nq))], [np.zeros((b, 0, n_raw))]
    for n, lp in enumerate(limb.loops):
        blk = 6 * (nq + 1 + n)
        sides[n][1][:, :, blk : blk + 6] = np.eye(6)  # the loop's own closure error moves frame b
        _, d = loop_rows_many(lp, placements[n][0], placements[n][1], sides[n][0], sides[n][1])
        rows_d.append(d)
        rows_c.append(d[:, :, off:])  # an offset column is the joint's column
    c = np.concatenate(rows_c, axis=1)
    return e_p, e_p[:, :, off:], c, np.concatenate(rows_d, axis=1), rot


def eliminate_loops(
    limb: Limb, t: np.ndarray, e: np.ndarray, c: np.ndarray, d: np.ndarray, where: np.ndarray
) -> LoopMotion:
    """``T̃``, ``E'`` and the incompatible rows from stacked ``T`` (b, 6, nq), ``E`` (b, 6, m) in K'.

    Args:
        limb: The limb.
        t: Joint twists (the platform Jacobian in K').
        e: The platform error columns of the limb's parameters in K'.
        c: Loop rows per joint (b, rows, nq).
        d: Loop rows per parameter (b, rows, m).
        where: Shape (b, 3): the position of P at each pose, for messages [m].

    Raises:
        MobilityError: the actuated joint cannot move with the loops closed (its column of the
            loop rows is outside the passive joints' span): the loops lock the actuator.
    """
    b, nq = t.shape[0], limb.nq
    passive = np.array(limb.passive, dtype=int)
    cp = c[:, :, passive]
    u, sv, vt = np.linalg.svd(cp)
    ranks = np.sum(sv > LOOP_RANK_TOLERANCE * np.maximum(sv[:, :1], 1.0), axis=1)
    rank = int(np.bincount(ranks).argmax())
    r = slice(0, rank)
    pinv = np.swapaxes(vt[:, r], 1, 2) @ (np.swapaxes(u[:, :, r], 1, 2) / sv[:, r, None])  # (b, np, rows)
    null = np.swapaxes(vt[:, rank:], 1, 2)  # (b, np, np − rank)
    cols = []
    if limb.actuated:
        a = limb.actuated[0]
        z0 = np.zeros((b, nq))
        z0[:, a] = 1.0
        z0[:, passive] = -(pinv @ c[:, :, a : a + 1])[:, :, 0]
        closed = np.abs(np.einsum("bij,bj->bi", c, z0)).max(axis=1, initial=0.0)
        scale = np.maximum(1.0, np.abs(c[:, :, a]).max(axis=1, initial=0.0))
        locked = np.flatnonzero((closed > 1e-6 * scale) & (ranks == rank))
        if locked.size:
            raise MobilityError(
                f"limb '{limb.name}': its loops lock the actuated joint '{limb.joint_names[a]}' at "
                f"P = {where[int(locked[0])]} m (it cannot move with the loops closed)"
            )
        cols.append(z0[:, :, None])
    zp = np.zeros((b, nq, null.shape[2]))
    zp[:, passive] = null
    cols.append(zp)
    z = np.concatenate(cols, axis=2)
    twists = t @ z
    errors = e - t[:, :, passive] @ (pinv @ d)
    incompatible = np.swapaxes(u[:, :, rank:], 1, 2) @ d
    return LoopMotion(twists, errors, incompatible, (0,) if limb.actuated else (), ranks != rank)


def loop_motion(
    limb: Limb,
    model: pin.Model,
    data: pin.Data,
    qs: np.ndarray,
    rotations: np.ndarray,
    selection: np.ndarray,
    where: np.ndarray,
) -> LoopMotion:
    """:class:`LoopMotion` of a limb with loops at poses ``qs`` (b, nq).

    Args:
        limb: The limb (with loops).
        model: Its model (nominal, or the one the poses were solved on).
        data: A ``Data`` of ``model`` (reused).
        qs: Shape (b, nq): the limb's joint values.
        rotations: Shape (b, 3, 3): platform orientation in K (limb 0's platform frame).
        selection: The parameter set's selection for this limb, shape (n_raw, m).
        where: Shape (b, 3): the position of P at each pose, for messages [m].
    """
    e_p, j_p, c, d, _ = raw_rows_many(limb, model, data, np.asarray(qs, dtype=float).reshape(-1, limb.nq))
    return eliminate_loops(
        limb,
        to_k_prime_many(rotations, j_p),
        to_k_prime_many(rotations, e_p @ selection),
        c,
        d @ selection,
        where,
    )


def to_k_prime_many(rot: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Local-frame twists (b, 6, k) in K' (``diag(R, R)``), for rotations (b, 3, 3)."""
    out = np.empty_like(local)
    out[:, :3] = rot @ local[:, :3]
    out[:, 3:] = rot @ local[:, 3:]
    return out
