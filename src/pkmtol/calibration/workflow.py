"""The calibration jobs end to end: a plan and how it compares, the simulated study, real data.

These are what ``pkmtol calibrate`` runs (:mod:`pkmtol.cli.calibrate`); each returns a dataclass that
:mod:`pkmtol.present.calibration_tables` prints and writes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from pkmtol.calibration.holdout import Holdout, holdout_poses
from pkmtol.calibration.maps import PoseMaps
from pkmtol.calibration.plan import CalibrationPlan, candidate_pool, make_plan
from pkmtol.calibration.postcal import calibrated_maps
from pkmtol.calibration.prediction import Prediction, predict
from pkmtol.calibration.settings import CONTROLLERS, SELECTIONS, CalibrationSettings
from pkmtol.calibration.study import StudyCase, StudyResult, run_study, study_context
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.task import grid_sweep
from pkmtol.exceptions import InvalidRequestError
from pkmtol.executor import Executor
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism

#: Pose counts of the p99-against-N curve.
CURVE_POSES = (10, 15, 20, 30, 40, 60, 80, 100)
#: The same for the ballbar, in circles.
CURVE_CIRCLES = (2, 3, 4, 6, 8, 10, 15)


def design_sigma(
    pset: ParameterSet, classes: list[str], settings: CalibrationSettings, tolerances: np.ndarray | None
) -> np.ndarray:
    """σ of every parameter of a drawn machine (n,) [m or rad].

    A parameter with a finite entry in ``tolerances`` (an allocated design: the ideal mode's
    uncompensatable errors, or whatever a calibrated-mode design tolerances) is drawn at it; the
    other compensatable errors at the manufacturing σ; an uncompensatable error without a tolerance
    at 0 (not allocated: no effect anywhere); absorbed errors at 0 (they do not move the platform).
    """
    sigma = settings.manufacturing_sigma(pset)
    tol = np.full(len(pset), np.nan) if tolerances is None else np.asarray(tolerances, dtype=float)
    for i, c in enumerate(classes):
        if c == "absorbed":
            sigma[i] = 0.0
        elif np.isfinite(tol[i]):
            sigma[i] = tol[i]
        elif c == "uncompensatable":
            sigma[i] = 0.0
    return sigma


@dataclass(frozen=True)
class PlanSummary:
    """One plan's figures of merit.

    Attributes:
        label: ``d-optimal``, ``random #k``.
        poses: N.
        rank: Identifiable combinations.
        condition: Condition number of the scaled base Jacobian.
        observability: O1.
        log_det: ``log det`` of the information about the pool's base parameters.
        prediction: Predicted accuracy after calibration at the held-out poses.
    """

    label: str
    poses: int
    rank: int
    condition: float
    observability: float
    log_det: float
    prediction: Prediction


@dataclass(frozen=True, eq=False)
class PlanReport:
    """A plan, what it identifies, and how it compares with random plans of the same size.

    Attributes:
        plan: The chosen plan.
        summary: Its figures of merit.
        random: The same for random plans of the same size.
        curve: ``(N, d-optimal p99 [m], median random p99 [m])`` for N in :data:`CURVE_POSES`
            (within the pool), predicted by the linear model.
        sigma: The σ of every parameter behind the predictions [m or rad].
        holdout: The held-out evaluation poses.
        target_m: Δλ* [m].
        tool_axis: Tool axis in the platform frame.
    """

    plan: CalibrationPlan
    summary: PlanSummary
    random: tuple[PlanSummary, ...]
    curve: tuple[tuple[int, float, float], ...]
    sigma: np.ndarray
    holdout: Holdout
    target_m: float
    tool_axis: np.ndarray


def _summary(
    label: str, plan: CalibrationPlan, held: PoseMaps, sigma: np.ndarray, target: float, axis: np.ndarray
) -> PlanSummary:
    maps = calibrated_maps(held, plan.H, plan.ident, plan.prior_sigma)
    return PlanSummary(
        label=label,
        poses=plan.poses,
        rank=plan.ident.rank,
        condition=plan.ident.condition,
        observability=plan.ident.observability,
        log_det=plan.log_det,
        prediction=predict(maps, sigma, target, axis),
    )


def plan_report(
    mechanism: Mechanism,
    pset: ParameterSet,
    classes: list[str],
    settings: CalibrationSettings,
    sigma: np.ndarray,
    target_m: float,
    tool_axis: np.ndarray | None = None,
    random_sets: int = 10,
    holdout: int = 200,
    curve: bool = True,
) -> PlanReport:
    """Choose the plan of ``settings`` and compare it with ``random_sets`` random plans of its size."""
    axis = np.array([0.0, 0.0, 1.0]) if tool_axis is None else np.asarray(tool_axis, dtype=float)
    chain = ClosedChain(mechanism)
    pool = candidate_pool(mechanism, pset, settings, chain)
    ho = holdout_poses(mechanism, pset, holdout, np.random.default_rng(settings.seed + 1), chain)
    plan = make_plan(mechanism, pset, classes, settings, pool, sigma)
    summary = _summary(settings.selection, plan, ho.maps, sigma, target_m, axis)
    rnd = []
    for k in range(random_sets):
        s_k = _with(settings, seed=settings.seed + 1000 + k)
        p = make_plan(mechanism, pset, classes, s_k, pool, sigma, selection="random")
        rnd.append(_summary(f"random #{k + 1}", p, ho.maps, sigma, target_m, axis))
    points = []
    if curve:
        inst = plan.measurement_model(mechanism)
        groups = np.unique(pool.group_index).size
        per_group = plan.poses / max(np.unique(plan.maps.group_index).size, 1)
        for n in CURVE_CIRCLES if inst.name == "ballbar" else CURVE_POSES:
            values = n * per_group * inst.values_per_pose
            if n > groups or values < plan.ident.rank + inst.nuisance_count:
                continue
            d = make_plan(mechanism, pset, classes, settings, pool, sigma, poses=n, selection="d-optimal")
            p99_d = _summary("d", d, ho.maps, sigma, target_m, axis).prediction.p99_m
            p99_r = []
            for k in range(3):
                r = make_plan(
                    mechanism,
                    pset,
                    classes,
                    _with(settings, seed=settings.seed + 2000 + k),
                    pool,
                    sigma,
                    poses=n,
                    selection="random",
                )
                p99_r.append(_summary("r", r, ho.maps, sigma, target_m, axis).prediction.p99_m)
            points.append((n, p99_d, float(np.median(p99_r))))
    return PlanReport(
        plan=plan,
        summary=summary,
        random=tuple(rnd),
        curve=tuple(points),
        sigma=sigma,
        holdout=ho,
        target_m=float(target_m),
        tool_axis=axis,
    )


def _with(settings: CalibrationSettings, **changes: object) -> CalibrationSettings:
    return replace(settings, **changes)  # type: ignore[arg-type]


@dataclass(frozen=True, eq=False)
class StudyReport:
    """The simulated study and the plans it used.

    Attributes:
        study: The pooled results.
        settings: The settings of the study.
        sigma: σ of every parameter of the drawn machines [m or rad].
        holdout_skipped: Random held-out draws left out (unreachable or singular).
        timings_s: Wall time per stage [s].
    """

    study: StudyResult
    settings: CalibrationSettings
    sigma: np.ndarray
    holdout_skipped: int
    timings_s: dict[str, float] = field(default_factory=dict)


def simulate(
    mechanism: Mechanism,
    pset: ParameterSet,
    classes: list[str],
    settings: CalibrationSettings,
    sigma: np.ndarray,
    target_m: float,
    machines: int = 100,
    holdout: int = 200,
    controllers: tuple[str | tuple[str, ...], ...] | None = None,
    selections: tuple[str, ...] = SELECTIONS,
    tool_axis: np.ndarray | None = None,
    executor: Executor | None = None,
    plans_per_machine: bool = False,
) -> StudyReport:
    """The calibration study on exact kinematics (:mod:`pkmtol.calibration.study`).

    Args:
        mechanism: The mechanism.
        pset: Its parameter set.
        classes: Class of every parameter.
        settings: Targets, noise, pose count, controller (the default case), prior, seed.
        sigma: σ of every parameter of the drawn machines (:func:`design_sigma`).
        target_m: Δλ* [m].
        machines: K.
        holdout: Held-out random targets per machine.
        controllers: Controller models to compare (default: both ``compensatable`` and ``full``).
        selections: Pose selections to compare.
        tool_axis: Tool axis in the platform frame (default z).
        executor: Where the machines are simulated (None: serial); the numbers do not depend on it.
        plans_per_machine: Calibrate every machine by its own plan: a random plan of its own seed,
            or the D-optimal plan of its own random half of the candidate pool.
    """
    if isinstance(machines, bool) or not isinstance(machines, int) or machines < 1:
        raise InvalidRequestError(f"the study needs an integer number of machines ≥ 1, got {machines!r}")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    chain = ClosedChain(mechanism)
    pool = candidate_pool(mechanism, pset, settings, chain)
    ho = holdout_poses(mechanism, pset, holdout, np.random.default_rng(settings.seed + 1), chain)
    timings["pool and held-out poses"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ctrls = controllers if controllers is not None else CONTROLLERS
    plans = []
    for ctrl in ctrls:
        s_c = _with(settings, controller=ctrl)
        for sel in selections:
            unit = "circles" if settings.instrument == "ballbar" else "poses"
            case = StudyCase(controller=ctrl, selection=sel, poses=settings.poses, unit=unit)
            plans.append((case, make_plan(mechanism, pset, classes, s_c, pool, sigma, selection=sel)))
    per_machine = None
    if plans_per_machine:
        per_machine = [
            machine_plans(
                mechanism,
                pset,
                classes,
                _with(settings, controller=case.controller),
                pool,
                sigma,
                case.selection,
                machines,
            )
            for case, _ in plans
        ]
    ctx = study_context(
        mechanism, pset, sigma, ho.maps, ho.correction, ho.ideal, plans, target_m, tool_axis, per_machine
    )
    timings["plans"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    study = run_study(ctx, machines, settings.seed, chunk=5 if executor is None else 10, executor=executor)
    timings["exact simulation"] = time.perf_counter() - t0
    return StudyReport(
        study=study, settings=settings, sigma=sigma, holdout_skipped=ho.skipped, timings_s=timings
    )


def machine_plans(
    mechanism: Mechanism,
    pset: ParameterSet,
    classes: list[str],
    settings: CalibrationSettings,
    pool: PoseMaps,
    sigma: np.ndarray,
    selection: str,
    machines: int,
) -> list[CalibrationPlan]:
    """One plan per machine: random plans of their own seeds, or D-optimal on random halves of the pool.

    Each draw is seeded by the machine's index (``SeedSequence((seed, 61, k))``), so the plans do
    not depend on how the machines are run.
    """
    out = []
    for k in range(machines):
        rng = np.random.default_rng(np.random.SeedSequence((settings.seed, 61, k)))
        if selection == "random":
            s_k = _with(settings, seed=int(rng.integers(0, 2**31)))
            out.append(make_plan(mechanism, pset, classes, s_k, pool, sigma, selection="random"))
            continue
        groups = np.unique(pool.group_index)
        half = rng.choice(groups, size=max(settings.poses, groups.size // 2), replace=False)
        sub = np.flatnonzero(np.isin(pool.group_index, half))
        out.append(
            make_plan(mechanism, pset, classes, settings, pool.subset(sub), sigma, selection="d-optimal")
        )
    return out


def grid_classes(mechanism: Mechanism, pset: ParameterSet) -> list[str]:
    """The class of every parameter over the task-space grid (``Sweep.classify``)."""
    return grid_sweep(mechanism, pset, ClosedChain(mechanism)).classify()  # a hybrid's: TCP × axis
