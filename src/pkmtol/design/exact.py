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

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from pkmtol.design.reliability import exact_reliability_many
from pkmtol.design.verification import LINEAR_CHUNK, failure_counts, sample_errors
from pkmtol.exceptions import InvalidRequestError
from pkmtol.executor import Executor, map_chunks

CRITERIA = ("worst", "every", "average")


def grid_reliability(J: np.ndarray, sigma: np.ndarray, target_m: float) -> np.ndarray:
    """Exact Gaussian reliability at each pose: ``J`` (m, 3, k), ``σ`` (k,) → (m,)."""
    a = J * np.asarray(sigma)[None, None, :]
    cov = a @ np.swapaxes(a, 1, 2)
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
) -> ScaledDesign:
    """Scale ``shape`` (k,) so that the criterion's exact reliability equals ``r_star``.

    Args:
        J: Grid maps (m, 3, k) of the toleranced parameters.
        shape: Design shape (k,), e.g. the FOSM tolerances; parameters with ``inf`` stay free.
        target_m: Δλ* [m].
        r_star: Target reliability in (0, 1).
        criterion: ``worst`` / ``every`` / ``average``.
        worst_index: Grid index of the design point (for ``worst``).
    """
    if not 0.0 < r_star < 1.0:
        raise InvalidRequestError(f"target reliability must be in (0, 1), got {r_star}")
    shape = np.asarray(shape, dtype=float)
    finite = np.isfinite(shape)
    base = np.where(finite, shape, 0.0)  # a free parameter has no effect on Δλ at these poses
    Jsel = J if criterion != "worst" else J[worst_index : worst_index + 1]
    w_idx = worst_index if criterion != "worst" else 0

    def excess(log_s: float) -> float:
        r = grid_reliability(Jsel, base * math.exp(log_s), target_m)
        return criterion_value(r, criterion, w_idx) - r_star

    lo, hi = -1.0, 1.0
    while excess(lo) < 0:
        lo -= 2.0
        if lo < -60:
            raise InvalidRequestError("no scale reaches the target reliability (Δλ does not shrink with σ?)")
    while excess(hi) > 0:
        hi += 2.0
        if hi > 60:
            raise InvalidRequestError("the design reaches the target at any scale: Δλ does not depend on it")
    from scipy import optimize  # only the exact and cost designs find roots; keep it out of start-up

    log_s = optimize.brentq(excess, lo, hi, xtol=1e-12, rtol=1e-12)
    s = math.exp(log_s)
    sigma = np.where(finite, shape * s, np.inf)
    return ScaledDesign(
        sigma=sigma,
        scale=s,
        reliability=grid_reliability(J, base * s, target_m),
        criterion=criterion,
        target_reliability=r_star,
    )


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


def claimed_vs_true(
    J_worst: np.ndarray,
    J_task: np.ndarray,
    tolerances: np.ndarray,
    betas: tuple[float, ...],
    target_m: float,
    samples: int,
    rng: np.random.Generator,
    executor: Executor | None = None,
) -> list[ClaimRow]:
    """Claimed ``Φ(β)`` vs exact and Monte Carlo reliabilities of the FOSM designs.

    Args:
        J_worst: Map at the worst pose (3, k).
        J_task: Maps at task-space poses (m, 3, k) (random points, uniform in the volume).
        tolerances: FOSM tolerances (k, len(betas)).
        betas: β series.
        target_m: Δλ* [m].
        samples: Monte Carlo samples per cell.
        rng: Random generator.
        executor: Where the exact reliabilities run, one chunk per β (None: serial).
    """
    sigmas = [np.where(np.isfinite(sigma), sigma, 0.0) for sigma in tolerances.T]
    exact = map_chunks(_exact_cells, [(J_worst, J_task, s, target_m) for s in sigmas], executor)
    rows = []
    m = J_task.shape[0]
    for b, s, (r_worst, r_task) in zip(betas, sigmas, exact, strict=True):
        cells = []
        for dist in ("uniform_sigma", "uniform_sqrt3_sigma"):
            fail_w = fail_t = 0
            for start in range(0, samples, LINEAR_CHUNK):
                count = min(LINEAR_CHUNK, samples - start)
                eta = sample_errors(dist, s, count, rng)
                dl_w = np.linalg.norm(eta @ J_worst.T, axis=1)
                idx = np.arange(start, start + count) % m
                dl_t = np.linalg.norm(np.einsum("sij,sj->si", J_task[idx], eta), axis=1)
                fail_w += int(np.sum(dl_w > target_m))
                fail_t += int(np.sum(dl_t > target_m))
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


def _exact_cells(task: tuple[np.ndarray, np.ndarray, np.ndarray, float]) -> tuple[float, np.ndarray]:
    """Exact reliability at the worst pose and at each task-space pose of one design (a chunk)."""
    J_worst, J_task, s, target_m = task
    return float(grid_reliability(J_worst[None], s, target_m)[0]), grid_reliability(J_task, s, target_m)
