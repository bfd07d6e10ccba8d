"""SE(3) maths on stacks of placements in numpy: log6 and its Jacobian, adjoint actions, cross products.

The batched solvers evaluate the closure residual ``log6(oMp_0⁻¹ oMp_i)`` and its Jacobian for many
poses at once. These functions do what ``pin.log6``/``pin.Jlog6``/``SE3.toActionMatrixInverse`` do
for one placement, on arrays of shape (B, 3, 3) and (B, 3); they agree with Pinocchio to round-off
(``tests/test_batch.py``). Conventions are Pinocchio's: twists ``[v; ω]``, ``log6`` of ``(R, p)``
is ``[α p − ½ ω×p + β (ω·p) ω ; ω]`` with ``ω = log3(R)``, ``α = (θ/2) cot(θ/2)`` and
``β = (1 − α)/θ²``.

Near ``θ = 0`` the coefficients come from their series (Bernoulli numbers), so they have no
cancellation; rotations within :data:`NEAR_PI` of a half turn, where ``log3`` needs another formula,
are flagged for the caller to hand to Pinocchio.
"""

from __future__ import annotations

import numpy as np

#: Angles above ``π − NEAR_PI`` [rad] are flagged: ``log3``'s axis is then read from the diagonal.
NEAR_PI = 1e-3
#: Below this angle [rad] the coefficients are evaluated by their series.
SERIES_ANGLE = 0.5

# |B_2n| / (2n)!, n = 1 … 7: (x/2) cot(x/2) = 1 − Σ c_n x^{2n}
_C = np.array(
    [1 / 12, 1 / 720, 1 / 30240, 1 / 1209600, 1 / 47900160, 691 / 2730 / 479001600, 7 / 6 / 87178291200]
)


_DIAG = np.arange(3)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for ``a`` (B, 3) and ``b`` (B, 3) or (B, 3, k) (column-wise), shape of ``b``."""
    if b.ndim == 2:
        a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
        b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    else:
        a0, a1, a2 = a[:, 0, None], a[:, 1, None], a[:, 2, None]
        b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def skew(v: np.ndarray) -> np.ndarray:
    """``[v]×`` (B, 3, 3) for ``v`` (B, 3)."""
    z = np.zeros(len(v))
    x, y, w = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([z, -w, y, w, z, -x, -y, x, z], axis=1).reshape(-1, 3, 3)


def _coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``α(θ)``, ``β(θ)`` and ``β'(θ)/θ`` (each (B,)), by series below :data:`SERIES_ANGLE`."""
    x = theta * theta
    # Horner: β = Σ c_n x^{n-1}, α = 1 − x β, β'/θ = Σ 2(n−1) c_n x^{n−2}
    beta = np.full_like(x, _C[6])
    dbeta = np.full_like(x, 12.0 * _C[6])
    for n in range(5, -1, -1):
        beta = beta * x + _C[n]
        if n:
            dbeta = dbeta * x + 2.0 * n * _C[n]
    alpha = 1.0 - x * beta
    big = theta >= SERIES_ANGLE
    if big.any():
        th = theta[big]
        half_cot = 0.5 / np.tan(0.5 * th)  # ½ cot(θ/2)
        a = th * half_cot
        da = half_cot - 0.25 * th / np.sin(0.5 * th) ** 2  # α'(θ)
        alpha[big] = a
        beta[big] = (1.0 - a) / (th * th)
        dbeta[big] = (-da * th - 2.0 * (1.0 - a)) / th**4  # β'(θ)/θ
    return alpha, beta, dbeta


def log3(rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rotation vectors ``ω`` (B, 3) of ``R`` (B, 3, 3), their angles θ (B,), and which are near π.

    Near a half turn (the mask) ``ω`` is not reliable: the caller recomputes those.
    """
    r = rotation.reshape(-1, 9)
    a = 0.5 * (r[:, [7, 2, 3]] - r[:, [5, 6, 1]])  # ½ (R − Rᵀ)ᵛ = sin θ · axis
    s = np.sqrt(np.einsum("bi,bi->b", a, a))  # sin θ
    c = 0.5 * (r[:, 0] + r[:, 4] + r[:, 8] - 1.0)  # cos θ
    theta = np.arctan2(s, c)
    s2 = s * s
    ratio = np.where(s > 1e-4, theta / np.maximum(s, 1e-4), 1.0 + s2 / 6.0 + 3.0 * s2 * s2 / 40.0)
    return a * ratio[:, None], theta, theta > np.pi - NEAR_PI


def log6_and_jacobian(
    rotation: np.ndarray, translation: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``log6`` (B, 6) of placements ``(R, p)`` and its Jacobian ``Jlog6`` (B, 6, 6).

    Args:
        rotation: Shape (B, 3, 3).
        translation: Shape (B, 3).

    Returns:
        ``(nu, jlog, near_pi)``: the twists ``[v; ω]``, their Jacobians (Pinocchio's ``Jlog6``)
        and the mask of rotations near a half turn, whose rows the caller must recompute.
    """
    w, theta, near_pi = log3(rotation)
    p = translation
    alpha, beta, dbeta = _coefficients(theta)
    wp = np.einsum("bi,bi->b", w, p)
    nu = np.empty((len(p), 6))
    nu[:, :3] = alpha[:, None] * p - 0.5 * cross(w, p) + (beta * wp)[:, None] * w
    nu[:, 3:] = w
    # Jlog3 = β ω ωᵀ + α I + ½ [ω]×;  C = v ωᵀ + β ω pᵀ + β (ω·p) I + ½ [p]×
    j3 = (beta[:, None] * w)[:, :, None] * w[:, None, :] + skew(0.5 * w)
    j3[:, _DIAG, _DIAG] += alpha[:, None]
    v3 = (dbeta * wp)[:, None] * w - (theta * theta * dbeta + 2.0 * beta)[:, None] * p
    c = v3[:, :, None] * w[:, None, :] + (beta[:, None] * w)[:, :, None] * p[:, None, :] + skew(0.5 * p)
    c[:, _DIAG, _DIAG] += (wp * beta)[:, None]
    jlog = np.zeros((len(p), 6, 6))
    jlog[:, :3, :3] = j3
    jlog[:, 3:, 3:] = j3
    jlog[:, :3, 3:] = c @ j3
    return nu, jlog, near_pi


def act_inverse(rotation: np.ndarray, translation: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """``M⁻¹ · m`` for motions ``m`` (B, 6, k) and placements ``M = (R, p)``: ``toActionMatrixInverse() @ m``.

    ``[Rᵀ (v − p × ω) ; Rᵀ ω]`` column by column.
    """
    rt = np.swapaxes(rotation, 1, 2)
    v, w = motion[:, :3], motion[:, 3:]
    out = np.empty_like(motion)
    out[:, :3] = rt @ (v - cross(translation, w))
    out[:, 3:] = rt @ w
    return out
