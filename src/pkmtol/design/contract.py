"""The contract check: a design's claimed failure against machines built and measured on exact kinematics.

:func:`check_contract` builds ``K`` machines at a design's printed tolerances and measures each one
by exact forward kinematics at every grid pose the design used (DESIGN.md, "Claims and their
scope"). What a machine goes through is the calibration study's own simulation
(:func:`pkmtol.calibration.study.simulate_machine`, run by the executor in chunks, one seed per
machine), so the check reuses the project's identification and compensation rather than a copy:

* every toleranced parameter is drawn Gaussian at its tolerance (``inf``, free: held at 0); every
  other non-absorbed parameter at its manufacturing σ (the calibration settings); absorbed ones at 0;
* ``ideal``: the actuators take Eq. 25's correction of the true errors (the paper's promise, as
  :func:`pkmtol.design.mode_verification.ideal_exact` applies it);
* ``calibrated``: the tracker measures the allocation's own plan (its poses, its noise), the
  identification fits the controller model on exact kinematics, and the controller commands each
  grid target by the identified model's exact inverse kinematics;
* ``none``: the nominal commands.

A hybrid machine (a ``[tool]`` chain, docs/hybrid.md) goes through the same simulation with the
whole machine in place of the module: its grid poses are TCP points × tool axes, its machines
perturb the limbs, the wrist and the tool, the identification and the controller are those of the
whole machine (:mod:`pkmtol.calibration.hybrid_machine`: the identified model's exact inverse
kinematics of the TCP and the tool axis), and the machine is measured by the exact forward
kinematics of the module and the tool chain together. Δλ is then the TCP's position error.

Every machine's tilt of the tool axis Δα is measured too. When the design claims the joint
reliability ``P(Δλ ≤ Δλ* and Δα ≤ Δα*)`` (an ``exact`` design with an orientation target), a
machine fails at a pose when either index is beyond its target, and the design's own linear
prediction there is that joint reliability; otherwise Δα is reported and not judged.

At each grid pose each machine contributes one Bernoulli trial (a failure), so the Wilson interval of
the failures across machines is the clustered interval of that pose; the task-space aggregate
pools the poses and takes a bootstrap over whole machines (:mod:`pkmtol.calibration.intervals`).
The claim holds at a pose when the claimed failure lies inside or above the 95 % interval. A machine
whose identification does not converge is left out and named, as the study does; more than the
study's 10 % of them, and no pose can hold its claim (the figures would describe only the machines
that happened to converge).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pkmtol.calibration.compensation import PoseErrors
from pkmtol.calibration.intervals import machine_bootstrap
from pkmtol.calibration.maps import pose_maps
from pkmtol.calibration.settings import CalibrationSettings, settings_from_table
from pkmtol.calibration.study import (
    LINEAR_VALIDITY,
    MAX_UNCONVERGED,
    MachineOutcome,
    StudyCase,
    simulate_chunk,
    study_context,
)
from pkmtol.design.exact import grid_reliability
from pkmtol.design.orientation import joint_covariance, joint_reliability
from pkmtol.design.reliability import exact_reliability_many, reliability_fosm
from pkmtol.error_model.compensation import AccuracyMaps, mode_maps
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.executor import Executor, map_chunks
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.statistics import quantiles, wilson_interval

if TYPE_CHECKING:
    from pkmtol.design.job import DesignResult

#: Verdicts of a pose.
VERDICTS = ("holds", "fails", "cannot hold here", "no claim here")


@dataclass(frozen=True, eq=False)
class PoseCheck:
    """The contract at one grid pose (fractions in [0, 1]).

    Attributes:
        index: Grid index.
        point_m: Shape (3,): the pose's P in K (a hybrid's TCP) [m].
        claimed: Claimed failure ``1 − R`` at this pose (NaN: the design claims nothing here).
        predicted: The design's own linear model's failure here (exact Gaussian reliability).
        measured: Share of the machines that fail here: beyond Δλ* (or, with a joint claim, beyond
            Δα*); unsolved machines count as failed.
        low: Lower end of its 95 % Wilson interval (one trial per machine).
        high: Upper end.
        machines: Machines counted here (all but those whose identification did not converge).
        unsolved: Of them, those that could not be solved here (cannot be assembled or commanded).
        noise_failure: Failure of the tracker noise alone here (0 without a calibration; the joint
            failure with a joint claim).
        linear_gap_m: Largest difference of the pose's figures over the machines (mean, p95, p99 of
            Δλ), exact against the linear ``L δ + N ν`` (``J η`` under ``ideal``) of the same draws
            [m], as the study compares its rows (NaN: no linear figure, mode ``none``).
        linear_valid: Whether that gap is within the study's ``LINEAR_VALIDITY`` (5 %) of Δλ*
            (else: the linear model is not valid here; use the exact figure).
        verdict: One of :data:`VERDICTS`.
        reason: Why, for ``cannot hold here`` and ``no claim here`` (empty otherwise).
        mean_tilt_rad: Mean tilt Δα of the tool axis over the solved machines here [rad].
        tilt_measured: Share of the machines beyond Δα* here (NaN: the design claims no Δα).
        tilt_gap_rad: Largest difference of the pose's figures of Δα (mean, p95, p99), exact
            against the linear model of the same draws [rad] (NaN: no linear tilt, which the
            study keeps under ``calibrated`` only).
    """

    index: int
    point_m: np.ndarray
    claimed: float
    predicted: float
    measured: float
    low: float
    high: float
    machines: int
    unsolved: int
    noise_failure: float
    linear_gap_m: float
    linear_valid: bool
    verdict: str
    reason: str = ""
    mean_tilt_rad: float = float("nan")
    tilt_measured: float = float("nan")
    tilt_gap_rad: float = float("nan")


@dataclass(frozen=True, eq=False)
class ContractCheck:
    """A design's contract measured on exact kinematics.

    Attributes:
        mechanism: The mechanism's name.
        mode: ``ideal``, ``calibrated`` or ``none``.
        method: ``fosm``, ``exact`` or ``cost``.
        scope: Where the claim holds, in words (``every one of 147 grid poses``, ...).
        claimed_reliability: The printed R (R* = Φ(design β)).
        target_m: Δλ* [m].
        machines: Machines drawn.
        unconverged: ``(machine, why)`` of the machines whose identification did not converge.
            As in the calibration study, they are left out of the figures and named here; when
            more than ``MAX_UNCONVERGED`` (10 %) of the machines are, every pose with a claim is
            ``cannot hold here`` (the figures would describe only the machines that converged).
        poses: Per grid pose, the check.
        dlambda_m: Shape (K, m): Δλ of every machine at every grid pose [m] (NaN: unsolved), the
            unconverged ones too (as their controller was left: the identification's last estimate).
        converged: Shape (K,): the machines the figures count (all but the unconverged).
        aggregate: Task-space share beyond Δλ* of the counted machines and its machine-bootstrap
            interval ``(f, low, high)``.
        aggregate_claimed: The claimed failure over the grid (pooled poses; NaN: no such claim).
        wall_time_s: Wall time of the simulation [s].
        hybrid: Whether the machine is a hybrid (Δλ and Δα at its TCP).
        orientation_target_rad: Δα* when the claim is the joint reliability of Δλ and Δα [rad]
            (None: the claim is Δλ's alone).
        dalpha_rad: Shape (K, m): the tilt Δα of the tool axis of every machine at every grid
            pose [rad] (NaN: unsolved).
    """

    mechanism: str
    mode: str
    method: str
    scope: str
    claimed_reliability: float
    target_m: float
    machines: int
    unconverged: tuple[tuple[int, str], ...]
    poses: tuple[PoseCheck, ...]
    dlambda_m: np.ndarray
    converged: np.ndarray
    aggregate: tuple[float, float, float]
    aggregate_claimed: float
    wall_time_s: float
    hybrid: bool = False
    orientation_target_rad: float | None = None
    dalpha_rad: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def task(self) -> str:
        """What a machine must meet at a pose, in words."""
        where = "the TCP" if self.hybrid else "P"
        if self.orientation_target_rad is None:
            return f"Δλ ≤ {self.target_m * 1e6:.4g} µm at {where}"
        return (
            f"Δλ ≤ {self.target_m * 1e6:.4g} µm at {where} and Δα ≤ "
            f"{self.orientation_target_rad * 1e6:.4g} µrad of the tool axis, jointly"
        )

    @property
    def holds(self) -> bool:
        """Whether no pose with a claim fails (a ``cannot hold here`` pose is not a pass)."""
        return all(p.verdict in ("holds", "no claim here") for p in self.poses)

    @property
    def worst(self) -> PoseCheck:
        """The pose with the largest measured failure (the first of equals)."""
        return max(self.poses, key=lambda p: (p.measured, -p.index))

    @property
    def aggregate_holds(self) -> bool | None:
        """Whether the claimed failure over the grid lies inside or above its interval (None: no claim)."""
        if not np.isfinite(self.aggregate_claimed):
            return None
        return bool(self.aggregate_claimed >= self.aggregate[1])

    def verdicts(self) -> dict[str, int]:
        """How many poses got each verdict."""
        return {v: sum(p.verdict == v for p in self.poses) for v in VERDICTS}


def claim_of(design: DesignResult) -> tuple[np.ndarray, float, str]:
    """The claimed failure at each grid pose (NaN: no claim there), over the grid, and the scope in words.

    ``exact`` / ``cost`` with criterion ``every`` claim ``R ≥ R*`` at every grid pose (so also over
    the grid); ``worst`` at the design point only; ``average`` on the grid mean only. FOSM prints
    ``R = Φ(β)`` with no place; the check reads it as a task-space claim, the reading a designer makes
    of its headline (issue 24) and the one the one-pose design does not keep.
    """
    m = len(design.grid.poses)
    md = design.method_design
    failure = 1.0 - (float(reliability_fosm(design.design_beta)) if md is None else md.target_reliability)
    if md is None:
        return np.full(m, failure), failure, f"Φ(β) read over all {m} grid poses (FOSM designs at one pose)"
    if md.criterion == "every":
        return np.full(m, failure), failure, f"every one of {m} grid poses"
    claimed = np.full(m, np.nan)
    if md.criterion == "worst":
        claimed[design.worst_index] = failure
        return claimed, float("nan"), f"the design point only (grid pose {design.worst_index})"
    return claimed, failure, f"the mean over {m} grid poses"


def machine_sigma(design: DesignResult, settings: CalibrationSettings) -> np.ndarray:
    """σ of every parameter of a drawn machine (n,) [m or rad]: tolerances, manufacturing σ, 0."""
    n = len(design.pset)
    unc = np.asarray(design.uncompensatable, dtype=int)
    tol = (
        design.method_design.sigma
        if design.method_design is not None
        else design.tolerances[unc, design.design_column]
    )
    sigma = np.where(
        np.array([c != "absorbed" for c in design.classes]), settings.manufacturing_sigma(design.pset), 0.0
    )
    sigma[unc] = np.where(np.isfinite(tol), tol, 0.0)
    return np.asarray(sigma, dtype=float).reshape(n)


def check_contract(
    design: DesignResult,
    machines: int = 200,
    seed: int = 0,
    executor: Executor | None = None,
    chunk: int = 5,
    settings: CalibrationSettings | None = None,
) -> ContractCheck:
    """Build ``machines`` machines at the design's tolerances and check its claim at every grid pose.

    Args:
        design: A :func:`pkmtol.allocate` result (a module's or a hybrid's).
        machines: K.
        seed: Machine ``k`` draws from ``SeedSequence(seed).spawn(K)[k]``.
        executor: Where the machines are simulated (None: serial); the numbers do not depend on it.
        chunk: Machines per chunk of work.
        settings: Manufacturing σ of the untoleranced errors (None: the plan's under
            ``calibrated``, else the mechanism's ``[calibration]`` table, else the defaults).

    Raises:
        InvalidArgumentError: ``machines`` or ``chunk`` not an integer ≥ 1, ``seed`` not an integer.
    """
    for name, value, low, what in (
        ("machines", machines, 1, "machines to build, e.g. 200"),
        ("chunk", chunk, 1, "machines per chunk of work, e.g. 5"),
        ("seed", seed, 0, "the random seed, e.g. 0"),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            raise InvalidArgumentError(name, value, f"expected an integer ≥ {low} ({what})")
    mech = design.mechanism
    plan = design.calibration_plan
    if settings is None:
        settings = plan.settings if plan is not None else _mechanism_settings(design)
    chain = ClosedChain(mech)
    grid = design.grid
    held = pose_maps(grid, chain.actuated_idx, mech.reference_point_m, mech.task_projection)
    correction = np.array([s.correction for s in grid.separations])
    sigma = machine_sigma(design, settings)
    cases = [(StudyCase(plan.settings.controller, plan.settings.selection, plan.poses), plan)] if plan else []
    ctx = study_context(
        mech, design.pset, sigma, held, correction, mode_maps(grid, "ideal"), cases, design.target_m
    )
    t0 = time.perf_counter()
    seeds = np.random.SeedSequence(int(seed)).spawn(int(machines))
    tasks = [(ctx, seeds[s : s + chunk], s) for s in range(0, machines, chunk)]
    outcomes = [o for part in map_chunks(simulate_chunk, tasks, executor) for o in part]
    wall = time.perf_counter() - t0
    axis, alpha_target = _orientation_claim(design)
    per = _per_machine(outcomes, design.compensation, axis, held.rotations)
    exact, linear, tilt, linear_tilt, unconverged = per
    kept = np.ones(len(exact), dtype=bool)
    kept[[k for k, _ in unconverged]] = False
    blocked = ""
    if len(unconverged) > MAX_UNCONVERGED * machines:
        blocked = (
            f"the identification of {len(unconverged)} of {machines} machines did not converge (more "
            f"than {100 * MAX_UNCONVERGED:.0f} %; first: {unconverged[0][1]}): the figures would describe "
            "only the machines that happened to converge"
        )
    maps = ctx.cases[0].maps if ctx.cases else mode_maps(grid, design.compensation)
    predicted, noise_fail = _linear_failures(
        maps,
        design.uncompensatable,
        sigma,
        design.target_m,
        None if alpha_target is None else (axis, alpha_target),
    )
    claimed, claimed_grid, scope = claim_of(design)
    ek, lk, tk, ltk = exact[kept], linear[kept], tilt[kept], linear_tilt[kept]
    poses = tuple(
        _pose_check(
            k,
            held.points_m[k],
            claimed[k],
            predicted[k],
            ek[:, k],
            lk[:, k],
            noise_fail[k],
            design.target_m,
            tilt_rad=tk[:, k],
            linear_tilt_rad=ltk[:, k],
            target_rad=alpha_target,
        )
        for k in range(len(held))
    )
    if blocked:
        poses = tuple(_blocked(p, blocked) for p in poses)
    failed = _failures(ek, design.target_m, tk, alpha_target)
    aggregate = machine_bootstrap(failed, np.ones_like(failed, dtype=bool))
    return ContractCheck(
        mechanism=mech.name,
        mode=design.compensation,
        method="fosm" if design.method_design is None else design.method_design.method,
        scope=scope,
        claimed_reliability=float(reliability_fosm(design.design_beta)),
        target_m=float(design.target_m),
        machines=int(machines),
        unconverged=unconverged,
        poses=poses,
        dlambda_m=exact,
        converged=kept,
        aggregate=aggregate,
        aggregate_claimed=claimed_grid,
        wall_time_s=wall,
        hybrid=mech.tool is not None,
        orientation_target_rad=alpha_target,
        dalpha_rad=tilt,
    )


def _orientation_claim(design: DesignResult) -> tuple[np.ndarray, float | None]:
    """The tool axis (platform frame; a hybrid's TCP frame) and Δα* when the claim is joint (else None)."""
    od = design.orientation
    axis = np.array([0.0, 0.0, 1.0]) if od is None else np.asarray(od.axis, dtype=float)
    joint = design.claim is not None and design.claim.joint
    target = None if od is None or not joint else od.target_rad
    return axis, None if target is None else float(target)


def _failures(
    dlambda_m: np.ndarray, target_m: float, tilt_rad: np.ndarray, target_rad: float | None
) -> np.ndarray:
    """Which entries fail: unsolved, beyond Δλ*, or (a joint claim) beyond Δα*."""
    failed = np.where(np.isfinite(dlambda_m), dlambda_m > target_m, True)
    if target_rad is not None:
        failed |= np.where(np.isfinite(tilt_rad), tilt_rad > target_rad, True)
    return np.asarray(failed, dtype=bool)


def _mechanism_settings(design: DesignResult) -> CalibrationSettings:
    mech = design.mechanism
    path = (mech.root / "mechanism.toml") if mech.root is not None else "<mechanism>"
    return settings_from_table(dict(mech.extra.get("calibration") or {}), path)


def _per_machine(
    outcomes: list[MachineOutcome], mode: str, axis: np.ndarray, rotations: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[tuple[int, str], ...]]:
    """Per machine and pose (K, m): exact and linear Δλ [m], exact and linear Δα [rad]; the unconverged.

    The linear Δα is the study's under ``calibrated`` (NaN otherwise: the study keeps the linear
    rotation of its calibrations only).
    """
    exact, linear, tilt, linear_tilt, bad = [], [], [], [], []
    for k, o in enumerate(outcomes):
        nan = np.full(o.before.dlambda_m.shape, np.nan)
        if mode == "calibrated":
            case = o.cases[0]
            if not case.converged:  # as its controller was left (NaN if the fit raised)
                bad.append((k, case.failure or "not converged"))
            errors = case.errors
            lin = PoseErrors(case.linear_position_m, case.linear_rotation_rad, np.ones(len(nan), dtype=bool))
            linear.append(lin.dlambda_m)
            linear_tilt.append(lin.tilt_rad(axis, rotations))
        else:
            errors = o.ideal if mode == "ideal" else o.before
            linear.append(np.linalg.norm(o.ideal_linear_m, axis=1) if mode == "ideal" else nan)
            linear_tilt.append(nan)
        exact.append(errors.dlambda_m)
        tilt.append(errors.tilt_rad(axis, rotations))
    m = outcomes[0].before.dlambda_m.size if outcomes else 0
    as_array = lambda rows: np.array(rows) if rows else np.zeros((0, m))  # noqa: E731
    return as_array(exact), as_array(linear), as_array(tilt), as_array(linear_tilt), tuple(bad)


def _linear_failures(
    maps: AccuracyMaps,
    unc: np.ndarray,
    sigma: np.ndarray,
    target_m: float,
    orientation: tuple[np.ndarray, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per pose: the linear model's failure at ``sigma`` and the tracker noise's alone (m,) each.

    With ``orientation = (tool axis, Δα*)``: the joint failure of Δλ and Δα (the claim's reliability,
    :func:`pkmtol.design.orientation.joint_reliability`).
    """
    cols = np.asarray(unc, dtype=int)
    if orientation is not None:
        sub = maps.subset(cols)
        axis, target_rad = orientation
        r = joint_reliability(joint_covariance(sub, sigma[cols], axis), target_m, target_rad)
        r0 = joint_reliability(joint_covariance(sub, np.zeros(cols.size), axis), target_m, target_rad)
        return np.clip(1.0 - r, 0.0, 1.0), np.clip(1.0 - r0, 0.0, 1.0)
    noise_cov = None
    if maps.position_noise.shape[2] and maps.noise_m > 0:
        N = maps.position_noise
        noise_cov = maps.noise_m**2 * (N @ np.swapaxes(N, 1, 2))
    r = grid_reliability(maps.position[:, :, cols], sigma[cols], target_m, noise_cov)
    predicted = np.clip(1.0 - r, 0.0, 1.0)  # the quadrature's round-off can pass 1
    noise = np.zeros(len(predicted))
    if noise_cov is not None:
        noise = np.clip(1.0 - exact_reliability_many(noise_cov, target_m)[0], 0.0, 1.0)
    return predicted, noise


def _blocked(p: PoseCheck, why: str) -> PoseCheck:
    """``p`` as ``cannot hold here`` for ``why`` (a pose without a claim stays as it is)."""
    if p.verdict == "no claim here":
        return p
    return dataclasses.replace(p, verdict="cannot hold here", reason=why)


def _pose_check(
    k: int,
    point_m: np.ndarray,
    claimed: float,
    predicted: float,
    exact_m: np.ndarray,
    linear_m: np.ndarray,
    noise_failure: float,
    target_m: float,
    tilt_rad: np.ndarray | None = None,
    linear_tilt_rad: np.ndarray | None = None,
    target_rad: float | None = None,
) -> PoseCheck:
    """One pose: failures across machines, Wilson interval, verdict.

    ``tilt_rad`` / ``linear_tilt_rad`` (K,): the machines' exact and linear Δα [rad] (None: not
    measured); ``target_rad``: Δα* of a joint claim (None: Δλ alone is judged).
    """
    K = exact_m.size
    nan = np.full(K, np.nan)
    tilt = nan if tilt_rad is None else np.asarray(tilt_rad, dtype=float)
    unsolved = int(np.sum(~np.isfinite(exact_m)))
    fails = int(np.sum(_failures(exact_m, target_m, tilt, target_rad)))
    low, high = wilson_interval(fails, K)
    gap_m = _row_gap(exact_m, linear_m)
    tilt_gap = _row_gap(tilt, nan if linear_tilt_rad is None else np.asarray(linear_tilt_rad, dtype=float))
    valid = not gap_m > LINEAR_VALIDITY * target_m
    if target_rad is not None:
        valid = valid and not tilt_gap > LINEAR_VALIDITY * target_rad
    reason = ""
    if not np.isfinite(claimed):
        verdict, reason = "no claim here", "the design claims nothing at this pose"
    elif claimed >= low:
        verdict = "holds"
    elif noise_failure > claimed:
        verdict = "cannot hold here"
        reason = f"beyond the noise floor: the tracker noise alone fails {100 * noise_failure:.2f} % here"
    elif unsolved:
        verdict = "cannot hold here"
        reason = f"{unsolved} of {K} machines cannot be assembled or commanded here"
    else:
        verdict = "fails"
    solved_tilt = tilt[np.isfinite(tilt)]
    tilt_share = float("nan")
    if target_rad is not None and K:
        tilt_share = float(np.mean(np.where(np.isfinite(tilt), tilt > target_rad, True)))
    return PoseCheck(
        index=k,
        point_m=np.asarray(point_m, dtype=float),
        claimed=float(claimed),
        predicted=float(predicted),
        measured=fails / K if K else float("nan"),
        low=low,
        high=high,
        machines=K,
        unsolved=unsolved,
        noise_failure=float(noise_failure),
        linear_gap_m=gap_m,
        linear_valid=valid,
        verdict=verdict,
        reason=reason,
        mean_tilt_rad=float(solved_tilt.mean()) if solved_tilt.size else float("nan"),
        tilt_measured=tilt_share,
        tilt_gap_rad=tilt_gap,
    )


def _row_gap(exact_m: np.ndarray, linear_m: np.ndarray) -> float:
    """Largest ``|mean|``, ``|p95|``, ``|p99|`` difference of two samples (Δλ [m] or Δα [rad]; NaN: none)."""
    ok = np.isfinite(exact_m) & np.isfinite(linear_m)
    if not ok.any():
        return float("nan")
    e, lin = exact_m[ok], linear_m[ok]
    gaps = [abs(float(e.mean() - lin.mean()))]
    tails = zip(quantiles(e, (0.95, 0.99)), quantiles(lin, (0.95, 0.99)), strict=True)
    gaps += [abs(a - b) for a, b in tails]
    return float(max(gaps))
