"""Designs that meet their reliability target exactly, and the claimed-vs-true comparison.

FOSM treats ``Δλ = ‖J η_c‖`` as a normal variable; it is a norm. For Gaussian errors the exact
``R = P(Δλ ≤ Δλ*)`` at a pose is :func:`pkmtol.design.reliability.exact_reliability` of
``Σ = J diag(σ²) Jᵀ``. :func:`scale_design` keeps the equal-effect *shape* ``σ_i ∝ 1/ω_i`` and
scales it by root finding so that the exact R equals the target at the worst pose, at every grid
pose (the minimum over the grid), or on average over the grid.

:func:`claimed_vs_true` runs the exact reliabilities of each β on an executor (one chunk per β)
and draws its Monte Carlo cells in the caller, in chunks of :data:`LINEAR_CHUNK` samples from the
caller's generator, β by β and cell by cell as one draw per cell would.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import special

from pkmtol.design.reliability import exact_reliability_many
from pkmtol.design.verification import LINEAR_CHUNK, cyclic_products, failure_counts, sample_errors
from pkmtol.error_model.accuracy import vector_norms
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.exceptions import InvalidRequestError
from pkmtol.executor import Executor, map_chunks

CRITERIA = ("worst", "every", "average")


def grid_reliability(
    J: np.ndarray, sigma: np.ndarray, target_m: float, extra_cov: np.ndarray | None = None
) -> np.ndarray:
    """Exact Gaussian reliability at each pose: ``J`` (m, 3, k), ``σ`` (k,) → (m,).

    ``extra_cov`` (m, 3, 3) [m²] is a fixed covariance added at each pose (the tracker noise left by
    a calibration, ``σ_m² N Nᵀ``).
    """
    a = J * np.asarray(sigma)[None, None, :]
    cov = a @ np.swapaxes(a, 1, 2)
    if extra_cov is not None:
        cov = cov + extra_cov
    return exact_reliability_many(cov, target_m)[0]


def criterion_value(r: np.ndarray, criterion: str, worst_index: int) -> float:
    """The reliability a criterion looks at: the worst pose's, the minimum, or the mean."""
    if criterion == "worst":
        return float(r[worst_index])
    if criterion == "every":
        return float(r.min())
    if criterion == "average":
        return float(r.mean())
    raise InvalidRequestError(f"unknown criterion {criterion!r}; use one of {', '.join(CRITERIA)}")


@dataclass(frozen=True)
class ScaledDesign:
    """An equal-effect design scaled to meet a reliability target exactly.

    Attributes:
        sigma: Tolerances (k,) [SI].
        scale: Factor applied to the input shape.
        reliability: Exact Gaussian R at each grid pose (m,).
        criterion: ``worst``, ``every`` or ``average``.
        target_reliability: R*.
    """

    sigma: np.ndarray
    scale: float
    reliability: np.ndarray
    criterion: str
    target_reliability: float


def scale_design(
    J: np.ndarray,
    shape: np.ndarray,
    target_m: float,
    r_star: float,
    criterion: str,
    worst_index: int,
    extra_cov: np.ndarray | None = None,
) -> ScaledDesign:
    """Scale ``shape`` (k,) so that the criterion's exact reliability equals ``r_star``.

    Args:
        J: Grid maps (m, 3, k) of the toleranced parameters.
        shape: Design shape (k,), e.g. the FOSM tolerances; parameters with ``inf`` stay free.
        target_m: Δλ* [m].
        r_star: Target reliability in (0, 1).
        criterion: ``worst`` / ``every`` / ``average``.
        worst_index: Grid index of the design point (for ``worst``).
        extra_cov: Fixed covariance (m, 3, 3) added at each pose [m²] (calibration noise).

    Raises:
        InvalidRequestError: the target cannot be reached at any scale (e.g. the noise alone
            exceeds it), or is reached at every scale.
    """
    if not 0.0 < r_star < 1.0:
        raise InvalidRequestError(f"target reliability must be in (0, 1), got {r_star}")
    shape = np.asarray(shape, dtype=float)
    finite = np.isfinite(shape)
    base = np.where(finite, shape, 0.0)  # a free parameter has no effect on Δλ at these poses
    Jsel = J if criterion != "worst" else J[worst_index : worst_index + 1]
    Esel = (
        None
        if extra_cov is None
        else (extra_cov if criterion != "worst" else extra_cov[worst_index : worst_index + 1])
    )
    w_idx = worst_index if criterion != "worst" else 0

    def excess(log_s: float) -> float:
        r = grid_reliability(Jsel, base * math.exp(log_s), target_m, Esel)
        return criterion_value(r, criterion, w_idx) - r_star

    lo, hi = bracket_log_scale(
        excess,
        60.0,
        "no scale of the tolerances reaches the target reliability: what no tolerance changes "
        "(the calibration's measurement noise) already exceeds it; measure more poses, use a "
        "more precise tracker, or relax Δλ* or β",
        "the design reaches the target at any scale: Δλ does not depend on it",
    )
    if criterion == "every" and len(Jsel) > 1:
        log_s = _every_root(Jsel, Esel, base, target_m, r_star, lo, hi)
    else:
        log_s = find_root(excess, lo, hi)
    s = math.exp(log_s)
    sigma = np.where(finite, shape * s, np.inf)
    return ScaledDesign(
        sigma=sigma,
        scale=s,
        reliability=grid_reliability(J, base * s, target_m, extra_cov),
        criterion=criterion,
        target_reliability=r_star,
    )


def find_root(f: Callable[[float], float], lo: float, hi: float, xtol: float = 1e-12) -> float:
    """A root of ``f`` in ``[lo, hi]`` (``f(lo)`` and ``f(hi)`` of opposite signs or zero), to ``xtol``.

    The Illinois variant of regula falsi: a secant step, with the retained end's value halved when
    the same end is kept twice, so that it converges superlinearly and always stays bracketed
    (the default design finds its scale without importing scipy.optimize, a sixth of the
    command's CPU). Stops when the bracket is narrower than ``xtol · (1 + |x|)`` or f is 0.

    >>> round(find_root(lambda x: x * x - 2.0, 0.0, 2.0), 12)
    1.414213562373
    """
    f_lo, f_hi = f(lo), f(hi)
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if (f_lo > 0) == (f_hi > 0):
        raise InvalidRequestError(f"no sign change of the reliability excess between {lo} and {hi}")
    side = 0
    x = lo
    for _ in range(200):
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < x < hi:  # round-off at the bracket's end: bisect
            x = 0.5 * (lo + hi)
        fx = f(x)
        if fx == 0.0:
            return x
        if (fx > 0) == (f_lo > 0):
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        if hi - lo <= xtol * (1.0 + abs(x)):
            break
    return x


def _call_with(f: Callable[[float, np.ndarray], float], rows: np.ndarray, x: float) -> float:
    return f(x, rows)


def bracket_log_scale(
    excess: Callable[[float], float], limit: float, never: str, always: str
) -> tuple[float, float]:
    """A bracket ``(lo, hi)`` of log scales with ``excess(lo) ≥ 0 ≥ excess(hi)`` (excess falls as it grows).

    The bracket starts at ±1 and widens by 2 until it holds, up to ``±limit``.

    Raises:
        InvalidRequestError: ``never`` if no scale down to ``e^−limit`` has a non-negative excess,
            ``always`` if none up to ``e^limit`` has a non-positive one.
    """
    lo, hi = -1.0, 1.0
    while excess(lo) < 0:
        lo -= 2.0
        if lo < -limit:
            raise InvalidRequestError(never)
    while excess(hi) > 0:
        hi += 2.0
        if hi > limit:
            raise InvalidRequestError(always)
    return lo, hi


def _every_root(
    J: np.ndarray,
    extra: np.ndarray | None,
    base: np.ndarray,
    target_m: float,
    r_star: float,
    lo: float,
    hi: float,
) -> float:
    """The scale at which the minimum over the poses of R reaches R*, on a growing set of poses.

    Every R_j falls as the scale grows, so the root over a subset of poses lies at or above the
    root over all of them. Start from the poses least reliable at ``hi``; find the subset's root;
    check every pose there; if one falls short, add the ones that do and search again below. At
    the end the subset holds the pose that binds, and its root is the whole grid's (to find_root's
    1e-12), in a few passes over the grid instead of one per root-finding step.
    """

    def sub_excess(log_s: float, rows: np.ndarray) -> float:
        Es = None if extra is None else extra[rows]
        return float(grid_reliability(J[rows], base * math.exp(log_s), target_m, Es).min()) - r_star

    r_hi = grid_reliability(J, base * math.exp(hi), target_m, extra)  # R = 1 everywhere at lo, often
    rows = np.sort(np.argsort(r_hi)[:8])  # holds the argmin at hi: the subset brackets its root
    while True:
        root = find_root(functools.partial(_call_with, sub_excess, rows), lo, hi)
        r_all = grid_reliability(J, base * math.exp(root), target_m, extra)
        short = np.setdiff1d(np.flatnonzero(r_all < r_star - 1e-12), rows)
        if not short.size:
            return root
        rows = np.union1d(rows, short)
        hi = root  # the whole grid's root lies below the subset's


@dataclass(frozen=True)
class ClaimRow:
    """Claimed vs true reliability of one FOSM design (one β).

    Attributes:
        beta: β.
        claimed: Φ(β).
        exact_worst: Exact Gaussian R at the worst pose.
        exact_task_space: Exact Gaussian R averaged over the task-space poses given.
        exact_task_space_min: Its minimum over those poses.
        uniform_sigma_worst: Monte Carlo R at the worst pose, errors uniform on ±σ (and 95 % CI).
        uniform_sqrt3_worst: The same, uniform on ±√3σ.
        uniform_sigma_task_space: Monte Carlo R over the task space, uniform ±σ.
        uniform_sqrt3_task_space: Monte Carlo R over the task space, uniform ±√3σ.
    """

    beta: float
    claimed: float
    exact_worst: float
    exact_task_space: float
    exact_task_space_min: float
    uniform_sigma_worst: tuple[float, float, float]
    uniform_sqrt3_worst: tuple[float, float, float]
    uniform_sigma_task_space: tuple[float, float, float]
    uniform_sqrt3_task_space: tuple[float, float, float]


def _noise_draws(cov: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Gaussian vectors (samples, 3) of covariance ``cov`` (3, 3), or of ``cov[s % m]`` for (m, 3, 3)."""
    covs = cov[None] if cov.ndim == 2 else cov
    lam, vec = np.linalg.eigh(covs)
    root = vec * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]
    idx = np.arange(samples) % covs.shape[0]
    return np.einsum("sij,sj->si", root[idx], rng.standard_normal((samples, 3)))


def claimed_vs_true(
    J_worst: np.ndarray,
    J_task: np.ndarray,
    tolerances: np.ndarray,
    betas: tuple[float, ...],
    target_m: float,
    samples: int,
    rng: np.random.Generator,
    extra_cov_worst: np.ndarray | None = None,
    extra_cov_task: np.ndarray | None = None,
    executor: Executor | None = None,
) -> list[ClaimRow]:
    """Claimed ``Φ(β)`` vs exact and Monte Carlo reliabilities of the FOSM designs.

    Args:
        J_worst: Map at the worst pose (3, k).
        J_task: Maps at task-space poses (m, 3, k) (random points, uniform in the volume).
        tolerances: FOSM tolerances (k, len(betas)); a column of NaN (a β the noise floor makes
            unreachable) is skipped.
        betas: β series.
        target_m: Δλ* [m].
        samples: Monte Carlo samples per cell.
        rng: Random generator.
        extra_cov_worst: Fixed covariance (3, 3) at the worst pose [m²] (calibration noise).
        extra_cov_task: Fixed covariance (m, 3, 3) at the task-space poses [m²].
        executor: Where the exact reliabilities run, one chunk per β (None: serial).
    """
    ew = None if extra_cov_worst is None else extra_cov_worst[None]
    noisy = extra_cov_worst is not None or extra_cov_task is not None
    # with noise draws after each cell's errors, a cell is one chunk (the stream of one draw)
    chunk = samples if noisy else LINEAR_CHUNK
    kept = [(b, np.where(np.isfinite(sg), sg, 0.0)) for b, sg in zip(betas, tolerances.T, strict=True)]
    kept = [(b, s) for b, s in kept if not np.any(np.isnan(s))]
    tasks = [(J_worst, J_task, s, target_m, ew, extra_cov_task) for _, s in kept]
    exact = map_chunks(_exact_cells, tasks, executor)
    rows = []
    for (b, s), (r_worst, r_task) in zip(kept, exact, strict=True):
        cells = []
        for dist in ("uniform_sigma", "uniform_sqrt3_sigma"):
            fail_w = fail_t = 0
            for start in range(0, samples, chunk):
                count = min(chunk, samples - start)
                eta = sample_errors(dist, s, count, rng)
                e_w = eta @ J_worst.T
                e_t = cyclic_products(J_task, eta, start)
                if extra_cov_worst is not None:
                    e_w = e_w + _noise_draws(extra_cov_worst, count, rng)
                if extra_cov_task is not None:
                    e_t = e_t + _noise_draws(extra_cov_task, count, rng)
                fail_w += int(np.sum(vector_norms(e_w) > target_m))
                fail_t += int(np.sum(vector_norms(e_t) > target_m))
            for fails in (fail_w, fail_t):
                f = failure_counts(fails, samples)
                cells.append((f.reliability, 1.0 - f.failure_ci95[1], 1.0 - f.failure_ci95[0]))
        rows.append(
            ClaimRow(
                beta=b,
                claimed=float(special.ndtr(b)),
                exact_worst=r_worst,
                exact_task_space=float(r_task.mean()),
                exact_task_space_min=float(r_task.min()),
                uniform_sigma_worst=cells[0],
                uniform_sigma_task_space=cells[1],
                uniform_sqrt3_worst=cells[2],
                uniform_sqrt3_task_space=cells[3],
            )
        )
    return rows


def _exact_cells(task: tuple) -> tuple[float, np.ndarray]:
    """Exact reliability at the worst pose and at each task-space pose of one design (a chunk)."""
    J_worst, J_task, s, target_m, ew, et = task
    return float(grid_reliability(J_worst[None], s, target_m, ew)[0]), grid_reliability(
        J_task, s, target_m, et
    )


def noise_covariance(maps: AccuracyMaps) -> np.ndarray | None:
    """``σ_m² N Nᵀ`` per pose (m, 3, 3) [m²], or None without a calibration."""
    if not maps.position_noise.shape[2] or maps.noise_m <= 0:
        return None
    N = maps.position_noise
    return maps.noise_m**2 * (N @ np.swapaxes(N, 1, 2))


def claims_stage(
    maps: AccuracyMaps,
    random_maps: AccuracyMaps,
    worst: int,
    unc: np.ndarray,
    tolerances: np.ndarray,
    betas: tuple[float, ...],
    target_m: float,
    samples: int,
    rng: np.random.Generator,
    claim_poses: int,
    executor: Executor | None = None,
) -> list[ClaimRow]:
    """The claims stage: :func:`claimed_vs_true` of the FOSM designs of the β series.

    At the design pose ``worst`` of the grid ``maps`` and over the first ``claim_poses`` random
    task-space poses of ``random_maps``; ``tolerances`` is (n_params, len(betas)), ``unc`` its rows
    that are toleranced; the calibration's noise enters as a fixed covariance.
    """
    cov = noise_covariance(maps)
    rnd_cov = noise_covariance(random_maps)
    return claimed_vs_true(
        maps.position[worst][:, unc],
        random_maps.position[:claim_poses][:, :, unc],
        tolerances[unc],
        betas,
        target_m,
        samples,
        rng,
        None if cov is None else cov[worst],
        None if rnd_cov is None else rnd_cov[:claim_poses],
        executor=executor,
    )
