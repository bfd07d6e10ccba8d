"""Predicted accuracy of a plan from the linear model: Δλ and tilt over the evaluation poses.

For Gaussian errors ``δ ~ N(0, diag(σ²))`` and noise ``ν ~ N(0, σ_m² I)``, P's error at pose
``k`` is Gaussian with covariance ``Σ_k = L_k diag(σ²) L_kᵀ + σ_m² N_k N_kᵀ``. The mean of
``Δλ_k = ‖e_k‖`` has a closed form (:func:`pkmtol.error_model.accuracy.norm_moments`); the
quantiles of Δλ pooled over the poses are taken from a seeded sample of the exact Gaussian
(``samples`` draws per pose; the sampling error is stated with the result).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.error_model.accuracy import norm_moments
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.statistics import quantiles

#: Draws per pose for the pooled quantiles.
SAMPLES_PER_POSE = 2000


@dataclass(frozen=True)
class Prediction:
    """Linear-model prediction of the accuracy over the evaluation poses (SI units).

    Attributes:
        mean_m: Mean Δλ over the poses (closed form) [m].
        p95_m: 95th percentile of Δλ pooled over the poses [m].
        p99_m: 99th percentile [m].
        beyond: Fraction of pooled samples with Δλ > Δλ*.
        tilt_mean_rad: Mean tilt of the tool axis (sampled) [rad].
        tilt_p99_rad: 99th percentile of the tilt [rad].
        samples: Pooled samples behind the quantiles.
    """

    mean_m: float
    p95_m: float
    p99_m: float
    beyond: float
    tilt_mean_rad: float
    tilt_p99_rad: float
    samples: int


def predict(
    maps: AccuracyMaps,
    sigma: np.ndarray,
    target_m: float,
    tool_axis: np.ndarray,
    samples_per_pose: int = SAMPLES_PER_POSE,
    seed: int = 0,
) -> Prediction:
    """Predicted Δλ and tilt of the tool axis for independent Gaussian errors of σ ``sigma`` (n,)."""
    cov = maps.position_covariance(sigma)
    tcov = maps.tilt_covariance(tool_axis, sigma)
    mean = float(np.mean([norm_moments(np.linalg.eigvalsh(c))[0] for c in cov]))
    rng = np.random.default_rng(seed)
    dl = _sample_norms(cov, samples_per_pose, rng)
    tilt = _sample_norms(tcov, samples_per_pose, rng)
    p95, p99 = quantiles(dl, (0.95, 0.99))
    return Prediction(
        mean_m=mean,
        p95_m=p95,
        p99_m=p99,
        beyond=float(np.mean(dl > target_m)),
        tilt_mean_rad=float(np.mean(tilt)),
        tilt_p99_rad=quantiles(tilt, (0.99,))[0],
        samples=int(dl.size),
    )


def _sample_norms(cov: np.ndarray, per_pose: int, rng: np.random.Generator) -> np.ndarray:
    """``‖x‖`` for ``x ~ N(0, Σ_k)``, ``per_pose`` draws per pose, pooled (m·per_pose,)."""
    lam, vec = np.linalg.eigh(cov)
    root = vec * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]  # (m, 3, 3): Σ^{1/2}
    z = rng.standard_normal((cov.shape[0], 3, per_pose))
    return np.linalg.norm(root @ z, axis=1).ravel()
