"""Monte Carlo: the most error-sensitive pose (paper §4.3) and verification of a design (§4.4).

Verification samples errors from three distributions, all reported:

* ``uniform_sigma``: uniform on ``±σ_i`` — the paper's choice (variance ``σ_i²/3``: a third of the
  design's, so it passes almost regardless);
* ``uniform_sqrt3_sigma``: uniform on ``±√3 σ_i`` (variance-matched);
* ``gaussian``: ``N(0, σ_i²)`` (variance-matched, the FOSM model's own assumption).

Each sample takes a random point of the task space (inverse kinematics there) and random errors;
``Δλ`` comes from the linear model for every sample and, on a subsample, from exact kinematics of
the perturbed mechanism with the Eq. 25 actuator correction applied (the truth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats
from tqdm import tqdm

from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.exceptions import ConvergenceError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.mechanism import Mechanism

DISTRIBUTIONS = ("uniform_sigma", "uniform_sqrt3_sigma", "gaussian")


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
    k = int(np.sum(dlam > target_m))
    p = k / n
    z = float(stats.norm.ppf(0.975))
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return FailureStats(
        mean_m=float(dlam.mean()),
        std_m=float(dlam.std(ddof=1)) if n > 1 else 0.0,
        failure_fraction=p,
        failure_ci95=(0.0 if k == 0 else max(0.0, centre - half), 1.0 if k == n else min(1.0, centre + half)),
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
        points_m: Shape (samples, 3): the sample points [m].
        exact_unassembled: Samples of the exact subsample whose perturbed mechanism cannot be
            closed (an over-constrained mechanism with errors no rigid motion satisfies: assembly
            errors); they are left out of ``exact``, ``linear_subsample`` and the difference.
        tilt_linear_rad: Linear tilt Δα of the tool axis of every sample [rad] (None unless the
            orientation is verified).
        tilt: Statistics of the linear Δα against Δα* (values in rad; None without a target).
        tilt_exact: The same on the exact subsample.
        joint: Linear statistics of ``max(Δλ/Δλ*, Δα/Δα*)`` against 1: its failure fraction is
            ``P(Δλ > Δλ* or Δα > Δα*)`` (None without an orientation target).
    """

    distribution: str
    linear: FailureStats
    exact: FailureStats | None
    linear_subsample: FailureStats | None
    max_relative_difference: float
    dlam_linear_m: np.ndarray
    points_m: np.ndarray
    exact_unassembled: int = 0
    tilt_linear_rad: np.ndarray | None = None
    tilt: FailureStats | None = None
    tilt_exact: FailureStats | None = None
    joint: FailureStats | None = None


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
) -> Verification:
    """Verify tolerances ``sigma`` (one per parameter in ``columns``) by Monte Carlo.

    Args:
        mechanism: The mechanism.
        pset: Its parameter set.
        sweep_random: Separations at random task-space points; sample ``s`` uses point
            ``s mod m``.
        columns: Indices (into ``pset``) of the toleranced parameters; the others are zero.
        sigma: Tolerances of those parameters (SI); a free parameter (``inf``: zero sensitivity
            at the design point) is held at zero, as in :mod:`pkmtol.exact_design`.
        target_m: Δλ* [m].
        distribution: One of :data:`DISTRIBUTIONS`.
        samples: Number of linear-model samples.
        exact_samples: Size of the exact-kinematics subsample (the first samples).
        rng: Random generator.
        progress: Show a progress bar for the exact subsample.
    """
    m = len(sweep_random.poses)
    point_of = np.arange(samples) % m
    eta = sample_errors(distribution, np.where(np.isfinite(sigma), sigma, 0.0), samples, rng)
    Jc = sweep_random.J[:, :, columns]  # (m, 3, k)
    dlam = np.linalg.norm(np.einsum("sij,sj->si", Jc[point_of], eta), axis=1)
    exact = lin_sub = None
    max_diff = float("nan")
    unassembled = 0
    if exact_samples > 0:
        k = min(exact_samples, samples)
        dl_exact = np.full(k, np.nan)
        chain = ClosedChain(mechanism)
        full = np.zeros(len(pset))
        for s in tqdm(
            range(k), desc=f"exact {distribution}", unit="sample", disable=not progress, leave=False
        ):
            full[:] = 0.0
            full[columns] = eta[s]
            sep = sweep_random.separations[point_of[s]]
            if sep.redundancy and sep.incompatible_map is not None:
                # an over-constrained mechanism assembles only if the incompatible part vanishes;
                # when the linear model already says it does not, Newton cannot close it either
                y = np.vstack([sep.Y_a, sep.Y_c]) @ full
                if np.linalg.norm(sep.incompatible_map @ full) > 1e-9 * max(float(np.linalg.norm(y)), 1e-300):
                    continue
            try:
                dl_exact[s] = exact_position_error(mechanism, pset, chain, sweep_random, point_of[s], full)
            except ConvergenceError:
                pass  # cannot be assembled: counted in exact_unassembled
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
        points_m=sweep_random.points_m[point_of],
        exact_unassembled=unassembled,
    )


def exact_position_error(
    mechanism: Mechanism,
    pset: ParameterSet,
    chain: ClosedChain,
    sweep_: Sweep,
    index: int,
    eta: np.ndarray,
) -> float:
    """``‖P_actual − P_nominal‖`` [m] of the perturbed mechanism with the Eq. 25 correction.

    The actuators are commanded to their nominal values plus ``correction · η`` (the calibrated
    compensation); the perturbed closed chain is solved exactly.
    """
    pose = sweep_.poses[index]
    sep = sweep_.separations[index]
    eps, offsets = pset.perturbation(eta, mechanism)
    models = perturbed_limb_models(mechanism, eps)
    pchain = ClosedChain(mechanism, models=models, check_limits=False)
    u = pose.q_all[chain.actuated_idx] + sep.correction @ eta
    actual = pchain.forward(u, pose.q_all, offsets)
    return float(np.linalg.norm(actual.p_m - pose.p_m))
