"""Reliability of the accuracy index ``Δλ = ‖J η‖`` (paper Eqs. 9–17, and exact alternatives).

For Gaussian ``η ~ N(0, diag(σ²))``, ``Δλ² = ηᵀ Jᵀ J η`` is a generalized chi-square: a weighted
sum ``Σ λ_k χ²_1`` with ``λ_k`` the eigenvalues of ``J diag(σ²) Jᵀ`` (3 × 3). Its moments and
distribution are one-dimensional integrals, computed here with scipy's adaptive quadrature.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import integrate, stats


def reliability_fosm(beta: float | np.ndarray) -> np.ndarray:
    """The paper's ``R = Φ(β)`` (Eq. 13)."""
    return np.asarray(stats.norm.cdf(beta))


def covariance_eigenvalues(J: np.ndarray, sigma: np.ndarray | None = None) -> np.ndarray:
    """Eigenvalues (descending, ≥ 0) of ``J diag(σ²) Jᵀ`` [m²]; ``σ`` defaults to ones."""
    a = J if sigma is None else J * np.asarray(sigma)[None, :]
    return np.clip(np.linalg.eigvalsh(a @ a.T)[::-1], 0.0, None)


def norm_moments(eigenvalues: np.ndarray) -> tuple[float, float]:
    """Mean and standard deviation of ``‖x‖`` for ``x ~ N(0, Σ)`` with the given eigenvalues of Σ.

    Uses ``E√Q = (1/(2√π)) ∫₀^∞ (1 − E[e^{−tQ}]) t^{−3/2} dt`` with
    ``E[e^{−tQ}] = Π (1 + 2 λ_k t)^{−1/2}`` and ``E[Q] = Σ λ_k``.

    >>> m, s = norm_moments(np.array([1.0]))   # half-normal: √(2/π), √(1 − 2/π)
    >>> round(m, 6), round(s, 6)
    (0.797885, 0.602810)
    """
    lam = np.asarray(eigenvalues, dtype=float)
    lam = lam[lam > 0]
    if lam.size == 0:
        return 0.0, 0.0
    scale = float(lam.max())
    lam_n = lam / scale

    def integrand(u: float) -> float:
        # t = u / (1 - u) maps [0, 1) to [0, ∞)
        t = u / (1.0 - u)
        mgf = float(np.prod(1.0 + 2.0 * lam_n * t) ** -0.5)
        return (1.0 - mgf) * t**-1.5 / (1.0 - u) ** 2

    val, _ = integrate.quad(integrand, 0.0, 1.0, limit=200, epsabs=1e-13, epsrel=1e-11)
    mean = val / (2.0 * math.sqrt(math.pi)) * math.sqrt(scale)
    second = float(lam.sum())
    return mean, math.sqrt(max(second - mean * mean, 0.0))
