"""The accuracy index ``Δλ = ‖J η‖`` (Eqs. 23–24): sensitivities ω_i, and its mean and σ for Gaussian η.

For Gaussian ``η ~ N(0, diag(σ²))``, ``J η`` is a 3-D Gaussian vector with covariance
``J diag(σ²) Jᵀ``; the moments of its norm have closed forms (Carlson's ``R_G``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

import pkmtol.values as values


def sensitivities(J: np.ndarray) -> np.ndarray:
    """``ω_i = ‖J[:, i]‖`` (n,) [m per m or m per rad] for ``J`` of shape (3, n)."""
    J = values.array("J", J, ndim=2)
    return np.linalg.norm(J, axis=0)


def covariance_eigenvalues(J: np.ndarray, sigma: np.ndarray | None = None) -> np.ndarray:
    """Eigenvalues (descending, ≥ 0) of ``J diag(σ²) Jᵀ`` [m²]; ``σ`` defaults to ones."""
    a = J if sigma is None else J * np.asarray(sigma)[None, :]
    return np.clip(np.linalg.eigvalsh(a @ a.T)[::-1], 0.0, None)


def norm_moments(eigenvalues: np.ndarray) -> tuple[float, float]:
    """Mean and standard deviation of ``‖x‖`` for ``x ~ N(0, Σ)`` in 3-D, from Σ's eigenvalues.

    Closed form: with ``x = Σ^{1/2} z`` and ``z = s u`` (``s ~ χ₃`` independent of ``u``, uniform on
    the unit sphere), ``‖x‖ = s √(uᵀ Λ u)``, so ``E‖x‖ = E[χ₃] · E_u[√(uᵀΛu)] = 2√(2/π) R_G(λ₁, λ₂, λ₃)``
    — the sphere average of ``√(uᵀΛu)`` is Carlson's symmetric elliptic integral ``R_G``
    (:func:`scipy.special.elliprg`). ``E‖x‖² = Σ λ_k``. Fewer than 3 eigenvalues are padded with 0.

    >>> m, s = norm_moments(np.array([1.0]))   # half-normal: √(2/π), √(1 − 2/π)
    >>> round(m, 6), round(s, 6)
    (0.797885, 0.60281)
    """
    eigenvalues = values.array("eigenvalues", eigenvalues, ndim=1)
    lam = np.clip(np.asarray(eigenvalues, dtype=float), 0.0, None)
    if lam.size > 3:
        raise ValueError(f"norm_moments is for 3-D vectors; got {lam.size} eigenvalues")
    if lam.size == 0 or lam.max() <= 0.0:
        return 0.0, 0.0
    lam = np.concatenate([lam, np.zeros(3 - lam.size)])
    scale = float(lam.max())
    mean = 2.0 * math.sqrt(2.0 / math.pi) * math.sqrt(scale) * float(special.elliprg(*(lam / scale)))
    second = float(lam.sum())
    return mean, math.sqrt(max(second - mean * mean, 0.0))


def grid_norm_moments(J: np.ndarray, sigma: np.ndarray | None = None) -> np.ndarray:
    """:func:`norm_moments` of ``‖J_j η‖`` at every pose: ``J`` (m, 3, n), ``σ`` (n,) → (m, 2).

    Column 0 is the mean, column 1 the standard deviation of ``Δλ_j`` [m] for independent
    ``η_i ~ N(0, σ_i²)`` (``σ`` defaults to ones).
    """
    return np.array([norm_moments(covariance_eigenvalues(Jj, sigma)) for Jj in J]).reshape(-1, 2)


#: Values within this relative distance of the largest count as tied with it.
TIE_TOLERANCE = 1e-9


def first_max(values: np.ndarray) -> int:
    """Index of the largest value, the first one among those tied with it to :data:`TIE_TOLERANCE`.

    Symmetric mechanisms have pairs of poses with the same σ[Δλ] up to round-off; ``np.argmax``
    would pick one of a pair by the last bit, which changes with any reordering of the arithmetic.

    >>> first_max(np.array([1.0, 3.0, 3.0 * (1 + 1e-14), 2.0]))
    1
    """
    v = np.asarray(values, dtype=float)
    top = float(v.max())
    return int(np.flatnonzero(v >= top - TIE_TOLERANCE * abs(top))[0])


def vector_norms(x: np.ndarray) -> np.ndarray:
    """Euclidean norms of 3-vectors: ``x`` of shape (..., 3) → (...); e.g. Δλ = ‖e‖ of P's errors.

    Component by component: the numbers of ``np.linalg.norm(x, axis=-1)`` (the same sum of three
    squares, in the same order), without its reduction over an axis of length 3, which costs
    several times the arithmetic on the millions of rows of a Monte Carlo run.

    >>> vector_norms(np.array([[3.0, 4.0, 12.0], [0.0, 0.0, -2.0]])).tolist()
    [13.0, 2.0]
    """
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
