"""Intervals of study statistics at machine level: a bootstrap over machines.

The held-out poses of one machine share its errors, and the machines of a study share their plan
(or each draws its own): ``K·m`` pose checks are not ``K·m`` independent trials (DESIGN.md, "Claims
and their scope"). The interval of a statistic pooled over the machines is the percentile interval
of the statistic over ``B`` resamples of whole machines (with replacement), seeded so that the
output is reproducible. With no failure in the sample the bootstrap cannot widen it: its upper end
is then the rule-of-three bound ``1 − 0.05^{1/K}`` on the machine-level fraction (no machine
failed), stated as such.
"""

from __future__ import annotations

import numpy as np

#: Bootstrap resamples.
RESAMPLES = 2000
#: The bootstrap's own seed (the interval must not depend on the study's seed stream).
SEED = 20240


def machine_bootstrap(
    failed: np.ndarray, valid: np.ndarray, resamples: int = RESAMPLES
) -> tuple[float, float, float]:
    """The pooled failure fraction and its 95 % machine-bootstrap interval ``(fraction, low, high)``.

    Args:
        failed: Shape (K, m): whether each held-out check of each machine failed.
        valid: Shape (K, m): whether it was measured (unsolved checks count for nothing).
        resamples: Bootstrap resamples.
    """
    f = np.asarray(failed, dtype=float) * valid
    per_fail = f.sum(axis=1)
    per_n = np.asarray(valid, dtype=float).sum(axis=1)
    K = per_n.size
    total = per_n.sum()
    if K == 0 or total == 0:
        return (float("nan"), 0.0, 1.0)
    frac = float(per_fail.sum() / total)
    if per_fail.sum() == 0:
        return (0.0, 0.0, float(1.0 - 0.05 ** (1.0 / K)))
    rng = np.random.default_rng(SEED)
    pick = rng.integers(0, K, size=(resamples, K))
    num, den = per_fail[pick].sum(axis=1), per_n[pick].sum(axis=1)
    stats = num / np.where(den > 0, den, np.nan)
    lo, hi = np.nanquantile(stats, (0.025, 0.975))
    return (frac, float(lo), float(hi))
