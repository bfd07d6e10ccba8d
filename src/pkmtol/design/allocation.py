"""The tolerances stage of the main job: FOSM at the design pose, above the noise floor, position and tilt.

Each allocated parameter's sensitivity ``ω_i = ‖J[:, i]‖`` is taken at the design pose (or, where it
vanishes there, at its own most sensitive grid pose); the equal-effect tolerances of the β series
follow from Eq. 20 with the calibration's noise as a fixed variance. With an orientation target the
tilt of the tool axis gets its own FOSM tolerances and each parameter keeps the smaller one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pkmtol.design.fosm import allocation_sensitivity, fosm_tolerances, tolerances_above_floor
from pkmtol.design.methods import MethodChoice, MethodDesign, method_design_for
from pkmtol.design.orientation import tilt_sensitivities, tilt_worst_pose
from pkmtol.error_model.accuracy import sensitivities
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class TiltTolerances:
    """The tilt's own allocation (with an orientation target).

    Attributes:
        worst_index: Grid index of the largest σ[Δα] for unit errors.
        sensitivity: Shape (n_params,): tilt sensitivities there [rad per unit].
        tolerances: Shape (n_params, len(betas)): the tilt's FOSM tolerances (NaN: not toleranced).
        binding: Shape (n_params,): True where the tilt's tolerance is the smaller.
    """

    worst_index: int
    sensitivity: np.ndarray
    tolerances: np.ndarray
    binding: np.ndarray


@dataclass(frozen=True, eq=False)
class Tolerances:
    """The FOSM tolerances of the β series at the design pose (SI units).

    Attributes:
        sensitivity: Shape (n_params,): ``‖J[:, i]‖`` at the design point (0 if not allocated).
        sensitivity_uncompensated: Shape (n_params,): ``‖J_total[:, i]‖`` at the design point.
        fallback_pose: Shape (n_params,): the grid pose a zero sensitivity was taken from (−1: none).
        noise_variance_m2: ``σ_m² ‖N‖²_F`` at the design point [m²] (0 without a calibration).
        tolerances: Shape (n_params, len(betas)): FOSM tolerances (NaN for parameters not allocated).
        tilt: The tilt's allocation (None without an orientation target).
    """

    sensitivity: np.ndarray
    sensitivity_uncompensated: np.ndarray
    fallback_pose: np.ndarray
    noise_variance_m2: float
    tolerances: np.ndarray
    tilt: TiltTolerances | None

    def tilt_allocation(self) -> tuple[int, np.ndarray, np.ndarray, np.ndarray] | None:
        """The tilt's ``(worst pose, sensitivity, tolerances, binding)``, or None without a target."""
        t = self.tilt
        return None if t is None else (t.worst_index, t.sensitivity, t.tolerances, t.binding)


def noise_variance(maps: AccuracyMaps, pose: int) -> float:
    """``σ_m² ‖N‖²_F`` of P at grid pose ``pose`` [m²] (0 without a calibration)."""
    if not maps.position_noise.shape[2]:
        return 0.0
    return float(maps.noise_m**2 * np.sum(maps.position_noise[pose] ** 2))


def total_variance(maps: AccuracyMaps, unc: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """``Σ_i ‖J_k[:, i]‖² σ_i² + σ_m² ‖N_k‖²_F`` at every grid pose k (m,) [m²]: E[Δλ²] of a design."""
    s = np.where(np.isfinite(sigma), sigma, 0.0)
    var = np.einsum("kri,i->k", maps.position[:, :, unc] ** 2, s**2)
    if maps.position_noise.shape[2]:
        var = var + maps.noise_m**2 * np.sum(maps.position_noise**2, axis=(1, 2))
    return var


#: Most passes of :func:`noise_design_pose`.
DESIGN_POSE_PASSES = 20


def noise_design_pose(
    maps: AccuracyMaps, unc: np.ndarray, start: int, target_m: float, design_beta: float
) -> int:
    """The design pose with the tracker noise included: where E[Δλ²] of the design is largest.

    After a calibration the unit-error σ misses the noise term ``σ_m² ‖N‖²``, which grows towards
    the rim the plan does not reach. From ``start`` (the unit-error pose), design FOSM tolerances
    at the pose and move to the grid pose where that design's total variance
    (:func:`total_variance`, tolerance and noise parts) is largest; repeat until the pose stays.
    When the passes come back to a pose already visited (or after :data:`DESIGN_POSE_PASSES`),
    the answer is the visited pose whose design has the smallest largest total variance over the
    grid (the one-pose design that misses least elsewhere). A pose whose noise alone misses the
    target is returned as it is: the tolerances stage then names the noise floor.
    """
    seen: dict[int, float] = {}
    pose = start
    for _ in range(DESIGN_POSE_PASSES):
        omega, _ = allocation_sensitivity(maps.position, unc, pose)
        sigma = fosm_tolerances(omega, target_m, np.array([design_beta]), noise_variance(maps, pose))[:, 0]
        if np.isnan(sigma).any():
            return pose
        var = total_variance(maps, unc, sigma)
        seen[pose] = float(var.max())
        nxt = int(np.argmax(var))
        if nxt == pose or nxt in seen:
            break
        pose = nxt
    return min(seen, key=lambda k: (seen[k], k))


def fosm_stage(
    maps: AccuracyMaps,
    J_total: np.ndarray,
    unc: np.ndarray,
    worst: int,
    target_m: float,
    betas: tuple[float, ...],
    design_beta: float,
    noise: tuple[float, int] | None = None,
    tilt: tuple[np.ndarray, float] | None = None,
) -> Tolerances:
    """The tolerances stage: FOSM tolerances of the columns ``unc`` at design pose ``worst``.

    Args:
        maps: The compensation mode's maps on the grid.
        J_total: Shape (m, 3, n_params): the uncompensated maps on the grid.
        unc: Indices of the toleranced parameters.
        worst: Grid index of the design pose.
        target_m: Δλ* [m].
        betas: β series.
        design_beta: The design β (its NoiseFloorError).
        noise: ``(tracker σ [m], plan poses)`` of a calibration (its NoiseFloorError), else None.
        tilt: ``(tool axis, Δα* [rad])`` with an orientation target, else None.

    Raises:
        NoiseFloorError: the tracker noise alone misses Δλ* (or Δα*) at the design β.
    """
    n_par = J_total.shape[2]
    sens = np.zeros(n_par)
    sens[unc] = sensitivities(maps.position[worst][:, unc])
    omega, fb = allocation_sensitivity(maps.position, unc, worst)
    fallback = np.full(n_par, -1, dtype=int)
    fallback[unc] = fb
    noise_var = noise_variance(maps, worst)
    kw = {"n_par": n_par, "unc": unc, "betas": betas, "design_beta": design_beta, "noise": noise}
    tol = tolerances_above_floor(omega, target_m, noise_var, "Δλ at P", **kw)
    tilt_tol = None
    if tilt is not None:
        axis, alpha_target = tilt
        w_a = tilt_worst_pose(maps, unc, axis)
        tilt_map, tilt_noise = maps.tilt_maps(axis)
        om_a, _ = allocation_sensitivity(tilt_map, unc, w_a)
        tn_var = float(maps.noise_m**2 * np.sum(tilt_noise[w_a] ** 2)) if tilt_noise.shape[2] else 0.0
        tol_a = tolerances_above_floor(om_a, alpha_target, tn_var, "the tilt of the tool axis", **kw)
        design_col = int(np.argmin(np.abs(np.asarray(betas) - design_beta)))
        binding = np.zeros(n_par, dtype=bool)
        binding[unc] = tol_a[unc, design_col] < tol[unc, design_col]
        tol[unc] = np.fmin(tol[unc], tol_a[unc])
        sens_a = np.zeros(n_par)
        sens_a[unc] = tilt_sensitivities(maps, unc, axis, w_a)
        tilt_tol = TiltTolerances(worst_index=w_a, sensitivity=sens_a, tolerances=tol_a, binding=binding)
    return Tolerances(
        sensitivity=sens,
        sensitivity_uncompensated=sensitivities(J_total[worst]),
        fallback_pose=fallback,
        noise_variance_m2=noise_var,
        tolerances=tol,
        tilt=tilt_tol,
    )


@dataclass(frozen=True, eq=False)
class DesignTolerances:
    """The tolerances of a design: the FOSM series and, for ``exact`` / ``cost``, the method's design.

    Attributes:
        fosm: The FOSM tolerances of the β series at the design pose.
        method_design: The ``exact`` or ``cost`` design (None for ``fosm``).
        sigma: Shape (len(columns),): the design-β tolerances of the toleranced parameters
            (the method's when there is one) [SI; inf: free].
    """

    fosm: Tolerances
    method_design: MethodDesign | None
    sigma: np.ndarray


def design_tolerances(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep,
    maps: AccuracyMaps,
    unc: np.ndarray,
    worst: int,
    target_m: float,
    betas: tuple[float, ...],
    design_beta: float,
    choice: MethodChoice,
    noise: tuple[float, int] | None = None,
    tilt: tuple[np.ndarray, float] | None = None,
    clock: Callable[..., Any] | None = None,
) -> DesignTolerances:
    """The tolerances stage of every design (``pkmtol allocate`` and each ``pkmtol sweep`` variant).

    FOSM over the β series (:func:`fosm_stage`), then the method of ``choice`` (``exact`` or
    ``cost``, :func:`pkmtol.design.methods.method_design_for`) from the design-β column.
    ``clock(name, stage, *args)`` (a :class:`pkmtol.design.job.StageClock`) times each step.
    """
    run = clock if clock is not None else _untimed
    fosm = run(
        "allocation", fosm_stage, maps, grid.J_total, unc, worst, target_m, betas, design_beta, noise, tilt
    )
    design_col = int(np.argmin(np.abs(np.asarray(betas) - design_beta)))
    sigma = fosm.tolerances[unc, design_col]
    method_design = None
    if choice.method != "fosm":
        method_design = run(
            f"{choice.method} design",
            method_design_for,
            mechanism,
            pset,
            grid,
            unc,
            sigma,
            target_m,
            design_beta,
            worst,
            choice,
            maps=maps,
            orientation=tilt,
        )
        sigma = method_design.sigma
    return DesignTolerances(fosm=fosm, method_design=method_design, sigma=sigma)


def _untimed(name: str | None, stage: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    return stage(*args, **kwargs)
