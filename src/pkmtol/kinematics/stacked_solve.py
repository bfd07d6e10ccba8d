"""Stacked linear algebra of the batched solver: Newton steps, inverses and condition numbers."""

from __future__ import annotations

import numpy as np

from pkmtol.kinematics import acceleration


def newton_steps(a: np.ndarray, res: np.ndarray, compiled: bool = False) -> np.ndarray:
    """Newton steps (b, free): stacked LU for square systems, stacked QR least squares otherwise.

    ``compiled``: square systems by the LU of :mod:`pkmtol.kinematics.jit_kernels` when the kernels
    run (LAPACK's otherwise); an exactly singular matrix gets the least-squares step either way.
    """
    kernels = acceleration.kernels() if compiled else None
    if kernels is not None and a.shape[1] == a.shape[2]:
        steps = np.empty(a.shape[:2])
        singular = np.zeros(len(a), dtype=bool)
        kernels.solve_steps(np.ascontiguousarray(a), np.ascontiguousarray(res), steps, singular)
        for k in np.flatnonzero(singular):
            steps[k] = np.linalg.lstsq(a[k], res[k], rcond=None)[0]
        return steps
    if a.shape[1] == a.shape[2]:
        try:
            return np.linalg.solve(a, res[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            return np.array([_solve_one(ak, rk) for ak, rk in zip(a, res, strict=True)])
    if a.shape[1] > a.shape[2]:
        qm, r = np.linalg.qr(a)
        rhs = np.swapaxes(qm, 1, 2) @ res[:, :, None]
        try:
            return np.linalg.solve(r, rhs)[:, :, 0]
        except np.linalg.LinAlgError:
            pass
    return np.array([np.linalg.lstsq(ak, rk, rcond=None)[0] for ak, rk in zip(a, res, strict=True)])


def _solve_one(a: np.ndarray, r: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(a, r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, r, rcond=None)[0]


def condition_bound(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``κ_F`` (b,) and the inverse (or pseudo-inverse) (b, free, rows) of stacked Jacobians."""
    rows, cols = a.shape[1:]
    if rows == cols:
        inv = _inverses(a)
        bound = _frobenius(a) * _frobenius(inv)
        return np.where(np.isfinite(bound), bound, np.inf), inv
    if rows > cols:
        g = np.swapaxes(a, 1, 2) @ a
        g_inv = _inverses(g)
        bound = np.sqrt(_frobenius(g) * _frobenius(g_inv))
        return np.where(np.isfinite(bound), bound, np.inf), g_inv @ np.swapaxes(a, 1, 2)
    return np.full(len(a), np.inf), np.full((len(a), cols, rows), np.nan)


def _inverses(a: np.ndarray) -> np.ndarray:
    """Inverses of stacked square matrices (b, n, n); NaN for an exactly singular one.

    By the compiled LU of :mod:`pkmtol.kinematics.jit_kernels` when numba is there.
    """
    kernels = acceleration.kernels()
    if kernels is not None:
        inv = np.empty(a.shape)
        singular = np.zeros(len(a), dtype=bool)
        kernels.inverses(np.ascontiguousarray(a), inv, singular)
        inv[singular] = np.nan
        return inv
    try:
        return np.linalg.inv(a)
    except np.linalg.LinAlgError:
        return np.array([_inv_or_nan(ak) for ak in a])


def _frobenius(a: np.ndarray) -> np.ndarray:
    """Frobenius norms (b,) of stacked matrices (b, r, c) (``np.linalg.norm(a, axis=(1, 2))``)."""
    return np.sqrt(np.einsum("bij,bij->b", a, a))


def _inv_or_nan(a: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(a)
    except np.linalg.LinAlgError:
        return np.full(a.shape[::-1], np.nan)


def exact_condition(a: np.ndarray) -> float:
    """The 2-norm condition number ``s_max / s_min`` of one matrix (inf if singular), by SVD."""
    s = np.linalg.svd(a, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
