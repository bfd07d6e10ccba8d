"""The ``exact`` and ``cost`` designs of the toleranced errors at R* = Φ(design β), in any compensation mode.

``exact`` keeps the equal-effect shape and scales it so that the exact reliability meets R* (at the
worst pose, at every grid pose, or on average); ``cost`` minimises the cost model under
``R ≥ R*`` at every grid pose. With a calibration the tracker noise enters as a fixed covariance;
with an orientation target, ``exact`` scales to the joint reliability
``P(Δλ ≤ Δλ* and Δα ≤ Δα*)`` (:mod:`pkmtol.design.orientation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

import pkmtol.values as values
from pkmtol.design.cost import cost_model, cost_optimal
from pkmtol.design.exact import bracket_log_scale, criterion_value, scale_design
from pkmtol.design.orientation import joint_covariance, joint_reliability
from pkmtol.design.reliability import exact_reliability_many, reliability_fosm
from pkmtol.design.verification import check_sigma
from pkmtol.error_model.compensation import AccuracyMaps, mode_maps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.exceptions import InvalidRequestError
from pkmtol.model.mechanism import Mechanism


class MethodChoice(Protocol):
    """What :func:`method_design_for` reads of the options (``DesignOptions`` has both)."""

    @property
    def method(self) -> str:
        """``exact`` or ``cost``."""

    @property
    def criterion(self) -> str:
        """``worst``, ``every`` or ``average``."""


@dataclass(frozen=True, eq=False)
class MethodDesign:
    """A design by the ``exact`` or ``cost`` method (tolerances of the toleranced parameters, SI).

    Attributes:
        method: ``exact`` or ``cost``.
        criterion: ``worst`` / ``every`` / ``average`` (``every`` for cost).
        target_reliability: R* = Φ(design β).
        sigma: Tolerances (len(uncompensatable),) [SI].
        reliability: Exact Gaussian R at each grid pose (the joint reliability with an orientation
            target).
        cost: Total cost of ``sigma`` under the cost model.
        reference_sigma: The equal-effect design scaled to the same true R (min over the grid).
        reference_cost: Its cost.
        joint: Whether ``reliability`` is the joint position and tilt reliability (an orientation
            target).
    """

    method: str
    criterion: str
    target_reliability: float
    sigma: np.ndarray
    reliability: np.ndarray
    cost: float
    reference_sigma: np.ndarray
    reference_cost: float
    joint: bool = False


def method_design_for(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep,
    unc: np.ndarray,
    fosm_sigma: np.ndarray,
    target: float,
    design_beta: float,
    worst: int,
    opt: MethodChoice,
    maps: AccuracyMaps | None = None,
    orientation: tuple[np.ndarray, float] | None = None,
) -> MethodDesign:
    """The ``exact`` or ``cost`` design of the toleranced errors at R* = Φ(design β).

    Args:
        mechanism: The mechanism (its ``[cost]`` table feeds the cost model).
        pset: Its parameter set.
        grid: The task-space grid sweep.
        unc: Indices of the toleranced parameters.
        fosm_sigma: Their FOSM tolerances at the design β [SI] (the equal-effect shape).
        target: Δλ* [m].
        design_beta: β; R* = Φ(β).
        worst: Grid index of the design point.
        opt: ``opt.method`` (``exact`` or ``cost``) and ``opt.criterion``.
        maps: The compensation mode's maps on the grid (default: the paper's ideal ones).
        orientation: ``(tool axis, Δα* [rad])`` to meet the orientation target too (``exact``).

    Raises:
        InvalidRequestError: unknown method, ``cost`` with an orientation target, or a target
            no tolerance reaches.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism")
    values.instance("pset", pset, ParameterSet, "a ParameterSet (pkmtol.parameter_set)")
    values.instance("grid", grid, Sweep, "a pkmtol.Sweep (pkmtol.sweep)")
    unc = values.indices("unc", unc, len(pset))
    fosm_sigma = check_sigma(fosm_sigma, len(unc))
    target = values.length_m("target", target)
    design_beta = values.number("design_beta", design_beta, positive=True)
    worst = values.index("worst", worst, len(grid.poses))
    for field_name in ("method", "criterion"):
        if not isinstance(getattr(opt, field_name, None), str):
            raise values.InvalidArgumentError("opt", opt, "expected DesignOptions (method and criterion)")
    values.optional(
        values.instance, "maps", maps, AccuracyMaps, "AccuracyMaps (error_model.compensation) or None"
    )
    if orientation is not None:
        if not isinstance(orientation, tuple) or len(orientation) != 2:
            raise values.InvalidArgumentError(
                "orientation", orientation, "expected (tool axis (3,), Δα* [rad])"
            )
        orientation = (
            values.vector("orientation[0]", orientation[0], 3),
            values.number("orientation[1]", orientation[1], positive=True),
        )
    maps = maps if maps is not None else mode_maps(grid, "ideal")
    r_star = float(reliability_fosm(design_beta))
    J = maps.position[:, :, unc]
    extra = None
    if maps.position_noise.shape[2] and maps.noise_m > 0:
        N = maps.position_noise
        extra = maps.noise_m**2 * (N @ np.swapaxes(N, 1, 2))
    model = cost_model([pset.parameters[i] for i in unc], mechanism.extra.get("cost"))
    if not np.asarray(unc).size:
        return _nothing_toleranced(opt, maps, target, r_star, extra, orientation)
    if orientation is not None:
        if opt.method == "cost":
            raise InvalidRequestError(
                "--method cost with an orientation target is not available: use --method exact "
                "(equal-effect shape scaled to the joint reliability) or fosm"
            )
        axis, target_rad = orientation
        sub = maps.subset(unc)
        reference = _scale_joint(sub, fosm_sigma, target, target_rad, axis, r_star, "every", worst)
        sigma, rel = _scale_joint(sub, fosm_sigma, target, target_rad, axis, r_star, opt.criterion, worst)
        criterion = opt.criterion
    else:
        ref = scale_design(J, fosm_sigma, target, r_star, "every", worst, extra)
        reference = (ref.sigma, ref.reliability)
        if opt.method == "exact":
            d = scale_design(J, fosm_sigma, target, r_star, opt.criterion, worst, extra)
            sigma, rel, criterion = d.sigma, d.reliability, opt.criterion
        elif opt.method == "cost":
            c = cost_optimal(
                J, model, target, r_star, ref.sigma, [pset.names[i] for i in unc], extra_cov=extra
            )
            sigma, rel, criterion = c.sigma, c.reliability, "every"
        else:
            raise InvalidRequestError(f"unknown method {opt.method!r}; use fosm, exact or cost")
    return MethodDesign(
        method=opt.method,
        criterion=criterion,
        target_reliability=r_star,
        sigma=sigma,
        reliability=rel,
        cost=model.cost(sigma),
        reference_sigma=reference[0],
        reference_cost=model.cost(reference[0]),
        joint=orientation is not None,
    )


def _nothing_toleranced(
    opt: MethodChoice,
    maps: AccuracyMaps,
    target: float,
    r_star: float,
    extra: np.ndarray | None,
    orientation: tuple[np.ndarray, float] | None,
) -> MethodDesign:
    """The design with no toleranced parameter (a calibration identifies every error): nothing to scale.

    Its reliability is the noise's alone; when that misses R* somewhere, no tolerance can help.
    """
    m = len(maps.position)
    if orientation is not None:
        rel = joint_reliability(
            joint_covariance(maps, np.zeros(maps.position.shape[2]), orientation[0]), target, orientation[1]
        )
    elif extra is not None:
        rel = exact_reliability_many(extra, target)[0]
    else:
        rel = np.ones(m)
    if rel.min() < r_star:
        raise InvalidRequestError(
            f"nothing is left to tolerance, and the tracker noise alone gives R = {100 * rel.min():.2f} % "
            f"< {100 * r_star:.2f} % at grid pose {int(np.argmin(rel))}: measure more poses, use a "
            "more precise tracker, or relax Δλ* or β"
        )
    empty = np.zeros(0)
    criterion = "every" if opt.method == "cost" else opt.criterion
    return MethodDesign(
        opt.method, criterion, r_star, empty, rel, 0.0, empty, 0.0, joint=orientation is not None
    )


def _scale_joint(
    maps: AccuracyMaps,
    shape: np.ndarray,
    target_m: float,
    target_rad: float,
    axis: np.ndarray,
    r_star: float,
    criterion: str,
    worst: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Scale ``shape`` so that the criterion's joint reliability equals ``r_star``: (σ, R per pose)."""
    finite = np.isfinite(shape)
    base = np.where(finite, shape, 0.0)
    sel = maps if criterion != "worst" else _one_pose(maps, worst)
    w_idx = worst if criterion != "worst" else 0

    def rel(s: float, m: AccuracyMaps) -> np.ndarray:
        return joint_reliability(joint_covariance(m, base * s, axis), target_m, target_rad)

    def excess(log_s: float) -> float:
        return criterion_value(rel(math.exp(log_s), sel), criterion, w_idx) - r_star

    lo, hi = bracket_log_scale(
        excess,
        40.0,
        "no scale of the tolerances meets both the position and the orientation target: what "
        "no tolerance changes (the calibration's noise) already exceeds one of them",
        "the design meets both targets at any scale: nothing depends on it",
    )
    from scipy import optimize  # only the joint-target designs find this root; keep it out of start-up

    s = math.exp(optimize.brentq(excess, lo, hi, xtol=1e-10, rtol=1e-10))
    return np.where(finite, shape * s, np.inf), rel(s, maps)


def _one_pose(maps: AccuracyMaps, k: int) -> AccuracyMaps:
    return AccuracyMaps(
        mode=maps.mode,
        position=maps.position[k : k + 1],
        rotation=maps.rotation[k : k + 1],
        position_noise=maps.position_noise[k : k + 1],
        rotation_noise=maps.rotation_noise[k : k + 1],
        noise_m=maps.noise_m,
        rotations=maps.rotations[k : k + 1],
    )
