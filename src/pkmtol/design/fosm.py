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

from dataclasses import dataclass

import numpy as np

import pkmtol.values as values
from pkmtol.error_model.accuracy import first_max, grid_norm_moments, sensitivities
from pkmtol.exceptions import InvalidRequestError, NoiseFloorError


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


def allocation_sensitivity(
    position: np.ndarray, cols: np.ndarray, worst: int
) -> tuple[np.ndarray, np.ndarray]:
    """``ω_i`` at the design point, with each zero one taken from its own most sensitive pose.

    A parameter with no effect at the design point but some elsewhere on the grid is never left
    free silently (docs/theory.md, "No error left untoleranced").

    Args:
        position: Grid maps (m, 3, n_params) [m per unit].
        cols: Indices of the allocated parameters.
        worst: Grid index of the design point.

    Returns:
        ``(ω (len(cols),), fallback pose (len(cols),) or −1)``.
    """
    per_pose = np.linalg.norm(position[:, :, cols], axis=1)  # (m, k)
    omega = per_pose[worst].copy()
    top = max(float(per_pose.max(initial=0.0)), 1e-300)
    fallback = np.full(cols.size, -1, dtype=int)
    zero = omega <= 1e-12 * top
    anywhere = per_pose.max(axis=0) > 1e-12 * top
    for j in np.flatnonzero(zero & anywhere):
        fallback[j] = first_max(per_pose[:, j])
        omega[j] = per_pose[fallback[j], j]
    return omega, fallback


def tolerances_above_floor(
    omega: np.ndarray,
    target: float,
    noise_var: float,
    what: str,
    *,
    n_par: int,
    unc: np.ndarray,
    betas: tuple[float, ...],
    design_beta: float,
    noise: tuple[float, int] | None,
) -> np.ndarray:
    """FOSM tolerances (n_par, len(betas)) of the columns ``unc`` (NaN elsewhere) against ``target``.

    The noise enters as the fixed variance ``noise_var``; when it alone misses the target at the
    design β, NoiseFloorError names ``what`` and ``noise`` = (tracker σ [m], plan poses).
    """
    tol = np.full((n_par, len(betas)), np.nan)
    tol[unc] = fosm_tolerances(omega, target, np.array(betas), noise_var)
    design_col = int(np.argmin(np.abs(np.asarray(betas) - design_beta)))
    if unc.size and np.isnan(tol[unc[0], design_col]):
        assert noise is not None  # only a calibration's noise has a floor
        floor = noise_floor_m(design_beta, noise_var)
        raise NoiseFloorError(noise[0], noise[1], floor, target, design_beta, what)
    return tol


@dataclass(frozen=True)
class Traditional:
    """The traditional method (§4.5): every non-absorbed error, no compensation.

    Attributes:
        columns: Parameter indices allocated (all non-absorbed).
        worst_index: Grid index of its own most sensitive point (reported only).
        sensitivity: Shape (len(columns),): ``‖J_total[:, i]‖`` at the design point of the new
            method (the same point, so that the comparison isolates the effect of compensation).
        tolerance: Shape (len(columns),): FOSM tolerance at the design β (SI; inf = free).
    """

    columns: np.ndarray
    worst_index: int
    sensitivity: np.ndarray
    tolerance: np.ndarray


def traditional_design(
    J_total: np.ndarray, classes: list[str], worst: int, target_m: float, design_beta: float
) -> Traditional:
    """The traditional method on grid maps ``J_total`` (m, 3, n_params), at the new method's design point.

    Evaluated at the same design point as the new method, so the comparison isolates what
    compensation buys; the traditional model's own most sensitive point is reported beside it.
    """
    cols = np.array([i for i, c in enumerate(classes) if c != "absorbed"], dtype=int)
    sens = sensitivities(J_total[worst][:, cols])
    return Traditional(
        columns=cols,
        worst_index=first_max(grid_norm_moments(J_total[:, :, cols])[:, 1]),
        sensitivity=sens,
        tolerance=fosm_tolerances(sens, target_m, np.array([design_beta]))[:, 0],
    )
