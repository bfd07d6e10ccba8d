"""A measurement plan: candidate pool, chosen poses, their identification Jacobian and identifiability.

The pool is the task-space grid plus ``candidates`` random reachable poses (unreachable or singular
draws are skipped). The controller model's base parameters are found on the pool; a D-optimal plan
chooses ``N`` poses that maximise ``log det`` of their information about those base parameters, a
random plan draws ``N`` at random. The plan's own identifiability (rank, condition number, O1,
correlations, combinations) is then computed on the chosen poses alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.calibration.identifiability import Identifiability, identifiability
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.calibration.selection import d_optimal, log_det_information, random_subset
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.exceptions import InvalidRequestError, KinematicsError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class CalibrationPlan:
    """Where the tracker measures and what that determines.

    Attributes:
        settings: The settings the plan was made with.
        targets_m: Shape (t, 3): tracker targets in the platform frame [m].
        chosen: Shape (N,): indices of the chosen poses in the pool.
        maps: The linear maps at the chosen poses (their nominal P, joints and commands).
        H: Shape (3·N·t, n): measured coordinates per unit parameter (every parameter of the set).
        ident: Identifiability of the controller model on the chosen poses.
        scale: Shape (n,): the expected size of every parameter [m or rad] (column scaling).
        prior_sigma: Shape (p,): the MAP prior σ of each controller parameter; None for least squares.
        log_det: ``log det`` of the chosen poses' information about the pool's base parameters.
    """

    settings: CalibrationSettings
    targets_m: np.ndarray
    chosen: np.ndarray
    maps: PoseMaps
    H: np.ndarray
    ident: Identifiability
    scale: np.ndarray
    prior_sigma: np.ndarray | None
    log_det: float

    @property
    def poses(self) -> int:
        """Number of calibration poses N."""
        return int(self.chosen.size)


def candidate_pool(
    mechanism: Mechanism,
    pset: ParameterSet,
    settings: CalibrationSettings,
    chain: ClosedChain | None = None,
    grid: Sweep | None = None,
) -> PoseMaps:
    """The task-space grid plus ``settings.candidates`` random reachable poses, as linear maps.

    ``grid`` is the task-space grid's sweep when it has been computed already.
    """
    chain = chain or ClosedChain(mechanism)
    grid_points = mechanism.task_space.grid()
    grid = grid if grid is not None else sweep(mechanism, pset, grid_points, chain)
    maps = pose_maps(grid, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    if settings.candidates == 0:
        return maps
    rng = np.random.default_rng(settings.seed)
    points = mechanism.task_space.sample(rng, settings.candidates)
    keep_points, keep_q = [], []
    for p in points:
        k = int(np.argmin(np.sum((grid_points - p) ** 2, axis=1)))
        try:
            pose = chain.inverse(p, chain.predict(grid.poses[k], p))
        except KinematicsError:
            continue
        keep_points.append(p)
        keep_q.append(pose.q_all)
    if not keep_points:
        return maps
    extra = sweep(mechanism, pset, np.array(keep_points), chain, guesses=np.array(keep_q))
    more = pose_maps(extra, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    return concat_maps(maps, more)


def concat_maps(a: PoseMaps, b: PoseMaps) -> PoseMaps:
    """The poses of ``a`` then those of ``b``."""
    return PoseMaps(
        points_m=np.concatenate([a.points_m, b.points_m]),
        rotations=np.concatenate([a.rotations, b.rotations]),
        q=np.concatenate([a.q, b.q]),
        commands=np.concatenate([a.commands, b.commands]),
        twist=np.concatenate([a.twist, b.twist]),
        actuation=np.concatenate([a.actuation, b.actuation]),
        reference_point_m=a.reference_point_m,
    )


def make_plan(
    mechanism: Mechanism,
    pset: ParameterSet,
    classes: list[str],
    settings: CalibrationSettings,
    pool: PoseMaps,
    sigma: np.ndarray | None = None,
    poses: int | None = None,
    selection: str | None = None,
    chosen: np.ndarray | None = None,
) -> CalibrationPlan:
    """Choose the calibration poses from ``pool`` and compute what they identify.

    Args:
        mechanism: The mechanism.
        pset: Its parameter set.
        classes: The class of every parameter (``Sweep.classify``).
        settings: Targets, noise, pose count, selection, controller, prior, rank tolerance.
        pool: The candidate poses (:func:`candidate_pool`).
        sigma: Shape (n,): the expected size of every parameter [m or rad] (manufacturing σ for the
            compensatable ones, tolerances for the others; default: the manufacturing σ by unit);
            it scales the columns and sizes the prior.
        poses: N (default ``settings.poses``).
        selection: ``d-optimal`` or ``random`` (default ``settings.selection``).
        chosen: Explicit pool indices (overrides ``poses`` and ``selection``).

    Raises:
        InvalidRequestError: more poses than the pool holds, or fewer coordinates than the rank.
    """
    targets = settings.targets(mechanism)
    n = len(pset)
    scale = settings.manufacturing_sigma(pset) if sigma is None else np.asarray(sigma, dtype=float).copy()
    unit_scale = settings.manufacturing_sigma(pset)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, unit_scale)
    columns = settings.controller_columns(pset, classes)
    rows_pool = pool.measurement_rows(targets)  # (m, 3t, n)
    H_pool = rows_pool.reshape(-1, n)
    ident_pool = identifiability(
        H_pool, columns, pset.names, pset.units, scale, len(pool), settings.noise_m, settings.rank_tolerance
    )
    base = ident_pool.base_columns
    blocks = rows_pool[:, :, base] * scale[base][None, None, :]
    count = settings.poses if poses is None else int(poses)
    how = settings.selection if selection is None else selection
    if chosen is None:
        if count > len(pool):
            raise InvalidRequestError(
                f"{count} calibration poses asked for, but the candidate pool has {len(pool)}; "
                "lower --poses or raise candidates"
            )
        if how == "d-optimal":
            chosen = d_optimal(blocks, count)
        else:
            chosen = random_subset(len(pool), count, np.random.default_rng(settings.seed + 7919 * count))
    chosen = np.asarray(chosen, dtype=int)
    maps = pool.subset(chosen)
    H = maps.measurement_rows(targets).reshape(-1, n)
    ident = identifiability(
        H, columns, pset.names, pset.units, scale, chosen.size, settings.noise_m, settings.rank_tolerance
    )
    if H.shape[0] < ident_pool.rank:
        raise InvalidRequestError(
            f"{chosen.size} poses × {targets.shape[0]} target(s) give {H.shape[0]} measured coordinates, "
            f"fewer than the {ident_pool.rank} identifiable combinations of the controller model; "
            "measure more poses or more targets"
        )
    return CalibrationPlan(
        settings=settings,
        targets_m=targets,
        chosen=chosen,
        maps=maps,
        H=H,
        ident=ident,
        scale=scale,
        prior_sigma=scale[columns] if settings.prior else None,
        log_det=log_det_information(blocks, chosen),
    )
