"""The most error-sensitive pose (paper §4.3): Monte Carlo σ[Δλ] over the grid beside the analytic one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import pkmtol.values as values
from pkmtol.error_model.accuracy import grid_norm_moments


@dataclass(frozen=True)
class PoseSearch:
    """Result of the sensitive-pose search (η_c ~ N(0, 1) per parameter, SI units).

    Attributes:
        sigma_sampled_m: Shape (m,): sample standard deviation of Δλ at each grid point [m].
        sigma_analytic_m: Shape (m,): exact standard deviation of Δλ from the linear map [m].
        mean_analytic_m: Shape (m,): exact mean of Δλ [m].
        worst_index: Grid index of the largest sampled σ (the paper's Step 5).
        worst_index_analytic: Grid index of the largest analytic σ.
        samples: Number of samples.
    """

    sigma_sampled_m: np.ndarray
    sigma_analytic_m: np.ndarray
    mean_analytic_m: np.ndarray
    worst_index: int
    worst_index_analytic: int
    samples: int


def search_sensitive_pose(J: np.ndarray, samples: int, rng: np.random.Generator) -> PoseSearch:
    """The paper's Steps 1–5 over grid maps ``J`` of shape (m, 3, n), and the analytic answer."""
    J = values.array_of_shape("J", J, (None, 3, None))
    values.count("samples", samples, low=2)
    values.instance("rng", rng, np.random.Generator, "a numpy.random.Generator (np.random.default_rng(seed))")
    m, _, n = J.shape
    eta = rng.standard_normal((samples, n))
    sampled = np.empty(m)
    for j in range(m):
        sampled[j] = np.linalg.norm(eta @ J[j].T, axis=1).std(ddof=1)
    moments = grid_norm_moments(J)
    return PoseSearch(
        sigma_sampled_m=sampled,
        sigma_analytic_m=moments[:, 1],
        mean_analytic_m=moments[:, 0],
        worst_index=int(np.argmax(sampled)),
        worst_index_analytic=int(np.argmax(moments[:, 1])),
        samples=samples,
    )
