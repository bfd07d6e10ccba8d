"""The main job: from a mechanism to a verified tolerance table (paper §3–4.5, end to end).

:func:`allocate` is a pipeline of named stages, each a function of the module that owns its
concept, returning a small frozen record; :class:`StageClock` times each one where it is called:

1. error model on the grid (:func:`pkmtol.design.modes.grid_model`): the task-space grid, classes;
2. mode maps (:func:`pkmtol.design.modes.mode_stage`): the maps and toleranced set of the mode;
3. design pose (:func:`pkmtol.design.pose_search.search_sensitive_pose`);
4. tolerances (:func:`pkmtol.design.allocation.fosm_stage`): FOSM over the β series;
5. verification poses and claims (:func:`pkmtol.design.mode_verification.verification_poses`,
   :func:`pkmtol.design.exact.claims_stage`): claimed Φ(β) against the true reliability;
6. method design (:func:`pkmtol.design.methods.method_design_for`): ``exact`` or ``cost``;
7. verification (:func:`pkmtol.design.mode_verification.verify_design`);
8. traditional method (:func:`pkmtol.design.fosm.traditional_design`);
9. orientation (:func:`pkmtol.design.orientation.orientation_stage`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from pkmtol.calibration.plan import CalibrationPlan
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.design.allocation import design_tolerances, noise_design_pose
from pkmtol.design.budget import check_memory
from pkmtol.design.claim import Claim, Miss, design_claim, verification_misses
from pkmtol.design.exact import CRITERIA, ClaimRow, claims_stage
from pkmtol.design.fosm import Traditional, check_design, traditional_design
from pkmtol.design.methods import MethodDesign
from pkmtol.design.mode_verification import (
    CALIBRATED_EXACT_SAMPLES,
    exact_cap,
    verification_poses,
    verify_design,
)
from pkmtol.design.modes import ModeSetup, grid_model, mode_stage
from pkmtol.design.options import DEFAULT_CRITERION, DEFAULT_METHOD, check_options
from pkmtol.design.orientation import OrientationDesign, orientation_stage
from pkmtol.design.pose_search import PoseSearch, search_sensitive_pose
from pkmtol.design.reliability import reliability_fosm
from pkmtol.design.verification import Verification
from pkmtol.error_model.compensation import COMPENSATIONS, AccuracyMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.task import machine_parameter_set
from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError
from pkmtol.executor import Executor
from pkmtol.model.drawing import DrawingSettings
from pkmtol.model.mechanism import Mechanism

__all__ = [
    "CALIBRATED_EXACT_SAMPLES",
    "DesignOptions",
    "DesignResult",
    "StageClock",
    "Traditional",
    "allocate",
]

T = TypeVar("T")


@dataclass(frozen=True)
class DesignOptions:
    """Options of the main job (defaults are the paper's design case).

    Attributes:
        target_m: Δλ* [m] (None: the mechanism's).
        betas: β series (None: the mechanism's).
        design_beta: β whose tolerances are verified (None: the mechanism's).
        parameter_set: ``"dh"`` or ``"urdf"`` (None: dh when every limb has a D–H table).
        samples: Monte Carlo samples of the pose search and of each linear verification.
        verification_poses: Distinct random task-space poses of the verification (sample ``s``
            uses pose ``s mod verification_poses``).
        exact_samples: Exact-kinematics verification subsample size per distribution.
        seed: Random seed (same seed, same numbers).
        progress: Show progress bars.
        method: ``fosm`` (the paper's Eq. 20), ``exact`` (equal-effect shape scaled so that the
            exact Gaussian reliability equals Φ(design β)) or ``cost`` (cost-optimal tolerances
            with exact reliability ≥ Φ(design β) at every grid pose).
        criterion: For ``exact``: where R* must hold — ``worst`` pose, ``every`` grid pose, or
            on ``average`` over the grid.
        claim_poses: Random task-space poses over which the claimed-vs-true table averages the
            exact reliability (the first of the verification poses).
        compensation: ``ideal`` (the paper's Eq. 25), ``calibrated`` (a least-squares calibration
            by ``calibration``) or ``none`` (the traditional method).
        calibration: The calibration plan's settings for ``calibrated`` (None: the mechanism's
            ``[calibration]`` table, else the defaults).
        orientation_target_rad: Δα*, the largest tilt of the tool axis [rad] (None: the
            mechanism's ``[design] orientation_target``, else no orientation target).
        tool_axis: The tool axis in the platform frame (None: ``[design] tool_axis``, else z).
        executor: Where the exact verification (ideal mode) and the claimed-vs-true
            reliabilities run (None: serial); the numbers do not depend on it.
        drawing: The drawing convention (±t = k·σ or √3·σ), nominal sizes and feature lengths
            (None: the mechanism's ``[drawing]`` table, else the defaults).
    """

    target_m: float | None = None
    betas: tuple[float, ...] | None = None
    design_beta: float | None = None
    parameter_set: str | None = None
    samples: int = 10_000
    verification_poses: int = 2_000
    exact_samples: int = 1_000
    seed: int = 0
    progress: bool = False
    method: str = DEFAULT_METHOD
    criterion: str = DEFAULT_CRITERION
    claim_poses: int = 300
    compensation: str = "ideal"
    calibration: CalibrationSettings | None = None
    orientation_target_rad: float | None = None
    tool_axis: tuple[float, float, float] | None = None
    executor: Executor | None = None
    drawing: DrawingSettings | None = None

    def __post_init__(self) -> None:
        """Check every field (raises InvalidArgumentError naming it); betas become a tuple."""
        check_options(self)


@dataclass(frozen=True, eq=False)
class DesignResult:
    """Everything the main job computed (SI units throughout).

    Attributes:
        mechanism: The mechanism.
        pset: The parameter set.
        target_m: Δλ* [m].
        betas: β series.
        design_beta: β of the verified design.
        reliability_fosm: ``Φ(β)`` per β.
        classes: Class of each parameter.
        grid: The task-space grid sweep.
        search: Sensitive-pose search result.
        worst_index: Grid index of the design point (most sensitive).
        uncompensatable: Indices of the allocated parameters (η_c under ``ideal``; the
            toleranced ones under ``calibrated`` and ``none``).
        sensitivity: Shape (n_params,): ``‖J[:, i]‖`` at the design point (0 if not allocated);
            ``J`` is the compensation mode's map (``L`` under ``calibrated``).
        sensitivity_uncompensated: Shape (n_params,): ``‖J_total[:, i]‖`` at the design point.
        tolerances: Shape (n_params, len(betas)): FOSM tolerances (nan for parameters not allocated).
        verification: Per distribution, the verification of the design-β tolerances.
        traditional: The traditional method.
        claims: Claimed Φ(β) vs true reliability of each FOSM design (β series).
        method_design: The ``exact`` or ``cost`` design when asked for (None for ``fosm``); the
            verification then belongs to it.
        timings_s: Wall time of each stage [s].
        compensation: The compensation mode.
        mode_classes: Each parameter's class in that mode (``ideal``: the error model's classes;
            ``calibrated``: identified / toleranced / absorbed; ``none``: toleranced / absorbed).
        maps: The mode's accuracy maps on the grid.
        calibration_plan: The calibration plan (``calibrated`` only).
        noise_variance_m2: ``σ_m² ‖N‖²_F`` at the design point: the variance of Δλ's linear
            response that no tolerance changes [m²] (0 without a calibration).
        fallback_pose: Shape (n_params,): for an allocated parameter with no effect at the design
            point, the grid index of its own most sensitive pose, from which its sensitivity was
            taken (docs/theory.md, "No error left untoleranced"); −1 otherwise.
        orientation: The tilt of the tool axis: sensitivities, its own FOSM tolerances when it has
            a target, and its statistics for the verified design.
        drawing: How the tolerances go on a drawing (:mod:`pkmtol.design.signoff` reports them).
        claim: What the verified design promises and where, with its exact reliability of the
            linear model at every grid pose (:mod:`pkmtol.design.claim`).
        claim_misses: The Gaussian verification rows that fall short of the claim beyond their
            95 % interval (empty: the verification agrees).
        exact_samples_cap: The exact verification samples the mode ran when it capped
            ``exact_samples`` (None: not capped).
        option_caps: Each option the run used less of than asked: ``(option, asked, used, why)``
            (the command prints one line per cap).
    """

    mechanism: Mechanism
    pset: ParameterSet
    target_m: float
    betas: tuple[float, ...]
    design_beta: float
    reliability_fosm: np.ndarray
    classes: list[str]
    grid: Sweep
    search: PoseSearch
    worst_index: int
    uncompensatable: np.ndarray
    sensitivity: np.ndarray
    sensitivity_uncompensated: np.ndarray
    tolerances: np.ndarray
    verification: dict[str, Verification]
    traditional: Traditional
    claims: list[ClaimRow] = field(default_factory=list)
    method_design: MethodDesign | None = None
    timings_s: dict[str, float] = field(default_factory=dict)
    compensation: str = "ideal"
    mode_classes: list[str] = field(default_factory=list)
    maps: AccuracyMaps | None = None
    calibration_plan: CalibrationPlan | None = None
    noise_variance_m2: float = 0.0
    fallback_pose: np.ndarray | None = None
    orientation: OrientationDesign | None = None
    drawing: DrawingSettings = field(default_factory=DrawingSettings)
    claim: Claim | None = None
    claim_misses: list[Miss] = field(default_factory=list)
    exact_samples_cap: int | None = None
    option_caps: tuple[tuple[str, int, int, str], ...] = ()

    @property
    def worst_point_m(self) -> np.ndarray:
        """Design point (most error-sensitive position of P) in K, shape (3,) [m]."""
        return self.grid.points_m[self.worst_index]

    @property
    def design_column(self) -> int:
        """Column of ``tolerances`` that belongs to the design β."""
        return int(np.argmin(np.abs(np.asarray(self.betas) - self.design_beta)))


def _check_options(mechanism: Mechanism, opt: DesignOptions) -> tuple[float, tuple[float, ...], float]:
    """Validated ``(Δλ*, β series, design β)``; raises InvalidRequestError naming the culprit."""
    target = mechanism.target_m if opt.target_m is None else opt.target_m
    betas = tuple(mechanism.betas if opt.betas is None else opt.betas)
    design_beta = mechanism.design_beta if opt.design_beta is None else opt.design_beta
    check_design(target, list(betas) + [design_beta])
    if design_beta not in betas:
        betas = tuple(sorted(set(betas) | {design_beta}))
    for name, value, low in (
        ("samples", opt.samples, 1),
        ("verification poses", opt.verification_poses, 1),
        ("exact samples", opt.exact_samples, 0),
    ):
        if int(value) != value or value < low:
            raise InvalidRequestError(f"{name} must be an integer ≥ {low}, got {value}")
    if opt.method not in ("fosm", "exact", "cost"):
        raise InvalidRequestError(f"unknown method {opt.method!r}; use fosm, exact or cost")
    if opt.criterion not in CRITERIA:
        raise InvalidRequestError(f"unknown criterion {opt.criterion!r}; use {', '.join(CRITERIA)}")
    if opt.compensation not in COMPENSATIONS:
        raise InvalidRequestError(
            f"unknown compensation {opt.compensation!r}; use one of {', '.join(COMPENSATIONS)}"
        )
    return target, betas, design_beta


def _orientation_inputs(mechanism: Mechanism, opt: DesignOptions) -> tuple[np.ndarray, float | None]:
    """The tool axis (unit, platform frame) and Δα* [rad] (None: no target)."""
    design = dict(mechanism.extra.get("design") or {})
    axis = np.asarray(
        opt.tool_axis if opt.tool_axis is not None else design.get("tool_axis", (0.0, 0.0, 1.0)), float
    )
    if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
        raise InvalidRequestError(
            f"the tool axis must be a non-zero [x, y, z] in the platform frame, got {axis.tolist()}"
        )
    target = (
        opt.orientation_target_rad
        if opt.orientation_target_rad is not None
        else design.get("orientation_target_rad")
    )
    if target is not None and (not np.isfinite(target) or target <= 0):
        raise InvalidRequestError(f"the orientation target Δα* must be positive, got {target!r} rad")
    return axis / np.linalg.norm(axis), None if target is None else float(target)


def allocate(mechanism: Mechanism, options: DesignOptions | None = None) -> DesignResult:
    """Run the main job on a mechanism.

    Raises:
        InvalidArgumentError: ``mechanism`` or ``options`` of the wrong type.
        ResourceLimitError: the run would not fit in memory (:mod:`pkmtol.design.budget`).
        InvalidRequestError: non-positive target, β, or sample counts; unknown options.
        NoiseFloorError: under ``calibrated``, the tracker noise alone exceeds Δλ* at the design β.
        pkmtol.exceptions.KinematicsError: a task-space point is unreachable or singular.
    """
    if not isinstance(mechanism, Mechanism):
        raise InvalidArgumentError(
            "mechanism", mechanism, "expected a pkmtol.Mechanism (load_mechanism, from_models)"
        )
    if options is not None and not isinstance(options, DesignOptions):
        raise InvalidArgumentError(
            "options", options, "expected a pkmtol.DesignOptions, e.g. DesignOptions(samples=2000)"
        )
    opt = options or DesignOptions()
    check_memory(mechanism, opt)  # refuse up front what would not fit (ResourceLimitError)
    target, betas, design_beta = _check_options(mechanism, opt)
    axis, alpha_target = _orientation_inputs(mechanism, opt)
    tilt = None if alpha_target is None else (axis, alpha_target)
    mode = opt.compensation
    clock = StageClock()
    rng = np.random.default_rng(opt.seed)
    pset = machine_parameter_set(mechanism, opt.parameter_set)  # a hybrid's: with its tool's

    # one line per stage, so that the pipeline reads top to bottom
    # fmt: off
    model = clock("error model on grid", grid_model, mechanism, pset, opt.progress)
    grid, chain = model.grid, model.chain
    maps_name = {"ideal": None, "calibrated": "calibration plan and maps", "none": "maps"}[mode]
    setup = clock(maps_name, mode_stage, mechanism, pset, model, mode, opt.calibration, target, design_beta,
                  None if tilt is None else axis)
    unc, maps = setup.columns, setup.grid_maps
    search = clock("sensitive-pose search", search_sensitive_pose, maps.position[:, :, unc], opt.samples, rng)
    worst = search.worst_index_analytic
    if setup.plan is not None:  # the design pose with the tracker noise σ_m² ‖N‖² included
        worst = clock("design pose", noise_design_pose, maps, unc, worst, target, design_beta)
    noise = None if setup.plan is None else (setup.plan.settings.noise_m, setup.plan.poses)
    tols = design_tolerances(mechanism, pset, grid, maps, unc, worst, target, betas, design_beta, opt, noise,
                             tilt, clock)  # FOSM ("allocation"), then the method ("<method> design")
    poses = clock("verification poses", verification_poses, mechanism, pset, grid, setup, chain,
                  min(opt.verification_poses, opt.samples), rng, opt.progress)
    claims = clock("claimed vs true reliability", claims_stage, maps, poses.maps, worst, unc,
                   tols.fosm.tolerances, betas, target, opt.samples, rng, opt.claim_poses, opt.executor)
    ver = clock("verification", verify_design, mechanism, pset, setup, poses, chain, tols.sigma, target,
                opt.samples, opt.exact_samples, rng, (axis, alpha_target), opt.progress, opt.executor)
    traditional = clock("traditional method", traditional_design, grid.J_total, model.classes, worst, target,
                        design_beta)
    claim = clock("claim", design_claim, maps, unc, tols.sigma, target, design_beta, worst, opt.method,
                  opt.criterion, tols.method_design)
    od = clock(None, orientation_stage, maps, unc, _sigma_full(pset, setup, tols.sigma), axis, alpha_target,
               worst, tols.fosm.tilt_allocation())
    # fmt: on
    fosm, tol, method_design = tols.fosm, tols.fosm.tolerances, tols.method_design
    return DesignResult(
        mechanism=mechanism,
        pset=pset,
        target_m=target,
        betas=betas,
        design_beta=design_beta,
        reliability_fosm=reliability_fosm(np.array(betas)),
        classes=model.classes,
        grid=grid,
        search=search,
        worst_index=worst,
        uncompensatable=unc,
        sensitivity=fosm.sensitivity,
        sensitivity_uncompensated=fosm.sensitivity_uncompensated,
        tolerances=tol,
        verification=ver,
        traditional=traditional,
        claims=claims,
        method_design=method_design,
        timings_s=clock.timings_s,
        compensation=mode,
        mode_classes=setup.classes,
        maps=maps,
        calibration_plan=setup.plan,
        noise_variance_m2=fosm.noise_variance_m2,
        fallback_pose=fosm.fallback_pose,
        orientation=od,
        drawing=opt.drawing or mechanism.extra.get("drawing") or DrawingSettings(),
        claim=claim,
        claim_misses=verification_misses(ver, claim.claimed),
        exact_samples_cap=exact_cap(mode, opt.exact_samples),
        option_caps=_option_caps(opt),
    )


def _sigma_full(pset: ParameterSet, setup: ModeSetup, sigma: np.ndarray) -> np.ndarray:
    """Every parameter's σ in the verified design.

    ``sigma`` on the toleranced ones, the background (identified) ones at their manufacturing σ,
    0 elsewhere (free ones too).
    """
    full = np.zeros(len(pset))
    full[setup.columns] = np.where(np.isfinite(sigma), sigma, 0.0)
    background = setup.background_sigma(pset)
    if background is not None:
        full[background[0]] = background[1]
    return full


def _option_caps(opt: DesignOptions) -> tuple[tuple[str, int, int, str], ...]:
    """The options the run uses less of than asked, ``(option, asked, used, why)`` (DesignResult)."""
    caps = []
    cap = exact_cap(opt.compensation, opt.exact_samples)
    if cap is not None:
        why = f"under --compensation {opt.compensation} (each exact sample is a whole simulated calibration)"
        caps.append(("--exact-samples", opt.exact_samples, min(cap, opt.samples), why))
    elif opt.exact_samples > opt.samples:
        why = "by --samples (the exact subsample is the first linear samples)"
        caps.append(("--exact-samples", opt.exact_samples, opt.samples, why))
    if opt.verification_poses > opt.samples:
        why = "by --samples (at most one distinct pose per sample)"
        caps.append(("--verification-poses", opt.verification_poses, opt.samples, why))
    return tuple(caps)


class StageClock:
    """The wall time of each stage of :func:`allocate`, recorded where the stage is called.

    ``clock(name, stage, *args, **kwargs)`` runs ``stage(*args, **kwargs)``, stores its wall time
    under ``name`` in :attr:`timings_s` (a stage named None is not timed) and returns its result.
    """

    def __init__(self) -> None:
        """An empty clock."""
        self.timings_s: dict[str, float] = {}

    def __call__(self, name: str | None, stage: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """Run one stage and record its time."""
        t0 = time.perf_counter()
        out = stage(*args, **kwargs)
        if name is not None:
            self.timings_s[name] = time.perf_counter() - t0
        return out
