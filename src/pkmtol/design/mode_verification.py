"""Verification of a design in any compensation mode, with the tool axis's tilt beside Δλ.

The linear model draws the toleranced errors from the verification distribution at their
tolerances, the other non-absorbed errors (``calibrated``: the identified ones) Gaussian at their
manufacturing σ, and the tracker noise Gaussian at σ_m; Δλ = ‖e‖ and Δα = ‖(R a) × θ‖ come from the
mode's maps. The exact subsample solves the same draws on exact kinematics: ``ideal`` commands
the Eq. 25 correction, ``none`` the nominal commands, ``calibrated`` simulates the whole
calibration (measure, identify, compensate by the identified model's inverse kinematics).

The linear samples are drawn and evaluated in chunks of :data:`MODE_CHUNK`, so the working memory
does not grow with the sample count: only Δλ and Δα (8 bytes a sample each) are kept. Each of the
three draws (toleranced errors, background errors, noise) keeps the stream it had as one draw of
all the samples: its chunks come from a copy of the generator taken where that draw starts, found
by drawing (and dropping) the earlier draws first. So every sample gets the values it got from the
one-piece draw, and the generator ends where the one-piece draw left it; Δλ and Δα agree with the
one-piece products to round-off (:func:`pkmtol.design.verification.cyclic_products`).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from pkmtol.calibration.compensation import PoseErrors
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.calibration.plan import CalibrationPlan
from pkmtol.calibration.study import calibrate_and_evaluate
from pkmtol.design.modes import ModeSetup
from pkmtol.design.verification import (
    DISTRIBUTIONS,
    Verification,
    cyclic_products,
    failure_stats,
    sample_errors,
    verify_all,
)
from pkmtol.error_model.accuracy import vector_norms
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.task import sample_sweep
from pkmtol.error_model.tool_chain import HybridParameterSet
from pkmtol.error_model.tool_exact import tool_exact
from pkmtol.error_model.tool_sweep import ToolSweep
from pkmtol.exceptions import KinematicsError
from pkmtol.executor import Executor
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism

#: Linear samples per chunk: a chunk's draws and products take a few doubles per sample and parameter.
MODE_CHUNK = 16_384

#: Most exact verification samples of the ``calibrated`` mode, Gaussian errors only. Each is its own
#: machine (its own draw, measured, identified and compensated on exact kinematics) at its own
#: random pose, so the Wilson interval is over machines: 11 failures of 500 give [1.23, 3.90] %,
#: which tells 2.3 % from 4.6 %. On the seed robot one costs about 29 ms (docs/claims.md). The
#: thorough check is `pkmtol calibrate --simulate --tolerances allocation.json`.
CALIBRATED_EXACT_SAMPLES = 500


def exact_cap(mode: str, exact_samples: int) -> int | None:
    """The exact samples a mode runs when it caps ``exact_samples`` (None: not capped)."""
    if mode == "calibrated" and exact_samples > CALIBRATED_EXACT_SAMPLES:
        return CALIBRATED_EXACT_SAMPLES
    return None


#: ``(pose index, full parameter vector, noise) → (P error (3,), rotation (3,))`` or None (unassembled).
ExactError = Callable[[int, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray] | None]


def ideal_exact(mechanism: Mechanism, pset: ParameterSet, sweep_: Sweep, corrected: bool) -> ExactError:
    """Exact pose errors with the Eq. 25 correction (``corrected``) or the nominal commands."""
    if isinstance(sweep_, ToolSweep) and isinstance(pset, HybridParameterSet):  # a hybrid: its TCP
        return tool_exact(mechanism, pset, sweep_, corrected)
    chain = ClosedChain(mechanism)

    def error(k: int, delta: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        pose, sep = sweep_.poses[k], sweep_.separations[k]
        if sep.redundancy and sep.incompatible_map is not None:
            y = np.vstack([sep.Y_a, sep.Y_c]) @ delta
            if np.linalg.norm(sep.incompatible_map @ delta) > 1e-9 * max(float(np.linalg.norm(y)), 1e-300):
                return None  # an over-constrained machine these errors cannot assemble
        u = pose.q_all[chain.actuated_idx] + (sep.correction @ delta if corrected else 0.0)
        try:
            actual = Machine(mechanism, pset, delta).forward(u, pose.q_all)
        except KinematicsError:
            return None
        r = pose.oMp.rotation
        return mechanism.task_error(actual.p_m - pose.p_m), r @ pin.log3(r.T @ actual.oMp.rotation)

    return error


def calibrated_exact(
    mechanism: Mechanism, pset: ParameterSet, plan: CalibrationPlan, poses: PoseMaps
) -> ExactError:
    """Exact pose errors after simulating the plan's calibration of the drawn machine."""

    def error(k: int, delta: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        try:
            errs, _ = calibrate_and_evaluate(
                mechanism, pset, plan, Machine(mechanism, pset, delta), noise, poses.subset(np.array([k]))
            )
        except KinematicsError:
            return None
        if not errs.solved[0]:
            return None
        return errs.position_m[0], errs.rotation_rad[0]

    return error


@dataclass(frozen=True, eq=False)
class VerificationPoses:
    """The random task-space poses of the verification (and of the claims' task-space columns).

    Attributes:
        sweep: Their sweep (error model at each pose).
        maps: The compensation mode's maps there.
    """

    sweep: Sweep
    maps: AccuracyMaps


def verification_poses(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep,
    setup: ModeSetup,
    chain: ClosedChain,
    count: int,
    rng: np.random.Generator,
    progress: bool = False,
) -> VerificationPoses:
    """Draw ``count`` random task-space poses (uniform in the volume) and the mode's maps there."""
    rnd = sample_sweep(mechanism, pset, grid, rng, count, chain, progress)
    maps = setup.maps_at(rnd, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    return VerificationPoses(sweep=rnd, maps=maps)


def verify_design(
    mechanism: Mechanism,
    pset: ParameterSet,
    setup: ModeSetup,
    poses: VerificationPoses,
    chain: ClosedChain,
    sigma: np.ndarray,
    target_m: float,
    samples: int,
    exact_samples: int,
    rng: np.random.Generator,
    orientation: tuple[np.ndarray, float | None],
    progress: bool = False,
    executor: Executor | None = None,
) -> dict[str, Verification]:
    """The verification stage: the design ``sigma`` of ``setup.columns`` per distribution.

    ``ideal`` without a tilt target or a tool chain runs the exact chunks of all distributions at
    once (:func:`pkmtol.design.verification.verify_all`); the other modes one distribution at a
    time (:func:`verify_mode`), ``calibrated`` with at most :data:`CALIBRATED_EXACT_SAMPLES` exact
    samples of Gaussian errors only.
    """
    rnd, unc, mode = poses.sweep, setup.columns, setup.mode
    if mode == "ideal" and orientation[1] is None and mechanism.tool is None:
        return verify_all(
            mechanism,
            pset,
            rnd,
            unc,
            sigma,
            target_m,
            samples,
            exact_samples,
            rng,
            progress=progress,
            executor=executor,
        )
    ver: dict[str, Verification] = {}
    for dist in DISTRIBUTIONS:
        exact: ExactError | None
        n_exact = exact_samples
        if mode == "calibrated":
            assert setup.plan is not None
            rnd_pose_maps = pose_maps(
                rnd, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection
            )
            exact = (
                calibrated_exact(mechanism, pset, setup.plan, rnd_pose_maps) if dist == "gaussian" else None
            )
            n_exact = exact_cap(mode, exact_samples) or exact_samples
        else:
            exact = ideal_exact(mechanism, pset, rnd, corrected=mode == "ideal")
        ver[dist] = verify_mode(
            poses.maps,
            rnd.points_m,
            len(pset),
            unc,
            sigma,
            target_m,
            dist,
            samples,
            n_exact,
            rng,
            exact,
            background=setup.background_sigma(pset),
            orientation=orientation,
            progress=progress,
        )
    return ver


def verify_mode(
    maps: AccuracyMaps,
    points_m: np.ndarray,
    n_params: int,
    columns: np.ndarray,
    sigma: np.ndarray,
    target_m: float,
    distribution: str,
    samples: int,
    exact_samples: int,
    rng: np.random.Generator,
    exact: ExactError | None,
    background: tuple[np.ndarray, np.ndarray] | None = None,
    orientation: tuple[np.ndarray, float | None] | None = None,
    progress: bool = False,
) -> Verification:
    """Verify tolerances ``sigma`` of ``columns`` by Monte Carlo in the mode of ``maps``.

    Args:
        maps: The mode's maps at the random verification poses (sample ``s`` uses pose ``s mod m``).
        points_m: Shape (m, 3): those poses' P [m].
        n_params: Size of the parameter set.
        columns: Toleranced parameters; ``sigma`` their tolerances (``inf``: held at 0).
        sigma: Tolerances [SI].
        target_m: Δλ* [m].
        distribution: One of ``DISTRIBUTIONS`` (of the toleranced errors).
        samples: Linear-model samples.
        exact_samples: Exact subsample size (the first samples).
        rng: Random generator.
        exact: Exact evaluation of a sample (None: linear only).
        background: ``(columns, σ)`` drawn Gaussian beside (identified errors at manufacturing σ).
        orientation: ``(tool axis, Δα* or None)``: also verify the tilt.
        progress: Progress bar over the exact subsample.
    """
    m = len(maps)
    sig = np.where(np.isfinite(sigma), sigma, 0.0)
    M = maps.position_noise.shape[2]
    bg_cols, bg_sigma = background if background is not None else (np.zeros(0, dtype=int), np.zeros(0))

    def draw_eta(count: int, g: np.random.Generator) -> np.ndarray:
        return sample_errors(distribution, sig, count, g)

    def draw_background(count: int, g: np.random.Generator) -> np.ndarray:
        return g.standard_normal((count, len(bg_cols))) * bg_sigma

    def draw_noise(count: int, g: np.random.Generator) -> np.ndarray:
        return g.standard_normal((count, M)) * maps.noise_m

    draws = [draw_eta] + ([draw_background] if len(bg_cols) else []) + ([draw_noise] if M else [])
    streams = _stream_starts(rng, draws, samples)
    tmap = tnoise = None
    if orientation is not None:
        tmap, tnoise = maps.tilt_maps(orientation[0])
    dlam = np.empty(samples)
    tilt = np.empty(samples) if orientation is not None else None
    head = min(exact_samples, samples) if exact is not None else 0
    delta_head, noise_head = np.zeros((head, n_params)), np.zeros((head, M))
    for start in range(0, samples, MODE_CHUNK):
        count = min(MODE_CHUNK, samples - start)
        rows = slice(start, start + count)
        delta = np.zeros((count, n_params))
        delta[:, columns] = draw_eta(count, streams[0])
        if len(bg_cols):
            delta[:, bg_cols] = draw_background(count, streams[1])
        noise = draw_noise(count, streams[-1]) if M else np.zeros((count, 0))
        e = cyclic_products(maps.position, delta, start)
        if M:
            e += cyclic_products(maps.position_noise, noise, start)
        dlam[rows] = vector_norms(e)
        if tilt is not None and tmap is not None and tnoise is not None:
            t = cyclic_products(tmap, delta, start)
            if M:
                t += cyclic_products(tnoise, noise, start)
            tilt[rows] = vector_norms(t)
        if start < head:
            delta_head[start : start + count] = delta[: head - start]
            noise_head[start : start + count] = noise[: head - start]
    exact_stats = lin_sub = tilt_exact_stats = None
    max_diff = float("nan")
    unassembled = 0
    if exact is not None and exact_samples > 0:
        k = min(exact_samples, samples)
        dl_exact = np.full(k, np.nan)
        tl_exact = np.full(k, np.nan)
        axis = None if orientation is None else orientation[0] / np.linalg.norm(orientation[0])
        for s in tqdm(
            range(k), desc=f"exact {distribution}", unit="sample", disable=not progress, leave=False
        ):
            got = exact(s % m, delta_head[s], noise_head[s])
            if got is None:
                continue
            dp, th = got
            dl_exact[s] = float(np.linalg.norm(dp))
            if axis is not None:
                rk = maps.rotations[s % m]
                pe = PoseErrors(dp[None], th[None], np.ones(1, dtype=bool))
                tl_exact[s] = float(pe.tilt_rad(axis, rk[None])[0])
        ok = np.isfinite(dl_exact)
        unassembled = int(k - ok.sum())
        if ok.any():
            exact_stats = failure_stats(dl_exact[ok], target_m)
            lin_sub = failure_stats(dlam[:k][ok], target_m)
            max_diff = float(np.max(np.abs(dl_exact[ok] - dlam[:k][ok])) / target_m)
            if orientation is not None and orientation[1] is not None:
                tilt_exact_stats = failure_stats(tl_exact[ok], orientation[1])
    tilt_stats = None
    if tilt is not None and orientation is not None and orientation[1] is not None:
        tilt_stats = failure_stats(tilt, orientation[1])
    joint = None
    if tilt is not None and orientation is not None and orientation[1] is not None:
        joint = failure_stats(np.maximum(dlam / target_m, tilt / orientation[1]), 1.0)
    return Verification(
        distribution=distribution,
        linear=failure_stats(dlam, target_m),
        exact=exact_stats,
        linear_subsample=lin_sub,
        max_relative_difference=max_diff,
        dlam_linear_m=dlam,
        pose_points_m=points_m,
        exact_unassembled=unassembled,
        dlam_exact_m=dl_exact if exact is not None and exact_samples > 0 else np.zeros(0),
        target_m=target_m,
        tilt_linear_rad=tilt,
        tilt=tilt_stats,
        tilt_exact=tilt_exact_stats,
        joint=joint,
    )


def _stream_starts(
    rng: np.random.Generator, draws: Sequence[Callable[[int, np.random.Generator], np.ndarray]], samples: int
) -> list[np.random.Generator]:
    """A generator for each draw, at the start of its stream in the one-piece order of the draws.

    The one-piece code draws all samples of ``draws[0]``, then of ``draws[1]``, and so on. Each
    but the last gets a copy of ``rng`` taken where its draw starts, and ``rng`` is then advanced
    over that draw in chunks (the values dropped); the last draw uses ``rng`` itself, which so ends
    where the one-piece draws leave it.
    """
    starts = []
    for draw in draws[:-1]:
        starts.append(copy.deepcopy(rng))
        for start in range(0, samples, MODE_CHUNK):
            draw(min(MODE_CHUNK, samples - start), rng)
    return [*starts, rng]
