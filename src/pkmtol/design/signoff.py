"""What a designer signs off, for a finished design: contributions, stack-ups, capability, drawing tolerances.

:func:`sign_off` takes a :class:`~pkmtol.design.job.DesignResult` and evaluates, on the task-space
grid and with the compensation mode's own maps (``result.maps``: ``J``, the post-calibration ``L``
with its noise, or ``J_total``):

* the percent contribution of every toleranced error (and of the tracker noise) to E[Δλ²]
  (:mod:`pkmtol.design.contributions`), and to E[Δα²] when the tilt is reported;
* the stack-up of the drawing tolerances ±t: exact worst case, arithmetic, RSS
  (:mod:`pkmtol.design.stackup`), beside FOSM's ``β √E[Δλ²]`` and the exact Φ(β)-quantile;
* the process capability: Cpk, exact PPM, sigma level (:mod:`pkmtol.design.capability`), of Δλ
  and, with an orientation target, of Δα;
* the drawing callouts (:mod:`pkmtol.design.drawing`).

The design evaluated is the verified one (the ``--method`` design, else FOSM at the design β);
under ``calibrated`` the identified errors keep their manufacturing σ (their columns vanish, so
they add nothing) and the noise enters every covariance. The result is cached per design result.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

import pkmtol.values as values
from pkmtol.design.capability import Capability, capability
from pkmtol.design.contributions import Contributions, contributions
from pkmtol.design.drawing import DrawingTolerance, drawing_tolerances
from pkmtol.design.job import DesignResult
from pkmtol.design.reliability import reliability_fosm
from pkmtol.design.stackup import StackUp, stack_up
from pkmtol.error_model.compensation import AccuracyMaps, mode_maps
from pkmtol.model.drawing import DrawingSettings


@dataclass(frozen=True, eq=False)
class SignOff:
    """The sign-off numbers of a design (SI: m, rad; shares as fractions).

    Attributes:
        sigma: Shape (n_params,): the verified design's σ_i (identified errors at their
            manufacturing σ, the rest 0).
        columns: Indices of the toleranced errors.
        drawing: The drawing convention used.
        tolerance: Shape (n_params,): the drawing tolerance ±t_i = factor · σ_i (nan where not
            toleranced).
        design_index: Grid index of the design point.
        reliability_target: Φ(design β), the R* of the quantiles.
        contributions: Shares of E[Δλ²].
        stackup: Stack-up of ±t for Δλ at every grid pose.
        fosm_m: Shape (m,): FOSM's claim ``β √E[Δλ²]`` at every grid pose [m].
        capability: Cpk, PPM, sigma level and the exact Φ(β)-quantile of Δλ.
        drawings: One drawing callout per toleranced error.
        tilt_contributions: Shares of E[Δα²] (None when the tilt is not reported).
        tilt_design_index: Grid index of the tilt's most sensitive pose.
        tilt_capability: Capability of Δα against Δα* (None without an orientation target).
    """

    sigma: np.ndarray
    columns: np.ndarray
    drawing: DrawingSettings
    tolerance: np.ndarray
    design_index: int
    reliability_target: float
    contributions: Contributions
    stackup: StackUp
    fosm_m: np.ndarray
    capability: Capability
    drawings: list[DrawingTolerance]
    tilt_contributions: Contributions | None = None
    tilt_design_index: int = 0
    tilt_capability: Capability | None = None


def verified_sigma(result: DesignResult) -> np.ndarray:
    """σ_i of the verified design for every parameter (SI; free and untoleranced errors 0)."""
    s = np.zeros(len(result.pset))
    unc = np.asarray(result.uncompensatable, dtype=int)
    verified = (
        result.method_design.sigma
        if result.method_design is not None
        else result.tolerances[unc, result.design_column]
    )
    s[unc] = np.where(np.isfinite(verified), verified, 0.0)
    plan = result.calibration_plan
    if plan is not None and result.mode_classes:
        identified = [i for i, c in enumerate(result.mode_classes) if c == "identified"]
        s[identified] = plan.settings.manufacturing_sigma(result.pset)[identified]
    return s


def result_maps(result: DesignResult) -> AccuracyMaps:
    """The compensation mode's maps on the grid (rebuilt from the grid when the result has none)."""
    return result.maps if result.maps is not None else mode_maps(result.grid, result.compensation)


def tilt_reported(result: DesignResult) -> bool:
    """Whether the reports show the tilt Δα (an orientation target, or a mode other than ideal)."""
    o = result.orientation
    return o is not None and (o.target_rad is not None or result.compensation != "ideal")


_CACHE: weakref.WeakKeyDictionary[DesignResult, SignOff] = weakref.WeakKeyDictionary()


def sign_off(result: DesignResult) -> SignOff:
    """The sign-off numbers of a design (computed once per result; see the module docstring)."""
    values.instance("result", result, DesignResult, "a pkmtol.DesignResult (pkmtol.allocate)")
    cached = _CACHE.get(result)
    if cached is not None:
        return cached
    maps = result_maps(result)
    sigma = verified_sigma(result)
    cols = np.asarray(result.uncompensatable, dtype=int)
    settings = result.drawing
    tol = np.full(len(result.pset), np.nan)
    tol[cols] = settings.factor * sigma[cols]
    worst = int(result.worst_index)
    r_star = float(reliability_fosm(result.design_beta))
    contrib = contributions(maps.position, sigma, cols, worst, maps.position_noise, maps.noise_m)
    cov = maps.position_covariance(sigma)
    cap = capability(cov, result.target_m, r_star)
    axis = result.orientation.axis if result.orientation is not None else None
    out = SignOff(
        sigma=sigma,
        columns=cols,
        drawing=settings,
        tolerance=tol,
        design_index=worst,
        reliability_target=r_star,
        contributions=contrib,
        stackup=stack_up(maps.position[:, :, cols], tol[cols]),
        fosm_m=result.design_beta * np.sqrt(contrib.mean_square),
        capability=cap,
        drawings=drawing_tolerances(result.mechanism, result.pset, cols, sigma, settings, axis),
    )
    if tilt_reported(result):
        o = result.orientation
        assert o is not None
        tilt, tilt_noise = maps.tilt_maps(o.axis)
        w_a = int(o.worst_index)
        t_contrib = contributions(tilt, sigma, cols, w_a, tilt_noise, maps.noise_m)
        t_cap = None
        if o.target_rad is not None:
            t_cap = capability(maps.tilt_covariance(o.axis, sigma), o.target_rad)
        out = SignOff(
            **{f: getattr(out, f) for f in out.__dataclass_fields__ if not f.startswith("tilt")},
            tilt_contributions=t_contrib,
            tilt_design_index=w_a,
            tilt_capability=t_cap,
        )
    _CACHE[result] = out
    return out
