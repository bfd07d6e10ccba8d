"""Monte Carlo: the most error-sensitive pose (paper §4.3) and verification of a design (§4.4).

Verification samples errors from three distributions, all reported:

* ``uniform_sigma``: uniform on ``±σ_i`` — the paper's choice (variance ``σ_i²/3``: a third of the
  design's, so it passes almost regardless);
* ``uniform_sqrt3_sigma``: uniform on ``±√3 σ_i`` (variance-matched);
* ``gaussian``: ``N(0, σ_i²)`` (variance-matched, the FOSM model's own assumption).

Each sample takes a random point of the task space (inverse kinematics there) and random errors;
``Δλ`` comes from the linear model for every sample and, on a subsample, from exact kinematics of
the perturbed mechanism with the Eq. 25 actuator correction applied (the truth).

The linear samples are drawn and evaluated in chunks of :data:`LINEAR_CHUNK` (the same random
stream as one draw: a chunk takes the next rows), so the working memory does not grow with the
sample count; only Δλ (8 bytes a sample) is kept. A sample's map is not gathered: the samples of
whole cycles of poses are multiplied pose by pose (:func:`cyclic_products`). The exact subsample
runs in chunks of :data:`EXACT_CHUNK` on an :class:`pkmtol.executor.Executor`, each chunk one
batched forward solve (:class:`pkmtol.kinematics.batch.BatchChain`); the chunks do not depend on
the executor, so neither do the numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

import pkmtol.values as values
from pkmtol.calibration.study import LINEAR_VALIDITY
from pkmtol.error_model.accuracy import vector_norms
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.exceptions import ConvergenceError, KinematicsError
from pkmtol.executor import Executor, imap_chunks
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.mechanism import Mechanism
from pkmtol.statistics import quantiles, wilson_interval

DISTRIBUTIONS = ("uniform_sigma", "uniform_sqrt3_sigma", "gaussian")


def check_sigma(sigma: object, size: int) -> np.ndarray:
    """Tolerances (size,) checked: ≥ 0, no nan (``inf`` marks a free parameter) [m, rad]."""
    sig = values.array_of_shape("sigma", sigma, (size,), finite=False)
    if np.any(np.isnan(sig)) or np.any(sig < 0) or np.any(sig[np.isfinite(sig)] > values.MAX_LENGTH_M):
        raise values.InvalidArgumentError(
            "sigma", sigma, "every tolerance must be in [0, 1e4] (m, rad) or inf (free)"
        )
    return sig


#: Linear-model samples drawn and evaluated at a time.
LINEAR_CHUNK = 65_536
#: Exact-kinematics samples per chunk of work (one batched forward solve).
EXACT_CHUNK = 500


def sample_errors(distribution: str, sigma: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """Error samples of shape (count, n) for per-parameter tolerances ``sigma`` (n,)."""
    sigma = np.asarray(sigma, dtype=float)
    if distribution == "uniform_sigma":
        return rng.uniform(-1.0, 1.0, (count, sigma.size)) * sigma
    if distribution == "uniform_sqrt3_sigma":
        return rng.uniform(-1.0, 1.0, (count, sigma.size)) * (math.sqrt(3.0) * sigma)
    if distribution == "gaussian":
        return rng.standard_normal((count, sigma.size)) * sigma
    raise ValueError(f"unknown distribution {distribution!r}; use one of {DISTRIBUTIONS}")


def cyclic_products(maps: np.ndarray, x: np.ndarray, start: int) -> np.ndarray:
    """Rows ``maps[(start + s) mod m] @ x[s]`` (count, r) for maps (m, r, n) and samples ``x`` (count, n).

    Sample ``s`` of a Monte Carlo run uses pose ``s mod m``. Gathering each sample's map (24 bytes
    per sample and error for r = 3) and contracting it cost most of a linear cell; instead, the
    whole cycles of poses in ``x`` are one stacked product per pose (``m`` products of
    (cycles, n) @ (n, r)), and only the rows before the first whole cycle and after the last are
    gathered. The rows agree with the gathered product to round-off (the sums run in another order).
    """
    m, count = len(maps), len(x)
    out = np.empty((count, maps.shape[1]))
    head = min((-start) % m, count)
    full = (count - head) // m
    body = slice(head, head + full * m)
    if head:
        out[:head] = np.einsum("sij,sj->si", maps[(start + np.arange(head)) % m], x[:head])
    if full:
        cycles = x[body].reshape(full, m, -1).transpose(1, 0, 2)  # (m, cycles, n)
        prod = np.matmul(cycles, maps.transpose(0, 2, 1))  # (m, cycles, r)
        out[body] = prod.transpose(1, 0, 2).reshape(full * m, -1)
    if body.stop < count:
        out[body.stop :] = np.einsum("sij,sj->si", maps[np.arange(count - body.stop) % m], x[body.stop :])
    return out


@dataclass(frozen=True)
class FailureStats:
    """Statistics of Δλ over samples.

    Attributes:
        mean_m: Mean Δλ [m].
        std_m: Standard deviation of Δλ [m].
        failure_fraction: Fraction of samples with Δλ > Δλ*.
        failure_ci95: Wilson 95 % interval of the failure probability.
        reliability: ``1 − failure_fraction``.
        samples: Number of samples.
    """

    mean_m: float
    std_m: float
    failure_fraction: float
    failure_ci95: tuple[float, float]
    reliability: float
    samples: int


def failure_stats(dlam: np.ndarray, target_m: float) -> FailureStats:
    """Summarise Δλ samples against Δλ*."""
    n = int(dlam.size)
    return failure_counts(
        int(np.sum(dlam > target_m)),
        n,
        float(dlam.mean()),
        float(dlam.std(ddof=1)) if n > 1 else 0.0,
    )


def failure_counts(failures: int, n: int, mean_m: float = math.nan, std_m: float = math.nan) -> FailureStats:
    """:class:`FailureStats` from a failure count ``failures`` out of ``n`` samples (Wilson interval)."""
    p = failures / n
    return FailureStats(
        mean_m=mean_m,
        std_m=std_m,
        failure_fraction=p,
        failure_ci95=wilson_interval(failures, n),
        reliability=1.0 - p,
        samples=n,
    )


@dataclass(frozen=True)
class Verification:
    """Verification of one design under one error distribution.

    Attributes:
        distribution: One of :data:`DISTRIBUTIONS`.
        linear: Statistics of the linear model over all samples.
        exact: Statistics of exact kinematics over the subsample (None if not run).
        linear_subsample: Statistics of the linear model over the same subsample.
        max_relative_difference: Largest ``|Δλ_exact − Δλ_linear| / Δλ*`` over the subsample.
        dlam_linear_m: Linear Δλ of every sample [m] (for figures).
        pose_points_m: Shape (m, 3): the distinct task-space points; sample ``s`` is at
            ``pose_points_m[s mod m]`` [m].
        exact_unassembled: Samples of the exact subsample whose perturbed mechanism cannot be
            closed (an over-constrained mechanism with errors no rigid motion satisfies: assembly
            errors); they are left out of ``exact``, ``linear_subsample`` and the difference.
        dlam_exact_m: Exact Δλ of the subsample [m] (nan where unassembled; empty if not run).
        tilt_linear_rad: Linear tilt Δα of the tool axis of every sample [rad] (None unless the
            orientation is verified).
        tilt: Statistics of the linear Δα against Δα* (values in rad; None without a target).
        tilt_exact: The same on the exact subsample.
        joint: Linear statistics of ``max(Δλ/Δλ*, Δα/Δα*)`` against 1: its failure fraction is
            ``P(Δλ > Δλ* or Δα > Δα*)`` (None without an orientation target).
        target_m: Δλ* [m] (the linear-validity check's scale).
    """

    distribution: str
    linear: FailureStats
    exact: FailureStats | None
    linear_subsample: FailureStats | None
    max_relative_difference: float
    dlam_linear_m: np.ndarray
    pose_points_m: np.ndarray
    exact_unassembled: int = 0
    dlam_exact_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tilt_linear_rad: np.ndarray | None = None
    tilt: FailureStats | None = None
    tilt_exact: FailureStats | None = None
    joint: FailureStats | None = None
    target_m: float = float("nan")

    @property
    def linear_gap_m(self) -> float:
        """Largest gap of the row figures (mean, p95, p99 of Δλ), exact against linear [m].

        On the same subsample; NaN without one (the study's measure, LINEAR_VALIDITY).
        """
        k = self.dlam_exact_m.size
        ok = np.isfinite(self.dlam_exact_m)
        if not k or not ok.any():
            return float("nan")
        return row_gap_m(self.dlam_exact_m[ok], self.dlam_linear_m[:k][ok])

    @property
    def linear_valid(self) -> bool:
        """Whether the linear figures are within :data:`LINEAR_VALIDITY` of Δλ* of the exact ones."""
        return not self.linear_gap_m > LINEAR_VALIDITY * self.target_m

    @property
    def points_m(self) -> np.ndarray:
        """Shape (samples, 3): the point of every sample [m] (made on demand)."""
        m = len(self.pose_points_m)
        return self.pose_points_m[np.arange(self.dlam_linear_m.size) % m]


def row_gap_m(exact_m: np.ndarray, linear_m: np.ndarray) -> float:
    """Largest difference of mean, p95 and p99 of Δλ between exact and linear samples [m].

    The measure of the calibration study's linear-validity check
    (:attr:`pkmtol.calibration.study.ErrorSummary.linear_gap_m`), on two sample arrays.
    """
    (e95, e99), (l95, l99) = quantiles(exact_m, (0.95, 0.99)), quantiles(linear_m, (0.95, 0.99))
    gaps = [abs(float(np.mean(exact_m)) - float(np.mean(linear_m))), abs(e95 - l95), abs(e99 - l99)]
    return float(np.nanmax(gaps))


def verify(
    mechanism: Mechanism,
    pset: ParameterSet,
    sweep_random: Sweep,
    columns: np.ndarray,
    sigma: np.ndarray,
    target_m: float,
    distribution: str,
    samples: int,
    exact_samples: int,
    rng: np.random.Generator,
    progress: bool = False,
    executor: Executor | None = None,
) -> Verification:
    """Verify tolerances ``sigma`` (one per parameter in ``columns``) by Monte Carlo.

    Args:
        mechanism: The mechanism.
        pset: Its parameter set.
        sweep_random: Separations at random task-space points; sample ``s`` uses point
            ``s mod m``.
        columns: Indices (into ``pset``) of the toleranced parameters; the others are zero.
        sigma: Tolerances of those parameters (SI); a free parameter (``inf``: zero sensitivity
            at the design point) is held at zero, as in :mod:`pkmtol.design.exact`.
        target_m: Δλ* [m].
        distribution: One of :data:`DISTRIBUTIONS`.
        samples: Number of linear-model samples.
        exact_samples: Size of the exact-kinematics subsample (the first samples).
        rng: Random generator.
        progress: Show a progress bar for the exact subsample.
        executor: Where the exact chunks run (None: serial).
    """
    values.choice("distribution", distribution, DISTRIBUTIONS)
    return verify_all(
        mechanism,
        pset,
        sweep_random,
        columns,
        sigma,
        target_m,
        samples,
        exact_samples,
        rng,
        progress,
        executor,
        distributions=(distribution,),
    )[distribution]


def verify_all(
    mechanism: Mechanism,
    pset: ParameterSet,
    sweep_random: Sweep,
    columns: np.ndarray,
    sigma: np.ndarray,
    target_m: float,
    samples: int,
    exact_samples: int,
    rng: np.random.Generator,
    progress: bool = False,
    executor: Executor | None = None,
    distributions: tuple[str, ...] = DISTRIBUTIONS,
) -> dict[str, Verification]:
    """:func:`verify` for several distributions, their exact chunks run as one batch of work.

    The random numbers are drawn in the order of ``distributions`` (each its ``samples`` rows),
    as one call of :func:`verify` per distribution would; the arguments are :func:`verify`'s.

    Raises:
        KinematicsError: an exact sample failed for another reason than assembly (the first such
            sample in order); :class:`ConvergenceError` counts as unassembled.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism")
    values.instance("pset", pset, ParameterSet, "the mechanism's ParameterSet (pkmtol.parameter_set)")
    values.instance("sweep_random", sweep_random, Sweep, "a pkmtol.Sweep (pkmtol.sweep)")
    columns = values.indices("columns", columns, len(pset))
    sigma = check_sigma(sigma, len(columns))
    target_m = values.length_m("target_m", target_m)
    values.count("samples", samples, low=1, high=values.MAX_SAMPLES)
    values.count("exact_samples", exact_samples, low=0, high=values.MAX_SAMPLES)
    values.generator("rng", rng)
    values.flag("progress", progress)
    values.optional(values.instance, "executor", executor, Executor, "a pkmtol.executor.Executor or None")
    for d in distributions:
        values.choice("distributions", d, DISTRIBUTIONS)
    m = len(sweep_random.poses)
    sig = np.where(np.isfinite(sigma), sigma, 0.0)
    Jc = sweep_random.J[:, :, columns]  # (m, 3, k)
    k = min(exact_samples, samples) if exact_samples > 0 else 0
    linear, heads = {}, {}
    for dist in distributions:
        linear[dist], heads[dist] = _linear_dlam(Jc, sig, dist, samples, rng, k)
    exact: dict[str, np.ndarray] = {}
    if k:
        tasks, owners = [], []
        for dist in distributions:
            for start in range(0, k, EXACT_CHUNK):
                rows = np.arange(start, min(start + EXACT_CHUNK, k))
                tasks.append(_exact_task(mechanism, pset, sweep_random, columns, heads[dist][rows], rows % m))
                owners.append(dist)
        bar = tqdm(total=len(tasks) * 1, desc="exact chunks", unit="chunk", disable=not progress, leave=False)
        parts: dict[str, list[np.ndarray]] = {d: [] for d in distributions}
        for dist, (chunk_values, error) in zip(
            owners, imap_chunks(_exact_chunk, tasks, executor), strict=True
        ):
            if error is not None:
                raise error
            parts[dist].append(chunk_values)
            bar.update(1)
        bar.close()
        exact = {d: np.concatenate(parts[d]) for d in distributions}
    return {
        d: _verification(d, linear[d], exact.get(d), k, sweep_random.points_m, target_m)
        for d in distributions
    }


def _linear_dlam(
    Jc: np.ndarray, sigma: np.ndarray, distribution: str, samples: int, rng: np.random.Generator, keep: int
) -> tuple[np.ndarray, np.ndarray]:
    """Linear Δλ (samples,) in chunks, and the first ``keep`` error rows (keep, k) for the exact part."""
    dlam = np.empty(samples)
    head = []
    for start in range(0, samples, LINEAR_CHUNK):
        count = min(LINEAR_CHUNK, samples - start)
        eta = sample_errors(distribution, sigma, count, rng)
        dlam[start : start + count] = vector_norms(cyclic_products(Jc, eta, start))
        if start < keep:
            head.append(eta[: keep - start])
    return dlam, (np.concatenate(head) if head else np.zeros((0, Jc.shape[2])))


def _verification(
    distribution: str,
    dlam: np.ndarray,
    dl_exact: np.ndarray | None,
    k: int,
    points: np.ndarray,
    target_m: float,
) -> Verification:
    exact = lin_sub = None
    max_diff = float("nan")
    unassembled = 0
    if dl_exact is not None:
        ok = np.isfinite(dl_exact)
        unassembled = int(k - ok.sum())
        if ok.any():
            exact = failure_stats(dl_exact[ok], target_m)
            lin_sub = failure_stats(dlam[:k][ok], target_m)
            max_diff = float(np.max(np.abs(dl_exact[ok] - dlam[:k][ok])) / target_m)
    return Verification(
        distribution=distribution,
        linear=failure_stats(dlam, target_m),
        exact=exact,
        linear_subsample=lin_sub,
        max_relative_difference=max_diff,
        dlam_linear_m=dlam,
        pose_points_m=np.asarray(points),
        exact_unassembled=unassembled,
        dlam_exact_m=dl_exact if dl_exact is not None else np.zeros(0),
        target_m=target_m,
    )


@dataclass(frozen=True, eq=False)
class _ExactTask:
    """One chunk of exact samples: everything a worker needs (picklable).

    Attributes:
        mechanism: The nominal mechanism.
        pset: Its parameter set.
        q0: Shape (c, N): nominal joint values of each sample's pose (the initial guess).
        commands: Shape (c, f): actuator commands, nominal plus the Eq. 25 correction.
        columns: Indices of the toleranced parameters (the others are zero).
        eta: Shape (c, len(columns)): their errors.
        p_nominal_m: Shape (c, 3): nominal position of P [m].
        skip: Shape (c,): samples whose linear model already says they cannot be assembled.
    """

    mechanism: Mechanism
    pset: ParameterSet
    q0: np.ndarray
    commands: np.ndarray
    columns: np.ndarray
    eta: np.ndarray
    p_nominal_m: np.ndarray
    skip: np.ndarray


def _exact_task(
    mechanism: Mechanism,
    pset: ParameterSet,
    sweep_: Sweep,
    columns: np.ndarray,
    eta_cols: np.ndarray,
    points: np.ndarray,
) -> _ExactTask:
    c = len(points)
    full = np.zeros((c, len(pset)))
    full[:, columns] = eta_cols
    skip = np.zeros(c, dtype=bool)
    q0, commands, p_nom = [], [], []
    for s, j in enumerate(points):
        pose, sep = sweep_.poses[j], sweep_.separations[j]
        if sep.redundancy and sep.incompatible_map is not None:
            # an over-constrained mechanism assembles only if the incompatible part vanishes;
            # when the linear model already says it does not, Newton cannot close it either
            y = np.vstack([sep.Y_a, sep.Y_c]) @ full[s]
            skip[s] = np.linalg.norm(sep.incompatible_map @ full[s]) > 1e-9 * max(
                float(np.linalg.norm(y)), 1e-300
            )
        q = pose.q_all
        q0.append(q)
        commands.append(q[_actuated(mechanism)] + sep.correction @ full[s])
        p_nom.append(pose.p_m)
    cols = np.asarray(columns, dtype=int)
    return _ExactTask(
        mechanism, pset, np.array(q0), np.array(commands), cols, eta_cols, np.array(p_nom), skip
    )


def _actuated(mechanism: Mechanism) -> np.ndarray:
    offsets = np.cumsum([0] + [lb.nq for lb in mechanism.limbs])
    return np.array([offsets[i] + a for i, lb in enumerate(mechanism.limbs) for a in lb.actuated], dtype=int)


_BATCHES: dict[int, tuple[Mechanism, BatchChain]] = {}


def _batch_for(mechanism: Mechanism) -> BatchChain:
    """A batch solver of ``mechanism`` without limit checks, kept for the chunks that follow."""
    hit = _BATCHES.get(id(mechanism))
    if hit is None or hit[0] is not mechanism:
        if len(_BATCHES) >= 4:
            _BATCHES.clear()
        hit = (mechanism, BatchChain(mechanism, check_limits=False))
        _BATCHES[id(mechanism)] = hit
    return hit[1]


def _exact_chunk(task: _ExactTask) -> tuple[np.ndarray, KinematicsError | None]:
    """Exact Δλ (c,) of a chunk (nan: cannot be assembled) and the first other error, if any."""
    out = np.full(len(task.q0), np.nan)
    run = np.flatnonzero(~task.skip)
    if not run.size:
        return out, None
    full = np.zeros((run.size, len(task.pset)))
    full[:, task.columns] = task.eta[run]
    eps, offsets = task.pset.perturbations(full, task.mechanism)
    sols = _batch_for(task.mechanism).forward(task.commands[run], task.q0[run], offsets, eps)
    for pos, s in enumerate(run):
        err = sols.errors[pos]
        if err is None:
            out[s] = float(np.linalg.norm(task.mechanism.task_error(sols.p_m[pos] - task.p_nominal_m[s])))
        elif not isinstance(err, ConvergenceError):
            return out, err  # cannot be assembled only when Newton does not converge
    return out, None


def exact_position_error(
    mechanism: Mechanism,
    pset: ParameterSet,
    chain: ClosedChain,
    sweep_: Sweep,
    index: int,
    eta: np.ndarray,
) -> float:
    """``‖P_actual − P_nominal‖`` [m] (the task's part) of the perturbed mechanism with Eq. 25 (one sample).

    The actuators are commanded to their nominal values plus ``correction · η`` (the calibrated
    compensation); the perturbed closed chain is solved exactly (the per-pose reference of the
    batched verification).
    """
    pose = sweep_.poses[index]
    sep = sweep_.separations[index]
    eps, offsets = pset.perturbation(eta, mechanism)
    models = perturbed_limb_models(mechanism, eps)
    pchain = ClosedChain(mechanism, models=models, check_limits=False)
    u = pose.q_all[chain.actuated_idx] + sep.correction @ eta
    actual = pchain.forward(u, pose.q_all, offsets)
    return float(np.linalg.norm(mechanism.task_error(actual.p_m - pose.p_m)))
