"""Numba kernels of the batched solver's per-pose arithmetic (the optional extra ``pkmtol[fast]``).

In numpy, the batched solver (:mod:`pkmtol.kinematics.batch`) spends a Newton iteration in two
places: four calls into Pinocchio per limb and pose (about 1.8 µs each, more than the arithmetic
they do), and the closure residual ``log6(oMp_0⁻¹ oMp_i)`` and its Jacobian stacked over poses,
where numpy pays a fixed cost per operation and runs 3 × 3 to 6 × 6 products element by element.
The kernels here do the same arithmetic pose by pose in compiled loops:

* :func:`frames`: the limbs' forward kinematics, the platform and loop frames' placements and LOCAL
  Jacobians, from the joint tables of :mod:`pkmtol.kinematics.frame_tables` (every pkmtol joint is
  a 1-DOF revolute or prismatic joint), and :func:`perturbed_placements`, each machine's joint
  placements ``placement · exp6(ε)``; both agree with Pinocchio to round-off;
* :func:`closure_rows`: the platform closure rows and the task rows with their Jacobian, the
  formulas of :mod:`pkmtol.kinematics.se3_batch` (the same series below ``SERIES_ANGLE``, the same
  near-half-turn flag, which the caller hands to Pinocchio as before);
* :func:`solve_steps` and :func:`inverses`: the Newton steps of square systems and the inverses of
  the converged Jacobians (the condition bound and the tangent), by LU with partial pivoting, with a
  flag for each exactly singular matrix.

What a failed problem reports follows every rounding (a wandering Newton's last residual, a singular
Jacobian's condition number), so the solver solves a failed problem once more as the per-pose
solver does, with Pinocchio's kinematics and LAPACK's steps, and reports what the per-pose solver
reports (``tests/test_batch.py``).

This module needs numba; :func:`pkmtol.kinematics.acceleration.kernels` imports it when numba is
installed and not turned off (``PKMTOL_JIT=0``). The kernels are compiled on first use and cached
beside this file (numba's ``cache=True``): a process pays numba's import and the first load of
machine code (about 0.9 s CPU together), and the first run after an install compiles (about 10 s).
Without them the solver keeps its numpy path; both give the same solutions to round-off
(``tests/test_jit_kernels.py``).
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
def _add_half_skew(m: np.ndarray, v: np.ndarray) -> None:
    """``m += ½ [v]×`` for a 3 × 3 ``m`` and a 3-vector ``v``."""
    h0, h1, h2 = 0.5 * v[0], 0.5 * v[1], 0.5 * v[2]
    m[0, 1] -= h2
    m[0, 2] += h1
    m[1, 0] += h2
    m[1, 2] -= h0
    m[2, 0] -= h1
    m[2, 1] += h0


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
    _add_half_skew(j3, w)
    _add_half_skew(cm, pe)
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
def _lu_solve(lu: np.ndarray, perm: np.ndarray, x: np.ndarray) -> None:
    """Solve ``A x = b`` in place (``x`` holds ``b``) from :func:`_lu`'s factors."""
    n = lu.shape[0]
    for j in range(n):
        p = perm[j]
        if p != j:
            x[j], x[p] = x[p], x[j]
    for i in range(n):
        acc = x[i]
        for c in range(i):
            acc -= lu[i, c] * x[c]
        x[i] = acc
    for i in range(n - 1, -1, -1):
        acc = x[i]
        for c in range(i + 1, n):
            acc -= lu[i, c] * x[c]
        x[i] = acc / lu[i, i]


@_jit
def solve_steps(a: np.ndarray, rhs: np.ndarray, steps: np.ndarray, singular: np.ndarray) -> None:
    """Solve ``a[k] x = rhs[k]`` for square ``a`` (b, n, n) by :func:`_lu`.

    ``singular[k]`` is set where a pivot is exactly zero (``steps[k]`` is then undefined), where
    ``numpy.linalg.solve`` raises ``LinAlgError``.
    """
    n = a.shape[1]
    lu = np.empty((n, n))
    perm = np.empty(n, dtype=np.int64)
    x = np.empty(n)
    for k in range(a.shape[0]):
        lu[:, :] = a[k]
        singular[k] = not _lu(lu, perm)
        if singular[k]:
            continue
        x[:] = rhs[k]
        _lu_solve(lu, perm, x)
        steps[k, :] = x


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


@_jit
def perturbed_placements(nominal: np.ndarray, eps: np.ndarray, out: np.ndarray) -> None:
    """Joint placements ``nominal[j] · exp6(eps[s, j])`` of many machines, as homogeneous matrices.

    Args:
        nominal: Shape (n, 4, 4): each joint's placement in its parent.
        eps: Shape (c, n, 6): each machine's placement errors ``[v; ω]`` in the joint frame.
        out: Shape (c, n, 4, 4): written.

    ``exp6`` is Rodrigues' formula, ``R = I + a[ω]× + b[ω]×²`` and ``p = (I + b[ω]× + c[ω]×²) v``
    with ``a = sin θ/θ``, ``b = (1 − cos θ)/θ²``, ``c = (θ − sin θ)/θ³``, by their series below
    θ = 1e-4 (Pinocchio's ``exp6`` to round-off, ``tests/test_jit_kernels.py``).
    """
    e = np.empty((4, 4))
    k1 = np.empty((3, 3))
    k2 = np.empty((3, 3))
    for s in range(eps.shape[0]):
        for j in range(eps.shape[1]):
            v0, v1, v2 = eps[s, j, 0], eps[s, j, 1], eps[s, j, 2]
            w0, w1, w2 = eps[s, j, 3], eps[s, j, 4], eps[s, j, 5]
            t2 = w0 * w0 + w1 * w1 + w2 * w2
            if t2 < 1e-8:
                a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0)
                b = 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0)
                c = 1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0)
            else:
                t = np.sqrt(t2)
                st, ct = np.sin(t), np.cos(t)
                a, b, c = st / t, (1.0 - ct) / t2, (t - st) / (t2 * t)
            k1[0, 0], k1[0, 1], k1[0, 2] = 0.0, -w2, w1
            k1[1, 0], k1[1, 1], k1[1, 2] = w2, 0.0, -w0
            k1[2, 0], k1[2, 1], k1[2, 2] = -w1, w0, 0.0
            for r in range(3):
                for col in range(3):
                    k2[r, col] = k1[r, 0] * k1[0, col] + k1[r, 1] * k1[1, col] + k1[r, 2] * k1[2, col]
            for r in range(3):
                for col in range(3):
                    e[r, col] = a * k1[r, col] + b * k2[r, col] + (1.0 if r == col else 0.0)
                vr = (
                    v0 * (b * k1[r, 0] + c * k2[r, 0])
                    + v1 * (b * k1[r, 1] + c * k2[r, 1])
                    + v2 * (b * k1[r, 2] + c * k2[r, 2])
                )
                e[r, 3] = eps[s, j, r] + vr
            for r in range(3):
                for col in range(4):
                    acc = nominal[j, r, 3] if col == 3 else 0.0
                    for m in range(3):
                        acc += nominal[j, r, m] * e[m, col]
                    out[s, j, r, col] = acc
                out[s, j, 3, r] = 0.0
            out[s, j, 3, 3] = 1.0


@_jit
def frames(
    q: np.ndarray,
    rows: np.ndarray,
    table: np.ndarray,
    which: np.ndarray,
    parent: np.ndarray,
    revolute: np.ndarray,
    axis: np.ndarray,
    f_joint: np.ndarray,
    f_place: np.ndarray,
    f_start: np.ndarray,
    f_support: np.ndarray,
    h: np.ndarray,
    jac: np.ndarray,
) -> None:
    """Placements and LOCAL Jacobians of frames of 1-DOF joint trees, pose by pose.

    Pinocchio's ``forwardKinematics``, ``updateFramePlacement`` and ``getFrameJacobian(…, LOCAL)``
    for revolute and prismatic joints (:mod:`pkmtol.kinematics.frame_tables` has the layout):
    joint ``j``'s placement in its parent is ``table[which[k], j] · exp(S_j q_j)`` (Rodrigues for a
    revolute joint of unit axis ``a``, ``a q`` for a prismatic one), ``oMi = oM_parent · liMi``,
    ``oMf = oMi[f_joint] · f_place``, and the column of a supporting joint ``j`` is
    ``[R_fᵀ ((t_j − t_f) × u_j) ; R_fᵀ u_j]`` (revolute) or ``[R_fᵀ u_j ; 0]`` (prismatic),
    ``u_j = R_j a_j``.

    Args:
        q: Shape (B, n): joint values of every problem [rad or m].
        rows: Shape (b,): the problems to evaluate.
        table: Shape (M, n, 4, 4): joint placements, one set per machine.
        which: Shape (B,): each problem's machine (row of ``table``).
        parent: Shape (n,): each joint's parent joint (−1: the root); parents come first.
        revolute: Shape (n,): revolute (True) or prismatic joint.
        axis: Shape (n, 3): unit joint axes in the joint frames.
        f_joint: Shape (F,): each frame's parent joint (−1: the root K; the frame is then fixed).
        f_place: Shape (F, 4, 4): each frame's placement in its parent joint.
        f_start: Shape (F,): the first joint of each frame's limb (its Jacobian's column 0).
        f_support: Shape (F, w): which of its limb's joints move each frame.
        h: Shape (F, b, 4, 4): written with the frames' placements in K.
        jac: Shape (F, b, 6, w): written in the supported columns (the caller zeroes the rest).
    """
    n = parent.shape[0]
    rot = np.zeros((n + 1, 3, 3))  # oMi of every joint, then the root's identity
    pos = np.zeros((n + 1, 3))
    for r in range(3):
        rot[n, r, r] = 1.0
    lr = np.empty((3, 3))
    lt = np.empty(3)
    rq = np.empty((3, 3))
    rf = np.empty((3, 3))
    tf = np.empty(3)
    for kk in range(rows.shape[0]):
        k = rows[kk]
        place = table[which[k]]
        for j in range(n):
            x = q[k, j]
            a0, a1, a2 = axis[j, 0], axis[j, 1], axis[j, 2]
            if revolute[j]:
                c, s = np.cos(x), np.sin(x)
                d = 1.0 - c
                rq[0, 0], rq[0, 1], rq[0, 2] = c + d * a0 * a0, d * a0 * a1 - s * a2, d * a0 * a2 + s * a1
                rq[1, 0], rq[1, 1], rq[1, 2] = d * a1 * a0 + s * a2, c + d * a1 * a1, d * a1 * a2 - s * a0
                rq[2, 0], rq[2, 1], rq[2, 2] = d * a2 * a0 - s * a1, d * a2 * a1 + s * a0, c + d * a2 * a2
                for r in range(3):
                    for col in range(3):
                        lr[r, col] = (
                            place[j, r, 0] * rq[0, col]
                            + place[j, r, 1] * rq[1, col]
                            + place[j, r, 2] * rq[2, col]
                        )
                    lt[r] = place[j, r, 3]
            else:
                for r in range(3):
                    for col in range(3):
                        lr[r, col] = place[j, r, col]
                    lt[r] = (
                        place[j, r, 3] + (place[j, r, 0] * a0 + place[j, r, 1] * a1 + place[j, r, 2] * a2) * x
                    )
            p = parent[j]
            if p < 0:
                rot[j] = lr
                pos[j] = lt
            else:
                for r in range(3):
                    for col in range(3):
                        rot[j, r, col] = (
                            rot[p, r, 0] * lr[0, col] + rot[p, r, 1] * lr[1, col] + rot[p, r, 2] * lr[2, col]
                        )
                    pos[j, r] = rot[p, r, 0] * lt[0] + rot[p, r, 1] * lt[1] + rot[p, r, 2] * lt[2] + pos[p, r]
        for f in range(f_joint.shape[0]):
            pj = f_joint[f] if f_joint[f] >= 0 else n  # a frame on the root K: the identity at n
            for r in range(3):
                for col in range(3):
                    rf[r, col] = (
                        rot[pj, r, 0] * f_place[f, 0, col]
                        + rot[pj, r, 1] * f_place[f, 1, col]
                        + rot[pj, r, 2] * f_place[f, 2, col]
                    )
                    h[f, kk, r, col] = rf[r, col]
                tf[r] = (
                    rot[pj, r, 0] * f_place[f, 0, 3]
                    + rot[pj, r, 1] * f_place[f, 1, 3]
                    + rot[pj, r, 2] * f_place[f, 2, 3]
                    + pos[pj, r]
                )
                h[f, kk, r, 3] = tf[r]
                h[f, kk, 3, r] = 0.0
            h[f, kk, 3, 3] = 1.0
            for col in range(f_support.shape[1]):
                if not f_support[f, col]:
                    continue
                j = f_start[f] + col
                u0 = rot[j, 0, 0] * axis[j, 0] + rot[j, 0, 1] * axis[j, 1] + rot[j, 0, 2] * axis[j, 2]
                u1 = rot[j, 1, 0] * axis[j, 0] + rot[j, 1, 1] * axis[j, 1] + rot[j, 1, 2] * axis[j, 2]
                u2 = rot[j, 2, 0] * axis[j, 0] + rot[j, 2, 1] * axis[j, 1] + rot[j, 2, 2] * axis[j, 2]
                if revolute[j]:
                    d0, d1, d2 = pos[j, 0] - tf[0], pos[j, 1] - tf[1], pos[j, 2] - tf[2]
                    v0, v1, v2 = d1 * u2 - d2 * u1, d2 * u0 - d0 * u2, d0 * u1 - d1 * u0
                    for r in range(3):
                        jac[f, kk, r, col] = rf[0, r] * v0 + rf[1, r] * v1 + rf[2, r] * v2
                        jac[f, kk, 3 + r, col] = rf[0, r] * u0 + rf[1, r] * u1 + rf[2, r] * u2
                else:
                    for r in range(3):
                        jac[f, kk, r, col] = rf[0, r] * u0 + rf[1, r] * u1 + rf[2, r] * u2
                        jac[f, kk, 3 + r, col] = 0.0


#: ``log6`` and ``Jlog6`` of one placement, for the tree kernels (:mod:`pkmtol.kinematics.tree_kernels`).
log6_one = _log6
