"""Numba kernels of a tree's forward kinematics and loop rows (the ``fast`` extra).

The same arithmetic as :func:`pkmtol.kinematics.tree_frames.forward` (joint placements, pre-motion
frames, spatial joint columns), pose by pose in compiled loops instead of numpy operations on
stacks of 4 × 4 matrices, whose fixed cost per call dominates at these sizes. Loaded, like
:mod:`pkmtol.kinematics.jit_kernels`, only when :func:`pkmtol.kinematics.acceleration.kernels` runs
(numba installed, ``PKMTOL_JIT`` not off); both paths agree to round-off (``tests/test_loop_tree.py``).
"""

from __future__ import annotations

import numba
import numpy as np

from pkmtol.kinematics.jit_kernels import log6_one

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def tree_forward(
    q: np.ndarray,
    parent: np.ndarray,
    revolute: np.ndarray,
    axis: np.ndarray,
    placement: np.ndarray,
    joint: np.ndarray,
    pre: np.ndarray,
    cols: np.ndarray,
) -> None:
    """Fill ``joint`` and ``pre`` (b, n, 4, 4) and ``cols`` (b, 6, n) for configurations ``q`` (b, n).

    ``pre_j = oMi_parent · placement_j``, ``oMi_j = pre_j · exp(S_j q_j)`` (Rodrigues for a revolute
    joint of unit axis ``a``, ``a q`` for a prismatic one), ``cols[:, j] = [t_j × u_j; u_j]``
    (revolute) or ``[u_j; 0]`` (prismatic) with ``u_j = R_j a``.
    """
    b, n = q.shape
    rq = np.empty((3, 3))
    for k in range(b):
        for j in range(n):
            p = parent[j]
            for r in range(4):
                for c in range(4):
                    if p < 0:
                        pre[k, j, r, c] = placement[j, r, c]
                    else:
                        pre[k, j, r, c] = (
                            joint[k, p, r, 0] * placement[j, 0, c]
                            + joint[k, p, r, 1] * placement[j, 1, c]
                            + joint[k, p, r, 2] * placement[j, 2, c]
                            + joint[k, p, r, 3] * placement[j, 3, c]
                        )
            a0, a1, a2 = axis[j, 0], axis[j, 1], axis[j, 2]
            x = q[k, j]
            if revolute[j]:
                cs, s = np.cos(x), np.sin(x)
                d = 1.0 - cs
                rq[0, 0], rq[0, 1], rq[0, 2] = cs + d * a0 * a0, d * a0 * a1 - s * a2, d * a0 * a2 + s * a1
                rq[1, 0], rq[1, 1], rq[1, 2] = d * a1 * a0 + s * a2, cs + d * a1 * a1, d * a1 * a2 - s * a0
                rq[2, 0], rq[2, 1], rq[2, 2] = d * a2 * a0 - s * a1, d * a2 * a1 + s * a0, cs + d * a2 * a2
                for r in range(3):
                    for c in range(3):
                        joint[k, j, r, c] = (
                            pre[k, j, r, 0] * rq[0, c]
                            + pre[k, j, r, 1] * rq[1, c]
                            + pre[k, j, r, 2] * rq[2, c]
                        )
                    joint[k, j, r, 3] = pre[k, j, r, 3]
            else:
                for r in range(3):
                    for c in range(3):
                        joint[k, j, r, c] = pre[k, j, r, c]
                    joint[k, j, r, 3] = (
                        pre[k, j, r, 3]
                        + (pre[k, j, r, 0] * a0 + pre[k, j, r, 1] * a1 + pre[k, j, r, 2] * a2) * x
                    )
            joint[k, j, 3, 0] = 0.0
            joint[k, j, 3, 1] = 0.0
            joint[k, j, 3, 2] = 0.0
            joint[k, j, 3, 3] = 1.0
            u0 = joint[k, j, 0, 0] * a0 + joint[k, j, 0, 1] * a1 + joint[k, j, 0, 2] * a2
            u1 = joint[k, j, 1, 0] * a0 + joint[k, j, 1, 1] * a1 + joint[k, j, 1, 2] * a2
            u2 = joint[k, j, 2, 0] * a0 + joint[k, j, 2, 1] * a1 + joint[k, j, 2, 2] * a2
            if revolute[j]:
                t0, t1, t2 = joint[k, j, 0, 3], joint[k, j, 1, 3], joint[k, j, 2, 3]
                cols[k, 0, j] = t1 * u2 - t2 * u1
                cols[k, 1, j] = t2 * u0 - t0 * u2
                cols[k, 2, j] = t0 * u1 - t1 * u0
                cols[k, 3, j], cols[k, 4, j], cols[k, 5, j] = u0, u1, u2
            else:
                cols[k, 0, j], cols[k, 1, j], cols[k, 2, j] = u0, u1, u2
                cols[k, 3, j], cols[k, 4, j], cols[k, 5, j] = 0.0, 0.0, 0.0


@_jit
def _frame(joint: np.ndarray, k: int, fj: int, place: np.ndarray, out: np.ndarray) -> None:
    """``out`` = placement (4, 4) of a frame on joint ``fj`` (−1: the base) at pose ``k``."""
    for r in range(4):
        for c in range(4):
            if fj < 0:
                out[r, c] = place[r, c]
            else:
                out[r, c] = (
                    joint[k, fj, r, 0] * place[0, c]
                    + joint[k, fj, r, 1] * place[1, c]
                    + joint[k, fj, r, 2] * place[2, c]
                    + joint[k, fj, r, 3] * place[3, c]
                )


@_jit
def tree_system(
    joint: np.ndarray,
    cols: np.ndarray,
    six: np.ndarray,
    fa_joint: np.ndarray,
    fa_place: np.ndarray,
    fb_joint: np.ndarray,
    fb_place: np.ndarray,
    ma: np.ndarray,
    mb: np.ndarray,
    row0: np.ndarray,
    t_joint: int,
    t_place: np.ndarray,
    t_mask: np.ndarray,
    point: np.ndarray,
    targets: np.ndarray,
    res: np.ndarray,
    jac: np.ndarray,
    near: np.ndarray,
) -> None:
    """Loop rows (and task rows when ``targets`` has rows) of a :class:`TreeBatch`.

    The formulas of :func:`pkmtol.kinematics.tree_chain.loop_rows_world` pose by pose: a ``6d``
    loop ``log6(oMa⁻¹ oMb)`` and ``Jlog6 Ad(oMb⁻¹) (T_b − T_a)``, a ``3d`` loop ``p_b − p_a`` and
    ``[I −[p_b×]] T_b − [I −[p_a×]] T_a``, the task ``oMt·P − target`` and ``[I −[p×]] T_t``;
    ``near[k]`` flags a ``6d`` loop near a half turn (the caller redoes that pose with Pinocchio).
    ``jac`` must be zero on entry.
    """
    b, _, n = cols.shape
    ha = np.empty((4, 4))
    hb = np.empty((4, 4))
    re = np.empty((3, 3))
    pe = np.empty(3)
    nu = np.empty(6)
    jl = np.empty((6, 6))
    m = np.empty((6, 6))
    for k in range(b):
        for lp in range(six.shape[0]):
            _frame(joint, k, fa_joint[lp], fa_place[lp], ha)
            _frame(joint, k, fb_joint[lp], fb_place[lp], hb)
            r0 = row0[lp]
            if six[lp]:
                for i in range(3):
                    pe[i] = 0.0
                    for c in range(3):
                        acc = 0.0
                        for t in range(3):
                            acc += ha[t, i] * hb[t, c]
                        re[i, c] = acc
                        pe[i] += ha[c, i] * (hb[c, 3] - ha[c, 3])
                if log6_one(re, pe, nu, jl):
                    near[k] = True
                for i in range(6):
                    res[k, r0 + i] = nu[i]
                # m = Jlog6 · Ad(oMb⁻¹), Ad(M⁻¹) = [Rᵀ  −Rᵀ[p×]; 0  Rᵀ]
                px, py, pz = hb[0, 3], hb[1, 3], hb[2, 3]
                for i in range(6):
                    for c in range(3):
                        a_top = jl[i, 0] * hb[c, 0] + jl[i, 1] * hb[c, 1] + jl[i, 2] * hb[c, 2]
                        m[i, c] = a_top
                    # −Rᵀ[p×] block: column c of [p×] is p × e_c
                    for c in range(3):
                        s0 = py * (1.0 if c == 2 else 0.0) - pz * (1.0 if c == 1 else 0.0)
                        s1 = pz * (1.0 if c == 0 else 0.0) - px * (1.0 if c == 2 else 0.0)
                        s2 = px * (1.0 if c == 1 else 0.0) - py * (1.0 if c == 0 else 0.0)
                        acc = 0.0
                        for t in range(3):
                            rt_s = hb[0, t] * s0 + hb[1, t] * s1 + hb[2, t] * s2
                            acc += -jl[i, t] * rt_s + jl[i, 3 + t] * hb[c, t]
                        m[i, 3 + c] = acc
                for j in range(n):
                    d = (1.0 if mb[lp, j] else 0.0) - (1.0 if ma[lp, j] else 0.0)
                    if d == 0.0:
                        continue
                    for i in range(6):
                        acc = 0.0
                        for t in range(6):
                            acc += m[i, t] * cols[k, t, j]
                        jac[k, r0 + i, j] = d * acc
            else:
                for i in range(3):
                    res[k, r0 + i] = hb[i, 3] - ha[i, 3]
                for j in range(n):
                    if not (ma[lp, j] or mb[lp, j]):
                        continue
                    w0, w1, w2 = cols[k, 3, j], cols[k, 4, j], cols[k, 5, j]
                    for side in range(2):
                        h = hb if side == 0 else ha
                        on = mb[lp, j] if side == 0 else ma[lp, j]
                        if not on:
                            continue
                        sg = 1.0 if side == 0 else -1.0
                        p0, p1, p2 = h[0, 3], h[1, 3], h[2, 3]
                        jac[k, r0, j] += sg * (cols[k, 0, j] - (p1 * w2 - p2 * w1))
                        jac[k, r0 + 1, j] += sg * (cols[k, 1, j] - (p2 * w0 - p0 * w2))
                        jac[k, r0 + 2, j] += sg * (cols[k, 2, j] - (p0 * w1 - p1 * w0))
        if targets.shape[0]:
            _frame(joint, k, t_joint, t_place, ha)
            r0 = row0[six.shape[0]]
            for i in range(3):
                hb[i, 3] = ha[i, 0] * point[0] + ha[i, 1] * point[1] + ha[i, 2] * point[2] + ha[i, 3]
                res[k, r0 + i] = hb[i, 3] - targets[k, i]
            p0, p1, p2 = hb[0, 3], hb[1, 3], hb[2, 3]
            for j in range(n):
                if not t_mask[j]:
                    continue
                w0, w1, w2 = cols[k, 3, j], cols[k, 4, j], cols[k, 5, j]
                jac[k, r0, j] = cols[k, 0, j] - (p1 * w2 - p2 * w1)
                jac[k, r0 + 1, j] = cols[k, 1, j] - (p2 * w0 - p0 * w2)
                jac[k, r0 + 2, j] = cols[k, 2, j] - (p0 * w1 - p1 * w0)
