"""Reliability of the accuracy index ``Δλ = ‖J η‖`` (paper Eqs. 9–17, and exact alternatives).

For Gaussian ``η ~ N(0, diag(σ²))``, ``Δλ² = ηᵀ Jᵀ J η`` is a generalized chi-square: a weighted
sum ``Σ λ_k χ²_1`` with ``λ_k`` the eigenvalues of ``J diag(σ²) Jᵀ`` (3 × 3). Its mean has a closed
form (Carlson's ``R_G``); its distribution function is a smooth integral over the unit sphere.
:func:`exact_reliability_many` evaluates it at many poses at once (one stacked eigendecomposition,
the quadrature as one array expression).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import special

import pkmtol.values as values


def reliability_fosm(beta: float | np.ndarray) -> np.ndarray:
    """The paper's ``R = Φ(β)`` (Eq. 13)."""
    beta = values.array("beta", beta) if not isinstance(beta, int | float) else values.number("beta", beta)
    return np.asarray(special.ndtr(beta))


def chi3_cdf_half_square(x: np.ndarray) -> np.ndarray:
    """``P(χ²₃ ≤ 2x)`` = ``gammainc(3/2, x)`` in closed form: ``erf(√x) − 2 √(x/π) e^{−x}``.

    The χ₃ distribution function at ``y = √(2x)``; 3× faster than ``gammainc`` and equal to it to
    round-off (``tests/test_reliability.py``).

    >>> round(float(chi3_cdf_half_square(np.array(2.0))), 12)   # P(χ²₃ ≤ 4)
    0.738535870329
    """
    r = np.sqrt(x)
    return special.erf(r) - (2.0 / math.sqrt(math.pi)) * r * np.exp(-x)


# --- exact reliability of the linear model ------------------------------------------------

#: Quadrature nodes over one octant of the unit sphere (the integrand depends on u² only):
#: Gauss–Legendre in cos θ ∈ [0, 1], midpoint (= trapezoid for this periodic, even integrand)
#: in φ ∈ [0, π/2].
_N_THETA = 48
_N_PHI = 48


def _sphere_nodes(n_theta: int, n_phi: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (k, 3) in the first octant and weights (k,) summing to 1."""
    x, w = np.polynomial.legendre.leggauss(n_theta)
    ct, wt = 0.5 * (x + 1.0), 0.5 * w  # cos θ ∈ [0, 1]
    phi = 0.5 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    c, ph = np.meshgrid(ct, phi, indexing="ij")
    st = np.sqrt(1.0 - c**2)
    u = np.stack([st * np.cos(ph), st * np.sin(ph), c], axis=-1).reshape(-1, 3)
    weights = np.repeat(wt, n_phi) / n_phi
    return u, weights


_NODES = _sphere_nodes(_N_THETA, _N_PHI)


def exact_reliability(
    covariance: np.ndarray, threshold_m: float, gradient: bool = False
) -> tuple[float, np.ndarray | None]:
    """``R = P(‖x‖ ≤ Δλ*)`` for ``x ~ N(0, Σ)`` in 3-D, exactly up to quadrature error (< 1e-9).

    With ``x = Σ^{1/2} z`` and ``z = s·u`` (``s = ‖z‖``, ``u`` uniform on the unit sphere),
    ``‖x‖ ≤ t ⟺ s ≤ t / √(uᵀ Σ u)``, so ``R = E_u[F_χ₃(t / √(uᵀ Σ u))]`` with ``F_χ₃`` the chi
    distribution function with 3 degrees of freedom. The integrand is smooth on the sphere, so a
    product rule (Gauss–Legendre in ``cos θ`` × trapezoid in ``φ``, in Σ's eigenbasis) converges
    exponentially; no oscillatory integral as in Imhof's formula.

    Args:
        covariance: Σ, shape (3, 3) [m²] (e.g. ``J diag(σ²) Jᵀ``).
        threshold_m: Δλ* [m].
        gradient: Also return ``∂R/∂Σ`` (3, 3), symmetric.

    Returns:
        ``(R, dR_dSigma or None)``.

    >>> r, _ = exact_reliability(np.eye(3) * 1e-10, 2e-5)   # isotropic: P(χ²₃ ≤ 4)
    >>> round(r, 9)
    0.73853587
    """
    covariance = values.array_of_shape("covariance", covariance, (3, 3))
    values.number("threshold_m", threshold_m, positive=True)
    lam, vec = np.linalg.eigh(np.asarray(covariance, dtype=float))
    lam = np.clip(lam, 0.0, None)  # ascending: the largest variance on the polar axis
    if lam.max() <= 0.0:
        return 1.0, (np.zeros((3, 3)) if gradient else None)
    u, w = _NODES
    q = (u**2) @ lam  # uᵀ Λ u in the eigenbasis
    q = np.maximum(q, lam.max() * 1e-300)
    y = threshold_m / np.sqrt(q)  # radius in z-space
    r = float(w @ chi3_cdf_half_square(0.5 * y * y))
    if not gradient:
        return r, None
    # dF_χ3(y)/dy = chi pdf = √(2/π) y² e^{−y²/2};  dy/dq = −y / (2q)
    pdf = math.sqrt(2.0 / math.pi) * y * y * np.exp(-0.5 * y * y)
    coef = w * pdf * (-y / (2.0 * q))
    # ∂q/∂Σ = ũ ũᵀ with ũ = V u; over the whole sphere the off-diagonal terms u_i u_j (i ≠ j)
    # integrate to zero in the eigenbasis, so only the diagonal survives the octant rule
    d_lam = (u**2).T @ coef
    return r, (vec * d_lam) @ vec.T


def exact_reliability_many(
    covariances: np.ndarray, threshold_m: float, gradient: bool = False
) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`exact_reliability` at many poses: ``Σ`` (m, 3, 3) [m²] → ``R`` (m,) (and ``∂R/∂Σ`` (m, 3, 3)).

    The same quadrature as :func:`exact_reliability`, pose by pose, with the eigendecompositions
    stacked; poses whose covariance vanishes get ``R = 1`` (and a zero gradient).
    """
    cov = np.asarray(covariances, dtype=float).reshape(-1, 3, 3)
    lam, vec = np.linalg.eigh(cov)
    lam = np.clip(lam, 0.0, None)
    top = lam.max(axis=1)
    zero = top <= 0.0
    u, w = _NODES
    q = lam @ (u**2).T  # (m, nodes): uᵀ Λ u in each eigenbasis
    q = np.maximum(q, np.where(zero, 1.0, top)[:, None] * 1e-300)
    y = threshold_m / np.sqrt(q)
    x = 0.5 * y * y
    r = chi3_cdf_half_square(x) @ w
    r[zero] = 1.0
    if not gradient:
        return r, None
    with np.errstate(over="ignore", invalid="ignore"):  # a pose without variance: y = ∞, set below
        pdf = math.sqrt(2.0 / math.pi) * y * y * np.exp(-x)
        coef = w * pdf * (-y / (2.0 * q))
    coef[zero] = 0.0
    d_lam = coef @ (u**2)  # (m, 3)
    grad = (vec * d_lam[:, None, :]) @ np.swapaxes(vec, 1, 2)
    grad[zero] = 0.0
    return r, grad


def exact_reliability_imhof(eigenvalues: np.ndarray, threshold_m: float) -> float:
    """The same probability by Imhof's (1961) inversion formula (an independent check).

    ``P(Q > x) = ½ + (1/π) ∫₀^∞ sin θ(u) / (u ρ(u)) du`` with ``Q = Σ λ_k χ²₁``,
    ``θ(u) = ½ Σ arctan(λ_k u) − ½ x u`` and ``ρ(u) = Π (1 + λ_k² u²)^{1/4}``; the oscillatory tail
    is integrated with QUADPACK's Fourier rule (QAWF).
    """
    from scipy import integrate  # only this check integrates; keep it out of the start-up

    lam = np.asarray(eigenvalues, dtype=float)
    lam = lam[lam > 0]
    if lam.size == 0:
        return 1.0
    scale = threshold_m**2
    lam = lam / scale  # x = 1

    def amp(u: float) -> float:
        return float(np.prod((1.0 + (lam * u) ** 2) ** 0.25))

    def phase(u: float) -> float:
        return 0.5 * float(np.sum(np.arctan(lam * u)))

    def full(u: float) -> float:
        if u == 0.0:
            return 0.5 * float(lam.sum()) - 0.5
        return math.sin(phase(u) - 0.5 * u) / (u * amp(u))

    a = 50.0
    head, _ = integrate.quad(full, 0.0, a, limit=2000, epsabs=1e-13, epsrel=1e-12)

    # tail ∫_a^∞ sin(φ(u) − u/2)/(u ρ(u)) du with u = v + a and
    # sin(φ − (v + a)/2) = sin φ [cos(v/2) cos(a/2) − sin(v/2) sin(a/2)]
    #                    − cos φ [sin(v/2) cos(a/2) + cos(v/2) sin(a/2)]
    def fourier(trig: Any, weight: str) -> float:
        val, _ = integrate.quad(
            lambda v: trig(phase(v + a)) / ((v + a) * amp(v + a)),
            0.0,
            np.inf,
            weight=weight,
            wvar=0.5,
            limlst=200,
        )
        return float(val)

    ca, sa = math.cos(0.5 * a), math.sin(0.5 * a)
    tail = (
        ca * fourier(math.sin, "cos")
        - sa * fourier(math.sin, "sin")
        - ca * fourier(math.cos, "sin")
        - sa * fourier(math.cos, "cos")
    )
    p_exceed = 0.5 + (head + tail) / math.pi
    return 1.0 - p_exceed


def exact_distribution(covariance: np.ndarray) -> ExactDistribution:
    """``q ↦ P(‖x‖ ≤ q)`` for ``x ~ N(0, Σ)`` in 3-D: :func:`exact_reliability` as a function of ``q``.

    The eigen-decomposition and the sphere nodes are computed once, so that a root finder (a
    quantile) evaluates it cheaply; same quadrature, same accuracy. The result also gives the
    density ``dP/dq`` (:meth:`ExactDistribution.density`).

    >>> F = exact_distribution(np.eye(3) * 1e-10)
    >>> round(F(2e-5), 9) == round(exact_reliability(np.eye(3) * 1e-10, 2e-5)[0], 9)
    True
    """
    return ExactDistribution(np.asarray(covariance, dtype=float))


class ExactDistribution:
    """The distribution of ``‖x‖``, ``x ~ N(0, Σ)`` in 3-D (see :func:`exact_distribution`).

    Per sphere node ``u``, ``‖x‖`` along ``u`` is a χ₃ scaled by ``√(uᵀΛu)``; the distribution is
    the nodes' weighted sum: ``F(q) = Σ w F_χ₃(q / √(uᵀΛu))`` and ``f(q) = dF/dq``.

    Args:
        covariance: Shape (3, 3): ``Σ`` [m²].
    """

    def __init__(self, covariance: np.ndarray) -> None:
        lam = np.clip(np.linalg.eigvalsh(covariance), 0.0, None)
        self.degenerate = bool(lam.max() <= 0.0)  # x = 0: ‖x‖ ≤ q for every q ≥ 0
        u, self._w = _NODES
        if self.degenerate:
            self._root_inv = np.zeros(len(self._w))
        else:  # 1 / √(uᵀΛu)
            self._root_inv = np.sqrt(1.0 / np.maximum((u**2) @ lam, lam.max() * 1e-300))

    def __call__(self, q: float) -> float:
        """``P(‖x‖ ≤ q)``."""
        if self.degenerate:
            return 1.0 if q >= 0 else 0.0
        if q <= 0:
            return 0.0
        # F_χ₃(y) = P(3/2, y²/2) = erf(y/√2) − √(2/π) y e^{−y²/2}, cheaper than gammainc
        y = q * self._root_inv
        return float(self._w @ (special.erf(y / math.sqrt(2.0)) - _C_CHI3 * y * np.exp(-0.5 * y * y)))

    def density(self, q: float) -> float:
        """``dP(‖x‖ ≤ q)/dq`` [1/m]: ``Σ w f_χ₃(y) / √(uᵀΛu)``, ``f_χ₃(y) = √(2/π) y² e^{−y²/2}``."""
        if self.degenerate or q <= 0:
            return 0.0
        y = q * self._root_inv
        return float(self._w @ (_C_CHI3 * y * y * np.exp(-0.5 * y * y) * self._root_inv))


#: √(2/π), of the χ₃ distribution's CDF and density.
_C_CHI3 = math.sqrt(2.0 / math.pi)
