"""The calibration study on exact kinematics: what a calibrated machine really achieves.

``K`` machines are drawn (every non-absorbed parameter Gaussian with its σ: manufacturing σ for the
compensatable ones, the allocated tolerances for the others). For each machine and each case
(controller model × pose selection × pose count): the tracker measures the targets at the plan's
poses (exact forward kinematics of the true machine, plus Gaussian noise σ_m per coordinate), the
identification fits the controller model (:func:`identify`), the controller commands held-out
random targets of P by its model's exact inverse kinematics, and the true machine's exact forward
kinematics gives the error left. Beside it: the same machine before calibration (nominal
commands), with the paper's ideal Eq. 25 correction (exact), and the linear prediction of every row
from the same draws (``L δ + N ν``, :mod:`pkmtol.calibration.postcal`), which must agree.

Machines are seeded one by one (``SeedSequence(seed).spawn(K)``), so the result does not depend
on how the machines are grouped or run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pkmtol.calibration.compensation import PoseErrors, controller_commands, pose_errors
from pkmtol.calibration.identification import Identification, identify, model_positions
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.maps import PoseMaps
from pkmtol.calibration.plan import CalibrationPlan
from pkmtol.calibration.postcal import calibrated_maps
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import CalibrationError
from pkmtol.executor import Executor, map_chunks
from pkmtol.model.mechanism import Mechanism
from pkmtol.statistics import quantiles, wilson_interval


@dataclass(frozen=True, eq=False)
class ErrorSummary:
    """Errors of the held-out poses of every machine, pooled (one row of the study's table).

    Attributes:
        label: What the row is (``before calibration``, ``Eq. 25 (ideal)``, a case label).
        dlambda_m: Shape (K·m,): Δλ = ‖P error‖ of every machine at every held-out pose [m]
            (NaN where a solve failed).
        tilt_rad: Shape (K·m,): tilt of the tool axis [rad] (NaN if not computed).
        angle_rad: Shape (K·m,): full platform orientation error angle [rad].
        target_m: Δλ* [m].
    """

    label: str
    dlambda_m: np.ndarray
    tilt_rad: np.ndarray
    angle_rad: np.ndarray
    target_m: float

    @property
    def samples(self) -> int:
        """Number of finite Δλ samples."""
        return int(np.isfinite(self.dlambda_m).sum())

    @property
    def mean_m(self) -> float:
        """Mean Δλ [m]."""
        return float(np.nanmean(self.dlambda_m))

    def quantile_m(self, p: float) -> float:
        """Sample quantile of Δλ [m] (p in [0, 1])."""
        return quantiles(self.dlambda_m, (p,))[0]

    @property
    def max_m(self) -> float:
        """Largest Δλ [m]."""
        return float(np.nanmax(self.dlambda_m))

    @property
    def failures(self) -> int:
        """Samples with Δλ > Δλ*."""
        return int(np.sum(self.dlambda_m[np.isfinite(self.dlambda_m)] > self.target_m))

    @property
    def beyond(self) -> tuple[float, float, float]:
        """Fraction beyond Δλ* and its Wilson 95 % interval ``(fraction, low, high)``."""
        n = self.samples
        lo, hi = wilson_interval(self.failures, n)
        return (self.failures / n if n else float("nan"), lo, hi)


@dataclass(frozen=True)
class StudyCase:
    """One calibration to simulate: the controller model, the pose selection and the pose count.

    Attributes:
        controller: ``compensatable``, ``full`` or explicit parameter names.
        selection: ``d-optimal`` or ``random``.
        poses: N.
    """

    controller: str | tuple[str, ...]
    selection: str
    poses: int

    @property
    def label(self) -> str:
        """``<controller>, <N> <selection> poses``."""
        ctrl = self.controller if isinstance(self.controller, str) else f"explicit ({len(self.controller)})"
        return f"{ctrl}, {self.poses} {self.selection} poses"


@dataclass(frozen=True, eq=False)
class CaseContext:
    """What a machine's simulation needs of one case (picklable)."""

    case: StudyCase
    plan: CalibrationPlan
    maps: AccuracyMaps


@dataclass(frozen=True, eq=False)
class StudyContext:
    """Everything the simulation of one machine needs (picklable, shared by all machines).

    Attributes:
        mechanism: The mechanism.
        pset: Its parameter set.
        sigma: Shape (n,): σ of every parameter's draw [m or rad] (0: held at zero).
        holdout: Maps at the held-out evaluation poses.
        correction: Shape (m, f, n): Eq. 25's command correction per parameter at those poses.
        ideal: The ``ideal`` accuracy maps at those poses (the linear Eq. 25 row).
        cases: The calibrations to simulate.
        tool_axis: The tool axis in the platform frame (unit vector).
        target_m: Δλ* [m].
    """

    mechanism: Mechanism
    pset: ParameterSet
    sigma: np.ndarray
    holdout: PoseMaps
    correction: np.ndarray
    ideal: AccuracyMaps
    cases: tuple[CaseContext, ...]
    tool_axis: np.ndarray
    target_m: float


@dataclass(frozen=True, eq=False)
class MachineOutcome:
    """One machine's errors at the held-out poses: before, Eq. 25, and each case (exact and linear).

    Attributes:
        before: Exact errors with nominal commands.
        ideal: Exact errors with Eq. 25's correction.
        ideal_linear_m: Shape (m, 3): the linear Eq. 25 P error ``J η``.
        cases: Per case, ``(exact errors, linear P error (m, 3), linear rotation (m, 3),
            identification iterations, RMS residual after [m])``.
    """

    before: PoseErrors
    ideal: PoseErrors
    ideal_linear_m: np.ndarray
    cases: tuple[tuple[PoseErrors, np.ndarray, np.ndarray, int, float], ...]


def study_context(
    mechanism: Mechanism,
    pset: ParameterSet,
    sigma: np.ndarray,
    holdout: PoseMaps,
    correction: np.ndarray,
    ideal: AccuracyMaps,
    plans: list[tuple[StudyCase, CalibrationPlan]],
    target_m: float,
    tool_axis: np.ndarray | None = None,
) -> StudyContext:
    """Assemble the study's shared inputs; the calibrated maps of each plan are computed here."""
    cases = tuple(
        CaseContext(case=c, plan=p, maps=calibrated_maps(holdout, p.H, p.ident, p.prior_sigma))
        for c, p in plans
    )
    return StudyContext(
        mechanism=mechanism,
        pset=pset,
        sigma=np.where(np.isfinite(sigma), np.asarray(sigma, dtype=float), 0.0),
        holdout=holdout,
        correction=correction,
        ideal=ideal,
        cases=cases,
        tool_axis=np.array([0.0, 0.0, 1.0]) if tool_axis is None else np.asarray(tool_axis, dtype=float),
        target_m=float(target_m),
    )


def calibrate_and_evaluate(
    mechanism: Mechanism,
    pset: ParameterSet,
    plan: CalibrationPlan,
    true: Machine,
    noise: np.ndarray | float,
    poses: PoseMaps,
) -> tuple[PoseErrors, Identification]:
    """Calibrate the true machine by ``plan`` and measure it at ``poses`` (exact throughout).

    The tracker reads the targets at the plan's commands with ``noise`` (3·N·t,) added [m]; the
    identification fits the controller model; the controller commands each pose's P by its model's
    exact inverse kinematics; the true machine's exact forward kinematics gives the errors (NaN
    where the model or the machine cannot be solved).
    """
    measured, _ = model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
    measured = measured + np.asarray(noise, dtype=float).reshape(measured.shape)
    ident = identify(
        mechanism,
        pset,
        plan.ident,
        plan.H,
        plan.maps.commands,
        plan.maps.q,
        measured,
        plan.targets_m,
        plan.prior_sigma,
    )
    model = Machine(mechanism, pset, ident.estimate)
    commands, ok = controller_commands(model, poses.points_m, poses.q)
    errors = pose_errors(
        true, np.where(ok[:, None], commands, poses.commands), poses.q, poses.points_m, poses.rotations
    )
    if not ok.all():
        errors = PoseErrors(
            position_m=np.where(ok[:, None], errors.position_m, np.nan),
            rotation_rad=np.where(ok[:, None], errors.rotation_rad, np.nan),
            solved=errors.solved & ok,
        )
    return errors, ident


def simulate_machine(ctx: StudyContext, seed: np.random.SeedSequence) -> MachineOutcome:
    """Draw one machine, calibrate it by every case, and measure it at the held-out poses."""
    rng = np.random.default_rng(seed)
    n = len(ctx.pset)
    delta = rng.standard_normal(n) * ctx.sigma
    true = Machine(ctx.mechanism, ctx.pset, delta)
    ho = ctx.holdout
    before = pose_errors(true, ho.commands, ho.q, ho.points_m, ho.rotations)
    corrected = ho.commands + np.einsum("kfn,n->kf", ctx.correction, delta)
    ideal = pose_errors(true, corrected, ho.q, ho.points_m, ho.rotations)
    ideal_lin = np.einsum("kin,n->ki", ctx.ideal.position, delta)
    outs = []
    for cc in ctx.cases:
        plan = cc.plan
        noise = rng.standard_normal(plan.H.shape[0]) * plan.settings.noise_m
        errors, ident = calibrate_and_evaluate(ctx.mechanism, ctx.pset, plan, true, noise, ho)
        lin_p = np.einsum("kin,n->ki", cc.maps.position, delta) + np.einsum(
            "kiM,M->ki", cc.maps.position_noise, noise
        )
        lin_r = np.einsum("kin,n->ki", cc.maps.rotation, delta) + np.einsum(
            "kiM,M->ki", cc.maps.rotation_noise, noise
        )
        outs.append((errors, lin_p, lin_r, ident.iterations, ident.rms_after_m))
    return MachineOutcome(before=before, ideal=ideal, ideal_linear_m=ideal_lin, cases=tuple(outs))


def simulate_chunk(task: tuple[StudyContext, list[np.random.SeedSequence]]) -> list[MachineOutcome]:
    """:func:`simulate_machine` for a chunk of machine seeds (the executor's unit of work)."""
    ctx, seeds = task
    return [simulate_machine(ctx, s) for s in seeds]


@dataclass(frozen=True, eq=False)
class CaseResult:
    """One case of the study.

    Attributes:
        case: The case.
        plan: Its measurement plan.
        exact: Pooled exact errors after calibration.
        linear: The same from the linear model ``L δ + N ν`` with the same draws.
        iterations: Shape (K,): Gauss–Newton iterations per machine.
        rms_after_m: Shape (K,): RMS residual of the identification per machine [m].
        linear_exact_difference_m: Largest ``|Δλ_exact − Δλ_linear|`` over all samples [m].
    """

    case: StudyCase
    plan: CalibrationPlan
    exact: ErrorSummary
    linear: ErrorSummary
    iterations: np.ndarray
    rms_after_m: np.ndarray
    linear_exact_difference_m: float


@dataclass(frozen=True, eq=False)
class StudyResult:
    """The calibration study (SI units).

    Attributes:
        machines: K.
        holdout_points_m: Shape (m, 3): the held-out targets of P [m].
        before: Exact errors with nominal commands.
        ideal: Exact errors with Eq. 25's correction (the paper's assumption).
        ideal_linear: The paper's linear prediction ``‖J η_c‖``.
        cases: Every simulated calibration.
        tool_axis: The tool axis in the platform frame.
        target_m: Δλ* [m].
        timings_s: Wall time per stage [s].
    """

    machines: int
    holdout_points_m: np.ndarray
    before: ErrorSummary
    ideal: ErrorSummary
    ideal_linear: ErrorSummary
    cases: tuple[CaseResult, ...]
    tool_axis: np.ndarray
    target_m: float
    timings_s: dict[str, float] = field(default_factory=dict)


def collect(ctx: StudyContext, outcomes: list[MachineOutcome]) -> StudyResult:
    """Pool the machines' outcomes into the study's rows."""
    ho = ctx.holdout
    K = len(outcomes)
    if K == 0:
        raise CalibrationError("the study needs at least one machine")

    def summary(label: str, errs: list[PoseErrors]) -> ErrorSummary:
        return ErrorSummary(
            label=label,
            dlambda_m=np.concatenate([e.dlambda_m for e in errs]),
            tilt_rad=np.concatenate([e.tilt_rad(ctx.tool_axis, ho.rotations) for e in errs]),
            angle_rad=np.concatenate([e.angle_rad for e in errs]),
            target_m=ctx.target_m,
        )

    nan = np.full(K * len(ho), np.nan)
    ideal_lin = np.concatenate([np.linalg.norm(o.ideal_linear_m, axis=1) for o in outcomes])
    cases = []
    for c, cc in enumerate(ctx.cases):
        exact = summary(f"after calibration: {cc.case.label}", [o.cases[c][0] for o in outcomes])
        lin_p = np.concatenate([o.cases[c][1] for o in outcomes])
        lin_r = np.concatenate([o.cases[c][2] for o in outcomes])
        lin_errors = PoseErrors(position_m=lin_p, rotation_rad=lin_r, solved=np.ones(len(lin_p), dtype=bool))
        rot = np.tile(ho.rotations, (K, 1, 1))
        linear = ErrorSummary(
            label=f"linear prediction: {cc.case.label}",
            dlambda_m=lin_errors.dlambda_m,
            tilt_rad=lin_errors.tilt_rad(ctx.tool_axis, rot),
            angle_rad=lin_errors.angle_rad,
            target_m=ctx.target_m,
        )
        diff = np.abs(exact.dlambda_m - linear.dlambda_m)
        cases.append(
            CaseResult(
                case=cc.case,
                plan=cc.plan,
                exact=exact,
                linear=linear,
                iterations=np.array([o.cases[c][3] for o in outcomes]),
                rms_after_m=np.array([o.cases[c][4] for o in outcomes]),
                linear_exact_difference_m=float(np.nanmax(diff)) if np.isfinite(diff).any() else float("nan"),
            )
        )
    return StudyResult(
        machines=K,
        holdout_points_m=ho.points_m,
        before=summary("before calibration (nominal commands)", [o.before for o in outcomes]),
        ideal=summary("Eq. 25, ideal compensation (exact)", [o.ideal for o in outcomes]),
        ideal_linear=ErrorSummary("Eq. 25, linear ‖J η_c‖", ideal_lin, nan, nan, ctx.target_m),
        cases=tuple(cases),
        tool_axis=ctx.tool_axis,
        target_m=ctx.target_m,
    )


def run_study(
    ctx: StudyContext, machines: int, seed: int = 0, chunk: int = 5, executor: Executor | None = None
) -> StudyResult:
    """Simulate ``machines`` machines and pool them; see :func:`simulate_chunk`.

    Machine ``k`` draws from its own ``SeedSequence(seed).spawn(machines)[k]``, so the result is the
    same for every ``chunk`` size, executor and worker count (tested).
    """
    if isinstance(machines, bool) or not isinstance(machines, int) or machines < 1:
        raise CalibrationError(f"the study needs an integer number of machines ≥ 1, got {machines!r}")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise CalibrationError(f"the study's chunk size must be an integer ≥ 1, got {chunk!r}")
    seeds = np.random.SeedSequence(seed).spawn(machines)
    tasks = [(ctx, seeds[start : start + chunk]) for start in range(0, machines, chunk)]
    outcomes = [o for part in map_chunks(simulate_chunk, tasks, executor) for o in part]
    return collect(ctx, outcomes)
