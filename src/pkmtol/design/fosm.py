"""Tolerance allocation with FOSM (paper §3.2, Eqs. 18–20).

Sensitivity (Eq. 18): ``Δλ = ‖J η‖`` is a norm, not differentiable at ``η = 0``, so the paper's
``|∂g/∂η_i|`` is taken as ``ω_i = ‖J_{:,i}‖`` [m per unit of η_i] — the standard deviation of
``Δλ``'s linear response (the vector ``J η``) to a unit-σ error ``η_i`` — which makes
``Σ ω_i² σ_i² = E[Δλ²]`` exact for independent zero-mean errors (docs/theory.md).

Equal-effect allocation (Eqs. 19–20): ``ω_i σ_i`` equal for all ``n`` allocated parameters and
``√(Σ ω_i² σ_i²) = Δλ*/β``, so ``σ_i = Δλ* / (√n ω_i β)``. Parameters with ``ω_i = 0`` at the
design point do not count in ``n`` and get ``σ_i = +∞`` (free: choose by manufacturing capacity).
"""

from __future__ import annotations

import numpy as np

import pkmtol.values as values
from pkmtol.exceptions import InvalidRequestError


def fosm_tolerances(
    omega: np.ndarray, target_m: float, betas: np.ndarray, noise_variance: float = 0.0
) -> np.ndarray:
    """Equal-effect FOSM tolerances ``σ_i(β) = √((Δλ*/β)² − v) / (√n ω_i)``.

    ``v`` is a fixed variance of Δλ's linear response that no tolerance changes (the tracker noise
    left after a calibration, ``σ_m² ‖N‖²_F`` at the design pose); with ``v = 0`` this is the
    paper's ``Δλ*/(√n ω_i β)`` (Eq. 20). Where ``(Δλ*/β)² ≤ v`` no tolerance reaches the target:
    that column is NaN.

    Args:
        omega: Sensitivities (n,).
        target_m: Δλ* [m].
        betas: Reliability indices (k,).
        noise_variance: ``v`` [m²].

    Returns:
        Shape (n, k): tolerances in each parameter's SI unit; ``inf`` where ``ω_i = 0``.

    >>> fosm_tolerances(np.array([1.0, 2.0, 0.0]), 5e-5, np.array([1.0, 2.0])) * 1e6
    array([[35.35533906, 17.67766953],
           [17.67766953,  8.83883476],
           [        inf,         inf]])
    """
    omega = values.array("omega", omega, ndim=1)
    target_m = values.number("target_m", target_m)
    betas = values.array("betas", betas, ndim=1)
    check_design(target_m, betas)
    noise_variance = values.number("noise_variance", noise_variance, nonnegative=True)
    scale = 1e-12 * max(float(omega.max(initial=0.0)), 1e-300)
    active = omega > scale
    n = int(active.sum())
    b = np.asarray(betas, dtype=float)
    budget2 = (target_m / b) ** 2 - noise_variance
    budget = np.where(budget2 > 0, np.sqrt(np.clip(budget2, 0.0, None)), np.nan)
    out = np.full((omega.size, b.size), np.inf)
    if n:
        out[active] = budget[None, :] / (np.sqrt(n) * omega[active, None])
    return out


def noise_floor_m(beta: float, noise_variance: float) -> float:
    """The smallest Δλ* FOSM can meet at ``β`` when the noise alone has variance ``v``: ``β √v`` [m]."""
    return float(beta * np.sqrt(max(noise_variance, 0.0)))


def check_design(target_m: float, betas: np.ndarray | list[float] | tuple[float, ...]) -> None:
    """Raise InvalidRequestError unless ``Δλ* > 0`` and every ``β > 0``."""
    if not np.isfinite(target_m) or target_m <= 0:
        raise InvalidRequestError(
            f"the required accuracy Δλ* must be positive, got {target_m * 1e3:g} mm; "
            "give e.g. --target 0.05mm"
        )
    b = np.atleast_1d(np.asarray(betas, dtype=float))
    if b.size == 0 or np.any(~np.isfinite(b)) or np.any(b <= 0):
        raise InvalidRequestError(
            f"every reliability index β must be positive, got {b.tolist()}; give e.g. --beta 2"
        )
