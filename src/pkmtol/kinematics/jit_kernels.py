"""Numba kernels of the batched solver's per-pose arithmetic (the optional extra ``pkmtol[fast]``).

The batched solver (:mod:`pkmtol.kinematics.batch`) spends most of a Newton iteration outside
Pinocchio: the closure residual ``log6(oMp_0⁻¹ oMp_i)``, its Jacobian and the Newton step, stacked
over poses in numpy. numpy pays a fixed cost per operation and runs 3 × 3 to 21 × 21 products
element by element, so those ~60 operations per iteration cost 3–4 times Pinocchio's own calls. The
kernels here do the same arithmetic pose by pose in compiled loops:

* :func:`closure_rows`: the platform closure rows and the task rows with their Jacobian, the
  formulas of :mod:`pkmtol.kinematics.se3_batch` (the same series below ``SERIES_ANGLE``, the same
  near-half-turn flag, which the caller hands to Pinocchio as before);
* :func:`inverses`: the inverses of the converged Jacobians (the condition bound and the tangent)
  by LU with partial pivoting, with a flag for each exactly singular matrix.

The Newton steps stay with LAPACK (``numpy.linalg.solve``), as in the per-pose solver: a target
out of reach makes Newton wander, and the residual it reports after the last iteration follows
every rounding of the steps. With the same LAPACK steps, the batch reports the same residual as
``ClosedChain`` (``tests/test_batch.py``); a compiled LU changed it in the second digit.

This module needs numba; :func:`pkmtol.kinematics.acceleration.kernels` imports it when numba is
installed and not turned off (``PKMTOL_JIT=0``). The kernels are compiled on first use and cached
beside this file (numba's ``cache=True``): a process pays numba's import (about 0.3 s) and loads the
machine code, and only the first run after an install compiles. Without them the solver keeps its
numpy path; both give the same solutions to round-off (``tests/test_jit_kernels.py``).
"""

from __future__ import annotations

import numba
import numpy as np

from pkmtol.kinematics.se3_batch import NEAR_PI, SERIES_ANGLE

#: Compiled once, cached beside this file (or in numba's user cache when that is read-only).
_jit = numba.njit(cache=True, nogil=True, error_model="numpy")

# |B_2n| / (2n)!, n = 1 … 7 (as in se3_batch)
_C = (
    1 / 12,
    1 / 720,
    1 / 30240,
    1 / 1209600,
    1 / 47900160,
    691 / 2730 / 479001600,
    7 / 6 / 87178291200,
)


@_jit
def _coefficients(theta: float) -> tuple[float, float, float]:
    """``α(θ)``, ``β(θ)`` and ``β'(θ)/θ`` of one angle (se3_batch._coefficients)."""
    x = theta * theta
    if theta >= SERIES_ANGLE:
        half_cot = 0.5 / np.tan(0.5 * theta)
        a = theta * half_cot
        da = half_cot - 0.25 * theta / np.sin(0.5 * theta) ** 2
        return a, (1.0 - a) / x, (-da * theta - 2.0 * (1.0 - a)) / (x * x)
    beta = _C[6]
    dbeta = 12.0 * _C[6]
    for n in range(5, -1, -1):
        beta = beta * x + _C[n]
        if n:
            dbeta = dbeta * x + 2.0 * n * _C[n]
    return 1.0 - x * beta, beta, dbeta


@_jit
def _log6(re: np.ndarray, pe: np.ndarray, nu: np.ndarray, jl: np.ndarray) -> bool:
    """``log6`` and ``Jlog6`` of one placement into ``nu`` (6,) and ``jl`` (6, 6); True near π."""
    a0 = 0.5 * (re[2, 1] - re[1, 2])
    a1 = 0.5 * (re[0, 2] - re[2, 0])
    a2 = 0.5 * (re[1, 0] - re[0, 1])
    s = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    c = 0.5 * (re[0, 0] + re[1, 1] + re[2, 2] - 1.0)
    theta = np.arctan2(s, c)
    if s > 1e-4:
        ratio = theta / s
    else:
        s2 = s * s
        ratio = 1.0 + s2 / 6.0 + 3.0 * s2 * s2 / 40.0
    w = np.empty(3)
    w[0], w[1], w[2] = a0 * ratio, a1 * ratio, a2 * ratio
    alpha, beta, dbeta = _coefficients(theta)
    wp = w[0] * pe[0] + w[1] * pe[1] + w[2] * pe[2]
    cross = np.empty(3)
    cross[0] = w[1] * pe[2] - w[2] * pe[1]
    cross[1] = w[2] * pe[0] - w[0] * pe[2]
    cross[2] = w[0] * pe[1] - w[1] * pe[0]
    for i in range(3):
        nu[i] = alpha * pe[i] - 0.5 * cross[i] + beta * wp * w[i]
        nu[3 + i] = w[i]
    # Jlog3 = β ω ωᵀ + α I + ½ [ω]×;  C = v3 ωᵀ + β ω pᵀ + β (ω·p) I + ½ [p]×
    j3 = np.empty((3, 3))
    cm = np.empty((3, 3))
    k1 = dbeta * wp
    k2 = theta * theta * dbeta + 2.0 * beta
    for i in range(3):
        v3 = k1 * w[i] - k2 * pe[i]
        for j in range(3):
            j3[i, j] = beta * w[i] * w[j]
            cm[i, j] = v3 * w[j] + beta * w[i] * pe[j]
    hw0, hw1, hw2 = 0.5 * w[0], 0.5 * w[1], 0.5 * w[2]
    j3[0, 1] -= hw2
    j3[0, 2] += hw1
    j3[1, 0] += hw2
    j3[1, 2] -= hw0
    j3[2, 0] -= hw1
    j3[2, 1] += hw0
    hp0, hp1, hp2 = 0.5 * pe[0], 0.5 * pe[1], 0.5 * pe[2]
    cm[0, 1] -= hp2
    cm[0, 2] += hp1
    cm[1, 0] += hp2
    cm[1, 2] -= hp0
    cm[2, 0] -= hp1
    cm[2, 1] += hp0
    for i in range(3):
        j3[i, i] += alpha
        cm[i, i] += wp * beta
    jl[:, :] = 0.0
    for i in range(3):
        for j in range(3):
            jl[i, j] = j3[i, j]
            jl[3 + i, 3 + j] = j3[i, j]
            acc = 0.0
            for k in range(3):
                acc += cm[i, k] * j3[k, j]
            jl[i, 3 + j] = acc
    return theta > np.pi - NEAR_PI


@_jit
def closure_rows(
    h: np.ndarray,
    jacobians: np.ndarray,
    offsets: np.ndarray,
    p_ref: np.ndarray,
    targets: np.ndarray,
    task_row: int,
    res: np.ndarray,
    jac: np.ndarray,
    near: np.ndarray,
) -> None:
    """Platform closure rows (and task rows) of every pose, into ``res``, ``jac`` and ``near``.

    The rows of :meth:`BatchChain._system <pkmtol.kinematics.batch.BatchChain._system>` before
    the internal loops: per limb pair ``r_i = log6(e_i)``, ``e_i = oMp_0⁻¹ oMp_i``, with
    ``∂r_i/∂q_i = Jlog6(e_i) J_i`` and ``∂r_i/∂q_0 = −Jlog6(e_i) Ad(e_i⁻¹) J_0``; then, when
    ``targets`` has rows, the task ``oMp_0 · P − target`` with ``R_0 (J_0,v − [P]× J_0,ω)``.

    Args:
        h: Shape (L, b, 4, 4): each limb's platform placement in K.
        jacobians: Shape (L, b, 6, w): their LOCAL Jacobians, zero-padded to the widest limb.
        offsets: Shape (L + 1,): where each limb's joints start in a row of ``jac``.
        p_ref: Shape (3,): P in the platform frame [m].
        targets: Shape (b, 3) for inverse problems, (0, 3) for forward ones [m].
        task_row: The first task row (after the closure rows of the internal loops).
        res: Shape (b, rows): written in the platform closure rows and the task rows.
        jac: Shape (b, rows, N): written in the same rows; other entries are left as they are.
        near: Shape (b,): set where a relative rotation is near a half turn (Pinocchio's case).
    """
    n_limbs, b = h.shape[0], h.shape[1]
    n0 = offsets[1] - offsets[0]
    nu = np.empty(6)
    jl = np.empty((6, 6))
    re = np.empty((3, 3))
    pe = np.empty(3)
    ad = np.empty((6, n0))
    task = targets.shape[0] > 0
    for k in range(b):
        near[k] = False
        j0 = jacobians[0, k]
        for i in range(1, n_limbs):
            for r in range(3):
                pe[r] = 0.0
                for c in range(3):
                    acc = 0.0
                    for m in range(3):
                        acc += h[0, k, m, r] * h[i, k, m, c]
                    re[r, c] = acc
                    pe[r] += h[0, k, c, r] * (h[i, k, c, 3] - h[0, k, c, 3])
            if _log6(re, pe, nu, jl):
                near[k] = True
            row = 6 * (i - 1)
            for r in range(6):
                res[k, row + r] = nu[r]
            # Ad(e⁻¹) J_0 = [Reᵀ (v − pe × ω) ; Reᵀ ω], column by column
            for col in range(n0):
                v0 = j0[0, col] - (pe[1] * j0[5, col] - pe[2] * j0[4, col])
                v1 = j0[1, col] - (pe[2] * j0[3, col] - pe[0] * j0[5, col])
                v2 = j0[2, col] - (pe[0] * j0[4, col] - pe[1] * j0[3, col])
                for r in range(3):
                    ad[r, col] = re[0, r] * v0 + re[1, r] * v1 + re[2, r] * v2
                    ad[3 + r, col] = re[0, r] * j0[3, col] + re[1, r] * j0[4, col] + re[2, r] * j0[5, col]
            start, width = offsets[i], offsets[i + 1] - offsets[i]
            for r in range(6):
                for col in range(n0):
                    acc = 0.0
                    for m in range(6):
                        acc += jl[r, m] * ad[m, col]
                    jac[k, row + r, offsets[0] + col] = -acc
                for col in range(width):
                    acc = 0.0
                    for m in range(6):
                        acc += jl[r, m] * jacobians[i, k, m, col]
                    jac[k, row + r, start + col] = acc
        if task:
            row = task_row
            for r in range(3):
                acc = h[0, k, r, 3] - targets[k, r]
                for m in range(3):
                    acc += h[0, k, r, m] * p_ref[m]
                res[k, row + r] = acc
            r0 = h[0, k]
            for col in range(n0):
                # J_0,v − [P]× J_0,ω, then R_0 ·
                u0 = j0[0, col] - (p_ref[1] * j0[5, col] - p_ref[2] * j0[4, col])
                u1 = j0[1, col] - (p_ref[2] * j0[3, col] - p_ref[0] * j0[5, col])
                u2 = j0[2, col] - (p_ref[0] * j0[4, col] - p_ref[1] * j0[3, col])
                for r in range(3):
                    jac[k, row + r, offsets[0] + col] = r0[r, 0] * u0 + r0[r, 1] * u1 + r0[r, 2] * u2


@_jit
def _lu(lu: np.ndarray, perm: np.ndarray) -> bool:
    """LU with partial pivoting of ``lu`` (n, n) in place, row swaps in ``perm``; False if singular.

    LAPACK's ``getrf`` algorithm (right-looking, the largest pivot of each column).
    """
    n = lu.shape[0]
    for j in range(n):
        p = j
        big = abs(lu[j, j])
        for i in range(j + 1, n):
            v = abs(lu[i, j])
            if v > big:
                big, p = v, i
        perm[j] = p
        if big == 0.0:
            return False
        if p != j:
            for c in range(n):
                lu[j, c], lu[p, c] = lu[p, c], lu[j, c]
        inv = 1.0 / lu[j, j]
        for i in range(j + 1, n):
            f = lu[i, j] * inv
            lu[i, j] = f
            if f != 0.0:
                for c in range(j + 1, n):
                    lu[i, c] -= f * lu[j, c]
    return True


@_jit
def inverses(a: np.ndarray, out: np.ndarray, singular: np.ndarray) -> None:
    """Inverses of square matrices ``a`` (b, n, n) into ``out``, by :func:`_lu` (``numpy.linalg.inv``).

    The substitutions run on whole rows of the inverse (``P`` applied to the identity, then
    ``L⁻¹``, then ``U⁻¹``). ``singular[k]`` is set where a pivot is exactly zero (``out[k]`` is
    then undefined).
    """
    n = a.shape[1]
    lu = np.empty((n, n))
    perm = np.empty(n, dtype=np.int64)
    for k in range(a.shape[0]):
        lu[:, :] = a[k]
        singular[k] = not _lu(lu, perm)
        if singular[k]:
            continue
        x = out[k]
        x[:, :] = 0.0
        for i in range(n):
            x[i, i] = 1.0
        for j in range(n):
            p = perm[j]
            if p != j:
                for c in range(n):
                    x[j, c], x[p, c] = x[p, c], x[j, c]
        for i in range(n):
            for m in range(i):
                f = lu[i, m]
                if f != 0.0:
                    for c in range(n):
                        x[i, c] -= f * x[m, c]
        for i in range(n - 1, -1, -1):
            for m in range(i + 1, n):
                f = lu[i, m]
                if f != 0.0:
                    for c in range(n):
                        x[i, c] -= f * x[m, c]
            d = 1.0 / lu[i, i]
            for c in range(n):
                x[i, c] *= d
