"""The main job: from a mechanism to a verified tolerance table (paper §3–4.5, end to end).

:func:`allocate` runs, in order: the error model over the task-space grid and the parameter
classification; the sensitive-pose search (Monte Carlo beside the analytic σ); FOSM allocation
over the β series; verification of the design-β tolerances (linear model on random poses, exact
kinematics on a subsample); the traditional method (all errors, no compensation) for comparison.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from pkmtol.design.cost import cost_model, cost_optimal
from pkmtol.design.exact import CRITERIA, ClaimRow, claimed_vs_true, scale_design
from pkmtol.design.fosm import check_design, fosm_tolerances
from pkmtol.design.pose_search import PoseSearch, search_sensitive_pose
from pkmtol.design.reliability import reliability_fosm
from pkmtol.design.verification import Verification, verify_all
from pkmtol.error_model.accuracy import first_max, grid_norm_moments, sensitivities
from pkmtol.error_model.parameters import ParameterSet, default_set, parameter_set
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.exceptions import InvalidRequestError
from pkmtol.executor import Executor
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


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
        executor: Where the exact verification and the claimed-vs-true reliabilities run
            (None: serial); the numbers do not depend on it.
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
    method: str = "fosm"
    criterion: str = "every"
    claim_poses: int = 300
    executor: Executor | None = None


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


@dataclass(frozen=True, eq=False)
class MethodDesign:
    """A design by the ``exact`` or ``cost`` method (tolerances of the η_c parameters, SI).

    Attributes:
        method: ``exact`` or ``cost``.
        criterion: ``worst`` / ``every`` / ``average`` (``every`` for cost).
        target_reliability: R* = Φ(design β).
        sigma: Tolerances (len(uncompensatable),) [SI].
        reliability: Exact Gaussian R at each grid pose.
        cost: Total cost of ``sigma`` under the cost model.
        reference_sigma: The equal-effect design scaled to the same true R (min over the grid).
        reference_cost: Its cost.
    """

    method: str
    criterion: str
    target_reliability: float
    sigma: np.ndarray
    reliability: np.ndarray
    cost: float
    reference_sigma: np.ndarray
    reference_cost: float


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
        uncompensatable: Indices of the allocated parameters (η_c).
        sensitivity: Shape (n_params,): ``‖J[:, i]‖`` at the design point (0 if not in η_c).
        sensitivity_uncompensated: Shape (n_params,): ``‖J_total[:, i]‖`` at the design point.
        tolerances: Shape (n_params, len(betas)): FOSM tolerances (nan for parameters not allocated).
        verification: Per distribution, the verification of the design-β tolerances.
        traditional: The traditional method.
        claims: Claimed Φ(β) vs true reliability of each FOSM design (β series).
        method_design: The ``exact`` or ``cost`` design when asked for (None for ``fosm``); the
            verification then belongs to it.
        timings_s: Wall time of each stage [s].
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

    @property
    def worst_point_m(self) -> np.ndarray:
        """Design point (most error-sensitive position of P) in K, shape (3,) [m]."""
        return self.grid.points_m[self.worst_index]

    @property
    def design_column(self) -> int:
        """Column of ``tolerances`` that belongs to the design β."""
        return int(np.argmin(np.abs(np.asarray(self.betas) - self.design_beta)))


def allocate(mechanism: Mechanism, options: DesignOptions | None = None) -> DesignResult:
    """Run the main job on a mechanism.

    Raises:
        InvalidRequestError: non-positive target, β, or sample counts.
        pkmtol.exceptions.KinematicsError: a task-space point is unreachable or singular.
    """
    opt = options or DesignOptions()
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
    timings: dict[str, float] = {}
    rng = np.random.default_rng(opt.seed)
    pset = parameter_set(mechanism, opt.parameter_set or default_set(mechanism))

    t0 = time.perf_counter()
    chain = ClosedChain(mechanism)
    grid = sweep(mechanism, pset, mechanism.task_space.grid(), chain, progress=opt.progress)
    classes = grid.classify()
    unc = np.array([i for i, c in enumerate(classes) if c == "uncompensatable"], dtype=int)
    timings["error model on grid"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    search = search_sensitive_pose(grid.J[:, :, unc], opt.samples, rng)
    worst = search.worst_index_analytic
    timings["sensitive-pose search"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    n_par = len(pset)
    sens = np.zeros(n_par)
    sens[unc] = sensitivities(grid.J[worst][:, unc])
    sens_unc = sensitivities(grid.J_total[worst])
    tol = np.full((n_par, len(betas)), np.nan)
    tol[unc] = fosm_tolerances(sens[unc], target, np.array(betas))
    timings["allocation"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    design_col = int(np.argmin(np.abs(np.asarray(betas) - design_beta)))
    points = mechanism.task_space.sample(rng, min(opt.verification_poses, opt.samples))
    nearest = np.argmin(((points[:, None, :] - grid.points_m[None]) ** 2).sum(-1), axis=1)
    guesses = np.array([grid.poses[k].q_all for k in nearest])
    rnd = sweep(mechanism, pset, points, chain, guesses=guesses, progress=opt.progress)
    timings["verification poses"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    claims = claimed_vs_true(
        grid.J[worst][:, unc],
        rnd.J[: opt.claim_poses][:, :, unc],
        tol[unc],
        betas,
        target,
        opt.samples,
        rng,
        opt.executor,
    )
    timings["claimed vs true reliability"] = time.perf_counter() - t0

    method_design = None
    verified = tol[unc, design_col]
    if opt.method != "fosm":
        t0 = time.perf_counter()
        method_design = method_design_for(
            mechanism, pset, grid, unc, tol[unc, design_col], target, design_beta, worst, opt
        )
        verified = method_design.sigma
        timings[f"{opt.method} design"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ver = verify_all(
        mechanism,
        pset,
        rnd,
        unc,
        verified,
        target,
        opt.samples,
        opt.exact_samples,
        rng,
        progress=opt.progress,
        executor=opt.executor,
    )
    timings["verification"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    trad_cols = np.array([i for i, c in enumerate(classes) if c != "absorbed"], dtype=int)
    trad_sigma = grid_norm_moments(grid.J_total[:, :, trad_cols])[:, 1]
    trad_worst = first_max(trad_sigma)
    # evaluated at the same design point as the new method, so the comparison isolates what
    # compensation buys; the traditional model's own most sensitive point is reported beside it
    trad_sens = sensitivities(grid.J_total[worst][:, trad_cols])
    traditional = Traditional(
        columns=trad_cols,
        worst_index=trad_worst,
        sensitivity=trad_sens,
        tolerance=fosm_tolerances(trad_sens, target, np.array([design_beta]))[:, 0],
    )
    timings["traditional method"] = time.perf_counter() - t0

    return DesignResult(
        mechanism=mechanism,
        pset=pset,
        target_m=target,
        betas=betas,
        design_beta=design_beta,
        reliability_fosm=reliability_fosm(np.array(betas)),
        classes=classes,
        grid=grid,
        search=search,
        worst_index=worst,
        uncompensatable=unc,
        sensitivity=sens,
        sensitivity_uncompensated=sens_unc,
        tolerances=tol,
        verification=ver,
        traditional=traditional,
        claims=claims,
        method_design=method_design,
        timings_s=timings,
    )


def method_design_for(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep,
    unc: np.ndarray,
    fosm_sigma: np.ndarray,
    target: float,
    design_beta: float,
    worst: int,
    opt: DesignOptions,
) -> MethodDesign:
    """The ``exact`` or ``cost`` design of the η_c tolerances at R* = Φ(design β).

    Args:
        mechanism: The mechanism (its ``[cost]`` table feeds the cost model).
        pset: Its parameter set.
        grid: The task-space grid sweep.
        unc: Indices of the uncompensatable parameters (the toleranced ones).
        fosm_sigma: Their FOSM tolerances at the design β [SI] (the equal-effect shape).
        target: Δλ* [m].
        design_beta: β; R* = Φ(β).
        worst: Grid index of the design point.
        opt: ``opt.method`` (``exact`` or ``cost``) and ``opt.criterion``.
    """
    r_star = float(reliability_fosm(design_beta))
    J = grid.J[:, :, unc]
    model = cost_model([pset.parameters[i] for i in unc], mechanism.extra.get("cost"))
    reference = scale_design(J, fosm_sigma, target, r_star, "every", worst)
    if opt.method == "exact":
        d = scale_design(J, fosm_sigma, target, r_star, opt.criterion, worst)
        sigma, rel, criterion = d.sigma, d.reliability, opt.criterion
    elif opt.method == "cost":
        c = cost_optimal(J, model, target, r_star, reference.sigma, [pset.names[i] for i in unc])
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
        reference_sigma=reference.sigma,
        reference_cost=model.cost(reference.sigma),
    )
