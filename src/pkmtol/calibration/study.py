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

Honest figures (DESIGN.md, "Claims and their scope"):

* the interval of every share beyond Δλ* is a bootstrap over machines (:mod:`.intervals`);
* a machine whose identification does not converge (or cannot be solved) in a case is left out
  of that case's rows, and the case names it and counts it; when more than
  :data:`MAX_UNCONVERGED` of the machines do, the study fails (the figures would describe the
  machines that happened to converge);
* a row whose exact and linear figures (mean, p95, p99 of Δλ) differ by more than
  :data:`LINEAR_VALIDITY` of Δλ* is flagged: the linear model is not valid there;
* with a nuisance-identifying instrument, every machine's instrument draws its own true nuisance
  (a random tracker placement, table balls and spheres off their nominal centres);
* ``plans_per_machine``: each machine is calibrated by its own plan (random subset, or D-optimal
  on its own half of the candidate pool), so the spread from one plan to another is part of the
  figures and is reported beside the one-plan study.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pkmtol.calibration.compensation import PoseErrors, controller_commands, pose_errors
from pkmtol.calibration.identification import Identification, identify_with, machine_poses
from pkmtol.calibration.intervals import machine_bootstrap
from pkmtol.calibration.linear_system import value_weights
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.maps import PoseMaps
from pkmtol.calibration.plan import CalibrationPlan
from pkmtol.calibration.postcal import calibrated_maps
from pkmtol.calibration.registration import registered
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import CalibrationError, IdentificationError, KinematicsError
from pkmtol.executor import Executor, map_chunks
from pkmtol.model.mechanism import Mechanism
from pkmtol.statistics import quantiles

#: A row whose exact and linear mean, p95 or p99 of Δλ differ by more than this fraction of Δλ* is
#: flagged "linear model not valid here; use the exact figure".
LINEAR_VALIDITY = 0.05
#: The study fails when more than this fraction of the machines do not converge in a case.
MAX_UNCONVERGED = 0.1
LINEAR_WARNING = "linear model not valid here; use the exact figure"


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
        machines: K, the machines behind the samples (machine ``k`` holds samples
            ``k·m … (k+1)·m − 1``); 0: one sample per machine.
    """

    label: str
    dlambda_m: np.ndarray
    tilt_rad: np.ndarray
    angle_rad: np.ndarray
    target_m: float
    machines: int = 0

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
        """Fraction beyond Δλ* and its 95 % interval ``(fraction, low, high)``, bootstrapped over machines."""
        d = self.dlambda_m
        K = self.machines if self.machines > 0 else d.size
        per = d.reshape(K, -1) if K and d.size % K == 0 else d.reshape(-1, 1)
        valid = np.isfinite(per)
        return machine_bootstrap(np.where(valid, per, 0.0) > self.target_m, valid)


@dataclass(frozen=True)
class StudyCase:
    """One calibration to simulate: the controller model, the pose selection and the pose count.

    Attributes:
        controller: ``compensatable``, ``full`` or explicit parameter names.
        selection: ``d-optimal`` or ``random``.
        poses: N.
        unit: What N counts (``poses``; ``circles`` for the ballbar).
    """

    controller: str | tuple[str, ...]
    selection: str
    poses: int
    unit: str = "poses"

    @property
    def label(self) -> str:
        """``<controller>, <N> <selection> poses`` (or circles)."""
        ctrl = self.controller if isinstance(self.controller, str) else f"explicit ({len(self.controller)})"
        return f"{ctrl}, {self.poses} {self.selection} {self.unit}"


@dataclass(frozen=True, eq=False)
class CaseContext:
    """What a machine's simulation needs of one case (picklable).

    ``plans`` and ``plan_maps``: one plan (and its calibrated maps) per machine, when each machine
    draws its own; else empty and every machine uses ``plan``.
    """

    case: StudyCase
    plan: CalibrationPlan
    maps: AccuracyMaps
    plans: tuple[CalibrationPlan, ...] = ()
    plan_maps: tuple[AccuracyMaps, ...] = ()

    def for_machine(self, k: int) -> tuple[CalibrationPlan, AccuracyMaps]:
        """Machine ``k``'s plan and maps."""
        if self.plans:
            return self.plans[k], self.plan_maps[k]
        return self.plan, self.maps


@dataclass(frozen=True, eq=False)
class CaseOutcome:
    """One machine's calibration in one case.

    Attributes:
        errors: Exact errors at the held-out poses after calibration.
        linear_position_m: Shape (m, 3): the linear prediction ``L δ + N ν`` of P's error.
        linear_rotation_rad: Shape (m, 3): its rotation.
        iterations: Gauss–Newton iterations.
        rms_after_m: RMS residual after the fit (length values) [m].
        converged: Whether the identification converged.
        failure: Why it did not (None when it did).
    """

    errors: PoseErrors
    linear_position_m: np.ndarray
    linear_rotation_rad: np.ndarray
    iterations: int
    rms_after_m: float
    converged: bool
    failure: str | None = None


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
        cases: Per case, the calibration's outcome.
    """

    before: PoseErrors
    ideal: PoseErrors
    ideal_linear_m: np.ndarray
    cases: tuple[CaseOutcome, ...]


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
    machine_plans: list[list[CalibrationPlan]] | None = None,
) -> StudyContext:
    """Assemble the study's shared inputs; the calibrated maps of each plan are computed here.

    ``machine_plans``: per case, one plan per machine (``plans_per_machine``), or None.
    """
    cases = tuple(
        CaseContext(
            case=c,
            plan=p,
            maps=calibrated_maps(holdout, p.H, p.ident, p.prior_sigma),
            plans=tuple(machine_plans[i]) if machine_plans else (),
            plan_maps=tuple(calibrated_maps(holdout, q.H, q.ident, q.prior_sigma) for q in machine_plans[i])
            if machine_plans
            else (),
        )
        for i, (c, p) in enumerate(plans)
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
    nuisance: np.ndarray | None = None,
) -> tuple[PoseErrors, Identification]:
    """Calibrate the true machine by ``plan`` and measure it at ``poses`` (exact throughout).

    The instrument reads the plan's poses of the true machine (exact forward kinematics, the true
    ``nuisance``, default its nominal) with ``noise`` added; ``noise`` (M,) is in the whitened
    units of ``plan.H`` (each value's own noise is ``noise · σ / σ_m``), so the linear prediction's
    ``N ν`` takes the same vector. The identification fits the controller model and the nuisance;
    the controller commands each pose's P by its model's exact inverse kinematics; the true
    machine's exact forward kinematics gives the errors (NaN where the model or the machine cannot
    be solved).
    """
    inst = plan.measurement_model(mechanism)
    origin, rot, _ = machine_poses(true, plan.maps.commands, plan.maps.q)
    pi = np.zeros(inst.nuisance_count) if nuisance is None else np.asarray(nuisance, dtype=float)
    values = inst.measure(origin, rot, plan.stations, pi)
    w = value_weights(inst, len(values), plan.settings.noise_m).reshape(values.shape)
    measured = inst.perturb(values, np.asarray(noise, dtype=float).reshape(values.shape) / w)
    ident = identify_with(mechanism, pset, plan.ident, plan.maps, inst, measured, plan.prior_sigma)
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


def simulate_machine(ctx: StudyContext, seed: np.random.SeedSequence, index: int = 0) -> MachineOutcome:
    """Draw machine ``index``, calibrate it by every case, and measure it at the held-out poses."""
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
        plan, maps = cc.for_machine(index)
        noise = rng.standard_normal(plan.H.shape[0]) * plan.settings.noise_m
        nuisance = plan.measurement_model(ctx.mechanism).draw_nuisance(rng)
        lin_p = np.einsum("kin,n->ki", maps.position, delta) + np.einsum(
            "kiM,M->ki", maps.position_noise, noise
        )
        lin_r = np.einsum("kin,n->ki", maps.rotation, delta) + np.einsum(
            "kiM,M->ki", maps.rotation_noise, noise
        )
        try:
            errors, ident = calibrate_and_evaluate(ctx.mechanism, ctx.pset, plan, true, noise, ho, nuisance)
        except (IdentificationError, KinematicsError) as err:
            nan = np.full((len(ho), 3), np.nan)
            failed = PoseErrors(position_m=nan, rotation_rad=nan, solved=np.zeros(len(ho), dtype=bool))
            outs.append(CaseOutcome(failed, lin_p, lin_r, 0, float("nan"), False, str(err)))
            continue
        why = None if ident.converged else f"not converged in {ident.iterations} Gauss–Newton iterations"
        outs.append(
            CaseOutcome(errors, lin_p, lin_r, ident.iterations, ident.rms_after_m, ident.converged, why)
        )
    return MachineOutcome(before=before, ideal=ideal, ideal_linear_m=ideal_lin, cases=tuple(outs))


def simulate_chunk(
    task: tuple[StudyContext, list[np.random.SeedSequence]]
    | tuple[StudyContext, list[np.random.SeedSequence], int],
) -> list[MachineOutcome]:
    """:func:`simulate_machine` for a chunk of machine seeds (the executor's unit of work).

    ``task`` is ``(context, seeds, index of the first machine)`` (the index defaults to 0).
    """
    ctx, seeds = task[0], task[1]
    first = task[2] if len(task) > 2 else 0  # type: ignore[misc]
    return [simulate_machine(ctx, s, first + i) for i, s in enumerate(seeds)]


@dataclass(frozen=True, eq=False)
class CaseResult:
    """One case of the study.

    Attributes:
        case: The case.
        plan: Its measurement plan (the one plan; with plans per machine, the study's reference plan).
        exact: Pooled exact errors after calibration (converged machines only).
        linear: The same from the linear model ``L δ + N ν`` with the same draws (same machines).
        iterations: Shape (K,): Gauss–Newton iterations per machine (0: the fit failed).
        rms_after_m: Shape (K,): RMS residual of the identification per machine [m].
        linear_exact_difference_m: Largest ``|Δλ_exact − Δλ_linear|`` over all samples [m].
        unconverged: ``(machine index, why)`` of every machine left out of this case's rows.
        plan_spread: With plans per machine: per plan, ``(mean Δλ [m], share beyond Δλ*)`` of the
            exact errors of the machine it calibrated; empty otherwise.
        registered: The exact errors once the workpiece is registered to each machine (its best
            rigid motion over the held-out poses removed, :mod:`.registration`): what an
            instrument that cannot see the machine's placement in K leaves at the part.
    """

    case: StudyCase
    plan: CalibrationPlan
    exact: ErrorSummary
    linear: ErrorSummary
    iterations: np.ndarray
    rms_after_m: np.ndarray
    linear_exact_difference_m: float
    unconverged: tuple[tuple[int, str], ...] = ()
    plan_spread: tuple[tuple[float, float], ...] = ()
    registered: ErrorSummary | None = None

    @property
    def linear_gap_m(self) -> float:
        """Largest difference of the row figures (mean, p95, p99 of Δλ), exact against linear [m]."""
        gaps = [
            abs(self.exact.mean_m - self.linear.mean_m),
            abs(self.exact.quantile_m(0.95) - self.linear.quantile_m(0.95)),
            abs(self.exact.quantile_m(0.99) - self.linear.quantile_m(0.99)),
        ]
        return float(np.nanmax(gaps)) if np.isfinite(gaps).any() else float("nan")

    @property
    def linear_valid(self) -> bool:
        """Whether the linear row is within :data:`LINEAR_VALIDITY` of Δλ* of the exact one."""
        return not self.linear_gap_m > LINEAR_VALIDITY * self.exact.target_m


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
        plans_per_machine: Whether every machine drew its own plan.
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
    plans_per_machine: bool = False

    @property
    def ideal_linear_valid(self) -> bool:
        """Whether Eq. 25's linear row is within :data:`LINEAR_VALIDITY` of Δλ* of its exact row."""
        gaps = [
            abs(self.ideal.mean_m - self.ideal_linear.mean_m),
            abs(self.ideal.quantile_m(0.95) - self.ideal_linear.quantile_m(0.95)),
            abs(self.ideal.quantile_m(0.99) - self.ideal_linear.quantile_m(0.99)),
        ]
        return not np.nanmax(gaps) > LINEAR_VALIDITY * self.target_m


def collect(ctx: StudyContext, outcomes: list[MachineOutcome]) -> StudyResult:
    """Pool the machines' outcomes into the study's rows.

    Raises:
        CalibrationError: no machine, or more than :data:`MAX_UNCONVERGED` of them unconverged in a
            case (names them).
    """
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
            machines=len(errs),
        )

    nan = np.full(K * len(ho), np.nan)
    ideal_lin = np.concatenate([np.linalg.norm(o.ideal_linear_m, axis=1) for o in outcomes])
    cases = []
    for c, cc in enumerate(ctx.cases):
        outs = [o.cases[c] for o in outcomes]
        bad = tuple((k, co.failure or "not converged") for k, co in enumerate(outs) if not co.converged)
        if len(bad) > MAX_UNCONVERGED * K:
            names = ", ".join(f"#{k}" for k, _ in bad[:10]) + (" …" if len(bad) > 10 else "")
            raise CalibrationError(
                f"case '{cc.case.label}': the identification of {len(bad)} of {K} machines did not "
                f"converge ({names}; first: {bad[0][1]}); the study's figures would describe only the "
                "machines that happened to converge. Lower the manufacturing σ, give more poses, or "
                "use another controller model"
            )
        good = [co for co in outs if co.converged]
        exact = summary(f"after calibration: {cc.case.label}", [co.errors for co in good])
        reg = summary(
            f"after calibration, workpiece registered: {cc.case.label}",
            [registered(co.errors, ho.points_m) for co in good],
        )
        lin_p = np.concatenate([co.linear_position_m for co in good])
        lin_r = np.concatenate([co.linear_rotation_rad for co in good])
        lin_errors = PoseErrors(position_m=lin_p, rotation_rad=lin_r, solved=np.ones(len(lin_p), dtype=bool))
        rot = np.tile(ho.rotations, (len(good), 1, 1))
        linear = ErrorSummary(
            label=f"linear prediction: {cc.case.label}",
            dlambda_m=lin_errors.dlambda_m,
            tilt_rad=lin_errors.tilt_rad(ctx.tool_axis, rot),
            angle_rad=lin_errors.angle_rad,
            target_m=ctx.target_m,
            machines=len(good),
        )
        diff = np.abs(exact.dlambda_m - linear.dlambda_m)
        spread: tuple[tuple[float, float], ...] = ()
        if cc.plans:
            spread = tuple(
                (
                    float(np.nanmean(co.errors.dlambda_m)),
                    float(np.nanmean(co.errors.dlambda_m > ctx.target_m)),
                )
                for co in good
            )
        cases.append(
            CaseResult(
                case=cc.case,
                plan=cc.plan,
                exact=exact,
                linear=linear,
                iterations=np.array([co.iterations for co in outs]),
                rms_after_m=np.array([co.rms_after_m for co in outs]),
                linear_exact_difference_m=float(np.nanmax(diff)) if np.isfinite(diff).any() else float("nan"),
                unconverged=bad,
                plan_spread=spread,
                registered=reg,
            )
        )
    return StudyResult(
        machines=K,
        holdout_points_m=ho.points_m,
        before=summary("before calibration (nominal commands)", [o.before for o in outcomes]),
        ideal=summary("Eq. 25, ideal compensation (exact)", [o.ideal for o in outcomes]),
        ideal_linear=ErrorSummary("Eq. 25, linear ‖J η_c‖", ideal_lin, nan, nan, ctx.target_m, K),
        cases=tuple(cases),
        tool_axis=ctx.tool_axis,
        target_m=ctx.target_m,
        plans_per_machine=any(cc.plans for cc in ctx.cases),
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
    for cc in ctx.cases:
        if cc.plans and len(cc.plans) != machines:
            raise CalibrationError(f"{len(cc.plans)} plans for {machines} machines in '{cc.case.label}'")
    seeds = np.random.SeedSequence(seed).spawn(machines)
    tasks = [(ctx, seeds[start : start + chunk], start) for start in range(0, machines, chunk)]
    outcomes = [o for part in map_chunks(simulate_chunk, tasks, executor) for o in part]
    return collect(ctx, outcomes)
