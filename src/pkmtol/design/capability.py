"""Process capability of a design: Cpk of Δλ against Δλ*, the exact out-of-spec PPM and the sigma level.

With Gaussian errors at the design's σ_i (and, after a calibration, the tracker noise), P's error at
a pose is ``x ~ N(0, Σ)`` (3-D) and ``Δλ = ‖x‖``. The specification is one-sided (``Δλ ≤ Δλ*``), so

    Cpk = (Δλ* − μ) / (3 σ),    μ = E[Δλ],  σ = √Var[Δλ]   (closed form, ``norm_moments``),

as a tolerance engineer computes it from a sample. Cpk presumes a normal Δλ; Δλ is a norm (never
negative, skewed), so the out-of-spec fraction it implies, ``Φ(−3 Cpk)``, is not the true one.
The true fraction comes from the exact distribution of ``‖x‖``
(:func:`pkmtol.design.reliability.exact_distribution`): ``PPM = 10⁶ (1 − R)``, and the sigma level
is ``Z = Φ⁻¹(1 − PPM/10⁶)`` — the long-term Z, without the 1.5σ shift of the six-sigma
convention (add 1.5 for the "short-term" figure). Both are reported at every grid pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from pkmtol.design.reliability import ExactDistribution, exact_distribution
from pkmtol.error_model.accuracy import first_max, norm_moments
from pkmtol.exceptions import InvalidRequestError

#: Below this out-of-spec fraction the quadrature of ``exact_reliability`` (error < 1e-9) cannot
#: tell it from zero: PPM is reported as an upper bound and Z as a lower bound.
RESOLUTION = 1e-9


@dataclass(frozen=True, eq=False)
class Capability:
    """Capability of one accuracy index at every pose of a grid (SI: m, or rad for the tilt).

    Attributes:
        target: The one-sided specification limit (Δλ* or Δα*).
        mean: Shape (m,): ``μ = E[Δλ]`` at each pose.
        std: Shape (m,): ``σ = √Var[Δλ]``.
        cpk: Shape (m,): ``(target − μ) / (3σ)`` (inf where σ = 0).
        ppm: Shape (m,): exact out-of-spec parts per million, ``10⁶ P(Δλ > target)``.
        ppm_normal: Shape (m,): what Cpk implies for a normal Δλ, ``10⁶ Φ(−3 Cpk)``.
        sigma_level: Shape (m,): ``Z = Φ⁻¹(1 − ppm/10⁶)`` (no 1.5σ shift).
        quantile: Shape (m,): the exact ``R*``-quantile of Δλ (the value not exceeded with
            probability ``R*``; nan when ``R*`` is not given).
        reliability_target: The ``R*`` of ``quantile`` (e.g. Φ(design β)), or None.
    """

    target: float
    mean: np.ndarray
    std: np.ndarray
    cpk: np.ndarray
    ppm: np.ndarray
    ppm_normal: np.ndarray
    sigma_level: np.ndarray
    quantile: np.ndarray
    reliability_target: float | None

    @property
    def worst_cpk_index(self) -> int:
        """Pose with the smallest Cpk."""
        return first_max(-np.asarray(self.cpk, dtype=float))

    @property
    def worst_ppm_index(self) -> int:
        """Pose with the most parts out of specification."""
        return first_max(np.asarray(self.ppm, dtype=float))

    @property
    def resolved(self) -> np.ndarray:
        """Shape (m,): True where the exact PPM is above the quadrature's resolution (1e-3 ppm)."""
        return self.ppm > 1e6 * RESOLUTION


def exact_quantile(covariance: np.ndarray, probability: float) -> float:
    """The ``probability``-quantile of ``‖x‖`` for ``x ~ N(0, Σ)`` in 3-D (Brent on the exact CDF).

    Bracket: ``‖x‖ ≤ √λ_max χ₃``, so the quantile lies below ``√λ_max F⁻¹_χ₃(probability)``.

    >>> round(exact_quantile(np.eye(3), 0.5), 6)   # median of a χ₃
    1.538172
    """
    if not 0.0 < probability < 1.0:
        raise InvalidRequestError(f"the quantile's probability must be in (0, 1), got {probability!r}")
    return _quantile(exact_distribution(covariance), covariance, probability)


def _quantile(cdf: ExactDistribution, covariance: np.ndarray, probability: float) -> float:
    """The ``probability`` quantile of ``cdf``: safeguarded Newton on ``F(q) = p`` in a bracket.

    The bracket ``[0, √λ_max F⁻¹_χ₃(p)]`` holds the root, and ``F`` is smooth and increasing with
    its density known in closed form, so Newton converges in a few steps; a step that leaves the
    bracket is replaced by bisection. Stops when the step is below ``1e-12`` of the bracket plus
    ``1e-10`` of the root (the tolerance ``scipy.optimize.brentq`` was given here; importing
    scipy.optimize cost a sixth of ``pkmtol allocate``'s CPU).
    """
    lam_max = float(np.linalg.eigvalsh(np.asarray(covariance, dtype=float)).max())
    if lam_max <= 0.0:
        return 0.0
    # F⁻¹_χ₃(p) = √(2 P⁻¹(3/2, p)), as scipy.stats.chi computes it
    hi = math.sqrt(lam_max) * math.sqrt(2.0 * float(special.gammaincinv(1.5, probability))) * (1 + 1e-9)
    tol = 1e-12 * hi
    lo, q = 0.0, 0.5 * hi
    for _ in range(200):
        g = cdf(q) - probability
        lo, hi = (lo, q) if g > 0 else (q, hi)
        slope = cdf.density(q)
        new = q - g / slope if slope > 0 else lo - 1.0
        if not lo < new < hi:  # off the bracket: bisect
            new = 0.5 * (lo + hi)
        if abs(new - q) <= tol + 1e-10 * new or hi - lo <= tol:
            return new
        q = new
    return q


def capability(covariance: np.ndarray, target: float, reliability_target: float | None = None) -> Capability:
    """Cpk, exact PPM, the implied-normal PPM, sigma level and quantile at every pose.

    Args:
        covariance: Shape (m, 3, 3): covariance of the error vector at each pose (``L Σ Lᵀ +
            σ_m² N Nᵀ`` for P [m²]; the tilt vector's for Δα [rad²]).
        target: The upper specification limit Δλ* [m] (or Δα* [rad]), > 0.
        reliability_target: ``R*`` for the quantile column (e.g. Φ(β)); None: no quantile.

    Raises:
        InvalidRequestError: a covariance of the wrong shape, or a non-positive target.
    """
    cov = np.asarray(covariance, dtype=float)
    if cov.ndim != 3 or cov.shape[1:] != (3, 3):
        raise InvalidRequestError(f"need covariances of shape (m, 3, 3), got {cov.shape}")
    if not (math.isfinite(target) and target > 0):
        raise InvalidRequestError(f"the specification limit must be positive, got {target!r}")
    if reliability_target is not None and not 0.0 < reliability_target < 1.0:
        raise InvalidRequestError(f"the quantile's probability must be in (0, 1), got {reliability_target!r}")
    m = cov.shape[0]
    mean, std, ppm, quant = np.empty(m), np.empty(m), np.empty(m), np.full(m, np.nan)
    for k, c in enumerate(cov):
        lam = np.clip(np.linalg.eigvalsh(c)[::-1], 0.0, None)
        mean[k], std[k] = norm_moments(lam)
        cdf = exact_distribution(c)
        ppm[k] = 1e6 * min(max(1.0 - cdf(target), 0.0), 1.0)
        if reliability_target is not None:
            quant[k] = _quantile(cdf, c, reliability_target)
    with np.errstate(divide="ignore", invalid="ignore"):
        cpk = np.where(std > 0, (target - mean) / (3.0 * std), np.inf)
    p = np.clip(ppm / 1e6, RESOLUTION, 1.0)
    return Capability(
        target=float(target),
        mean=mean,
        std=std,
        cpk=cpk,
        ppm=ppm,
        ppm_normal=1e6 * special.ndtr(-3.0 * cpk),  # the normal tail Φ(−3 Cpk), as scipy.stats.norm.sf
        sigma_level=-special.ndtri(p),  # Φ⁻¹(1 − p), as scipy.stats.norm.isf computes it
        quantile=quant,
        reliability_target=reliability_target,
    )
