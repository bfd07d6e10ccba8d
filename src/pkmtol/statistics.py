"""Sample statistics every stage shares: the Wilson interval of a failure fraction, sample quantiles."""

from __future__ import annotations

import math

import numpy as np

#: z of the two-sided 95 % interval, Φ⁻¹(0.975).
Z95 = 1.959963984540054


def wilson_interval(failures: int, samples: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``failures / samples`` (95 % by default).

    The ends are exactly 0 when no sample failed and 1 when all did.

    >>> [round(x, 4) for x in wilson_interval(0, 100)]
    [0.0, 0.037]
    """
    n, k = int(samples), int(failures)
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (0.0 if k == 0 else max(0.0, centre - half), 1.0 if k == n else min(1.0, centre + half))


def quantiles(values: np.ndarray, probabilities: tuple[float, ...]) -> tuple[float, ...]:
    """Sample quantiles (linear interpolation) of the finite entries of ``values``; NaN if none."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return tuple(float("nan") for _ in probabilities)
    return tuple(float(x) for x in np.quantile(v, probabilities))
