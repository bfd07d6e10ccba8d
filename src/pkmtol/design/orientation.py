"""Orientation accuracy: the tilt Δα of the tool axis, its FOSM tolerances, and the joint reliability.

The tool axis ``a`` is fixed in the platform (``[design] tool_axis``, default the platform z axis).
A platform rotation ``θ`` (in K) tilts it by ``Δα = ‖(R a) × θ‖`` to first order; rotation about the
axis itself does not tilt it. With a target ``Δα*`` (``[design] orientation_target``), a design must
meet both ``Δλ ≤ Δλ*`` and ``Δα ≤ Δα*``:

* FOSM: the equal-effect tolerances of each index (each at its own most sensitive grid pose),
  then the smaller of the two per parameter — both FOSM conditions hold;
* the joint reliability ``R = P(Δλ ≤ Δλ* and Δα ≤ Δα*)``: ``(e, Δα-vector)`` is a 6-D Gaussian
  (rank ≤ 5); R is estimated from :data:`JOINT_DRAWS` fixed standard-normal draws (common random
  numbers, so that R is a smooth, monotone function of the tolerances); its standard error
  ``√(R(1−R)/draws)`` is reported with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pkmtol.error_model.accuracy import first_max, grid_norm_moments, norm_moments, sensitivities
from pkmtol.error_model.compensation import AccuracyMaps

#: Standard-normal draws behind the joint reliability (fixed: common random numbers).
JOINT_DRAWS = 20_000
JOINT_SEED = 20_251


@dataclass(frozen=True, eq=False)
class OrientationDesign:
    """The orientation side of a design (SI units, rad).

    Attributes:
        axis: The tool axis in the platform frame (unit vector).
        target_rad: Δα* (None: no orientation target; the tilt is only reported).
        worst_index: Grid index with the largest σ[Δα] for unit errors of the toleranced parameters.
        sensitivity: Shape (n_params,): ``‖tilt column‖`` at that pose [rad per unit].
        tolerances: Shape (n_params, len(betas)): FOSM tolerances of the tilt alone (NaN where not
            toleranced; None without a target).
        binding: Shape (n_params,): True where the tilt's tolerance is the smaller (None without a
            target).
        tilt_mean_rad: Mean Δα at the position's design point for the design-β tolerances [rad].
        tilt_std_rad: Its standard deviation [rad].
        tilt_grid_mean_rad: Shape (m,): mean Δα at every grid pose for those tolerances [rad].
    """

    axis: np.ndarray
    target_rad: float | None
    worst_index: int
    sensitivity: np.ndarray
    tolerances: np.ndarray | None
    binding: np.ndarray | None
    tilt_mean_rad: float
    tilt_std_rad: float
    tilt_grid_mean_rad: np.ndarray


def orientation_stage(
    maps: AccuracyMaps,
    unc: np.ndarray,
    sigma_full: np.ndarray,
    axis: np.ndarray,
    target_rad: float | None,
    design_pose: int,
    allocated: tuple[int, np.ndarray, np.ndarray, np.ndarray] | None,
) -> OrientationDesign:
    """The orientation stage: the tilt of the tool axis for the verified tolerances ``sigma_full``.

    Args:
        maps: The mode's maps on the grid.
        unc: Indices of the toleranced parameters.
        sigma_full: Shape (n_params,): every parameter's σ in the verified design (0: none).
        axis: The tool axis (unit, platform frame).
        target_rad: Δα* (None: the tilt is only reported).
        design_pose: The position's design pose (where the tilt's mean and σ are reported).
        allocated: The tilt's own allocation ``(worst pose, sensitivity, tolerances, binding)``
            when it has a target, else None (its sensitivities are then computed here).
    """
    tm = tilt_moments(maps, sigma_full, axis)
    tolerances: np.ndarray | None
    binding: np.ndarray | None
    if allocated is not None:
        worst, sens, tolerances, binding = allocated
    else:
        worst = tilt_worst_pose(maps, unc, axis) if unc.size else 0
        sens = np.zeros(sigma_full.size)
        if unc.size:
            sens[unc] = tilt_sensitivities(maps, unc, axis, worst)
        tolerances = binding = None
    return OrientationDesign(
        axis=axis,
        target_rad=target_rad,
        worst_index=worst,
        sensitivity=sens,
        tolerances=tolerances,
        binding=binding,
        tilt_mean_rad=float(tm[design_pose, 0]),
        tilt_std_rad=float(tm[design_pose, 1]),
        tilt_grid_mean_rad=tm[:, 0],
    )


def tilt_worst_pose(maps: AccuracyMaps, columns: np.ndarray, axis: np.ndarray) -> int:
    """Grid index of the largest σ[Δα] for unit errors of ``columns``."""
    tilt, _ = maps.tilt_maps(axis)
    return first_max(grid_norm_moments(tilt[:, :, columns])[:, 1])


def tilt_sensitivities(maps: AccuracyMaps, columns: np.ndarray, axis: np.ndarray, index: int) -> np.ndarray:
    """``ω^α_i = ‖tilt column i‖`` at grid pose ``index`` for ``columns`` [rad per unit]."""
    tilt, _ = maps.tilt_maps(axis)
    return sensitivities(tilt[index][:, columns])


def tilt_moments(maps: AccuracyMaps, sigma: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Mean and σ of Δα at every pose, (m, 2) [rad], for errors ``δ_i ~ N(0, σ_i²)`` and the noise."""
    cov = maps.tilt_covariance(axis, sigma)
    out = np.empty((cov.shape[0], 2))
    for k, c in enumerate(cov):
        lam = np.clip(np.linalg.eigvalsh(c)[::-1], 0.0, None)
        out[k] = norm_moments(lam)
    return out


def joint_covariance(maps: AccuracyMaps, sigma: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Covariance (m, 6, 6) of ``(P error, tilt vector)`` at every pose [m², m·rad, rad²]."""
    s = np.where(np.isfinite(sigma), np.asarray(sigma, dtype=float), 0.0)
    tilt, tilt_noise = maps.tilt_maps(axis)
    L = np.concatenate([maps.position, tilt], axis=1) * s[None, None, :]
    cov = L @ np.swapaxes(L, 1, 2)
    if maps.position_noise.shape[2] and maps.noise_m > 0:
        N = np.concatenate([maps.position_noise, tilt_noise], axis=1)
        cov = cov + maps.noise_m**2 * (N @ np.swapaxes(N, 1, 2))
    return cov


_DRAWS: np.ndarray | None = None


def _draws() -> np.ndarray:
    global _DRAWS
    if _DRAWS is None:
        _DRAWS = np.random.default_rng(JOINT_SEED).standard_normal((6, JOINT_DRAWS))
    return _DRAWS


def joint_reliability(cov: np.ndarray, target_m: float, target_rad: float) -> np.ndarray:
    """``P(‖e‖ ≤ Δλ* and Δα ≤ Δα*)`` at each pose from covariances (m, 6, 6), shape (m,).

    Monte Carlo over :data:`JOINT_DRAWS` fixed draws; standard error :func:`joint_standard_error`.
    """
    lam, vec = np.linalg.eigh(cov)
    root = vec * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]
    x = root @ _draws()  # (m, 6, draws)
    ok = (np.linalg.norm(x[:, :3], axis=1) <= target_m) & (np.linalg.norm(x[:, 3:], axis=1) <= target_rad)
    return ok.mean(axis=1)


def joint_standard_error(r: float) -> float:
    """Standard error of a joint reliability estimate from :data:`JOINT_DRAWS` draws."""
    return math.sqrt(max(r * (1.0 - r), 0.0) / JOINT_DRAWS)
