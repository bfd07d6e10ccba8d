"""A measurement plan: candidate pool, chosen poses, their identification Jacobian and identifiability.

The pool is the task-space grid plus ``candidates`` random reachable poses (unreachable or singular
draws are skipped). The controller model's base parameters are found on the pool; a D-optimal plan
chooses ``N`` poses that maximise ``log det`` of their information about those base parameters, a
random plan draws ``N`` at random. The plan's own identifiability (rank, condition number, O1,
correlations, combinations) is then computed on the chosen poses alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pkmtol.calibration.hybrid_poses import hybrid_pool
from pkmtol.calibration.identifiability import Identifiability, identifiability
from pkmtol.calibration.instruments import Instrument, instrument_for
from pkmtol.calibration.linear_system import LinearSystem, linear_system
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.calibration.selection import d_optimal, random_subset
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.exceptions import InvalidRequestError, KinematicsError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class CalibrationPlan:
    """Where the instrument measures and what that determines.

    Attributes:
        settings: The settings the plan was made with.
        targets_m: Shape (t, 3): tracker targets in the platform frame [m] (the tracker family;
            P for the other instruments).
        chosen: Shape (N,): indices of the chosen poses in the pool.
        maps: The linear maps at the chosen poses (their nominal P, joints, commands, stations).
        H: Shape (M, n): the identification Jacobian the estimator works on: the measured values
            per unit parameter, whitened to the reference σ_m and with the instrument's nuisance
            parameters projected out (:mod:`pkmtol.calibration.linear_system`); for a tracker in
            a registered frame, the measured coordinates per unit parameter (3·N·t rows).
        ident: Identifiability of the controller model on the chosen poses.
        scale: Shape (n,): the expected size of every parameter [m or rad] (column scaling).
        prior_sigma: Shape (p,): the MAP prior σ of each controller parameter; None for least squares.
        log_det: ``log det`` of the chosen poses' information about the pool's base parameters
            (with the nuisance parameters unknown).
        instrument: The measurement model (None: the tracker of ``settings``).
        system: The raw linear system at the chosen poses (machine and nuisance rows, weights).
        pool_rank: Rank of the controller model over the whole candidate pool.
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
    instrument: Instrument | None = None
    system: LinearSystem | None = None
    pool_rank: int = 0

    @property
    def poses(self) -> int:
        """Number of calibration poses N (every reading of every ballbar circle counts)."""
        return int(self.chosen.size)

    @property
    def stations(self) -> np.ndarray:
        """The station of every chosen pose (N,)."""
        return self.maps.station_index

    def measurement_model(self, mechanism: Mechanism) -> Instrument:
        """The plan's instrument (built from the settings when the plan has none)."""
        return self.instrument if self.instrument is not None else instrument_for(self.settings, mechanism)


def candidate_pool(
    mechanism: Mechanism,
    pset: ParameterSet,
    settings: CalibrationSettings,
    chain: ClosedChain | None = None,
    grid: Sweep | None = None,
) -> PoseMaps:
    """The candidate poses of the plan, as linear maps.

    A tracker: the task-space grid plus ``settings.candidates`` random reachable poses. The
    ballbar and the probe: their own candidates (circle readings, approach directions), where the
    mechanism reaches them. ``grid`` is the task-space grid's sweep when it has been computed already.

    Raises:
        InvalidRequestError: the mechanism reaches none of the instrument's candidates.
    """
    if mechanism.tool is not None:  # a hybrid: TCP × tool axis, a tracker on the TCP
        return hybrid_pool(mechanism, pset, settings, chain, grid)
    chain = chain or ClosedChain(mechanism)
    grid_points = mechanism.task_space.grid()
    grid = grid if grid is not None else sweep(mechanism, pset, grid_points, chain)
    maps = pose_maps(grid, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    rng = np.random.default_rng(settings.seed)
    own = instrument_for(settings, mechanism).candidates(grid_points, rng)
    if own is not None:
        keep, q = _reachable(chain, grid, grid_points, own.points_m)
        if not keep.size:
            raise InvalidRequestError(
                f"the mechanism reaches none of the {settings.instrument}'s {len(own.points_m)} candidate "
                "poses; move the stations (stations_m) into the task space or change their size"
            )
        sw = sweep(mechanism, pset, own.points_m[keep], chain, guesses=q)
        out = pose_maps(sw, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
        return replace(out, stations=own.stations[keep], groups=own.groups[keep])
    if settings.candidates == 0:
        return maps
    points = mechanism.task_space.sample(rng, settings.candidates)
    keep, q = _reachable(chain, grid, grid_points, points)
    if not keep.size:
        return maps
    extra = sweep(mechanism, pset, points[keep], chain, guesses=q)
    more = pose_maps(extra, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    return concat_maps(maps, more)


def _reachable(
    chain: ClosedChain, grid: Sweep, grid_points: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the reachable ``points`` and their joint values, from the nearest grid pose."""
    keep, keep_q = [], []
    for i, p in enumerate(points):
        k = int(np.argmin(np.sum((grid_points - p) ** 2, axis=1)))
        try:
            pose = chain.inverse(p, chain.predict(grid.poses[k], p))
        except KinematicsError:
            continue
        keep.append(i)
        keep_q.append(pose.q_all)
    return np.array(keep, dtype=int), np.array(keep_q)


def concat_maps(a: PoseMaps, b: PoseMaps) -> PoseMaps:
    """The poses of ``a`` then those of ``b`` (stations and groups of ``a`` kept only if both have them)."""
    both = a.stations is not None and b.stations is not None
    groups = a.groups is not None and b.groups is not None
    return PoseMaps(
        points_m=np.concatenate([a.points_m, b.points_m]),
        rotations=np.concatenate([a.rotations, b.rotations]),
        q=np.concatenate([a.q, b.q]),
        commands=np.concatenate([a.commands, b.commands]),
        twist=np.concatenate([a.twist, b.twist]),
        actuation=np.concatenate([a.actuation, b.actuation]),
        reference_point_m=a.reference_point_m,
        task_projection=a.task_projection,
        stations=np.concatenate([a.station_index, b.station_index]) if both else None,
        groups=np.concatenate([a.group_index, b.group_index]) if groups else None,
        task_rows=None
        if a.task_rows is None or b.task_rows is None
        else np.concatenate([a.task_rows, b.task_rows]),
        measured_twist=None
        if a.measured_twist is None or b.measured_twist is None
        else np.concatenate([a.measured_twist, b.measured_twist]),
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
        settings: Instrument, targets, noise, pose count, selection, controller, prior, rank tolerance.
        pool: The candidate poses (:func:`candidate_pool`).
        sigma: Shape (n,): the expected size of every parameter [m or rad] (manufacturing σ for the
            compensatable ones, tolerances for the others; default: the manufacturing σ by unit);
            it scales the columns and sizes the prior.
        poses: N (default ``settings.poses``; the ballbar: circles).
        selection: ``d-optimal`` or ``random`` (default ``settings.selection``).
        chosen: Explicit pool indices (overrides ``poses`` and ``selection``).

    Raises:
        InvalidRequestError: more poses than the pool holds, or fewer values than the unknowns.
    """
    inst = instrument_for(settings, mechanism)
    targets = settings.targets(mechanism)
    n = len(pset)
    scale = settings.manufacturing_sigma(pset) if sigma is None else np.asarray(sigma, dtype=float).copy()
    unit_scale = settings.manufacturing_sigma(pset)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, unit_scale)
    columns = settings.controller_columns(pset, classes)
    sys_pool = linear_system(inst, pool, settings.noise_m)
    ident_pool = identifiability(
        sys_pool.effective,
        columns,
        pset.names,
        pset.units,
        scale,
        len(pool),
        settings.noise_m,
        settings.rank_tolerance,
    )
    base = ident_pool.base_columns
    r = inst.values_per_pose
    machine_w = (sys_pool.machine * sys_pool.weights[:, None]).reshape(len(pool), r, n)
    nuis_w = (sys_pool.nuisance * sys_pool.weights[:, None]).reshape(len(pool), r, -1)
    blocks = np.concatenate(
        [machine_w[:, :, base] * scale[base][None, None, :], nuis_w * inst.nuisance_scale[None, None, :]],
        axis=2,
    )
    count = settings.poses if poses is None else int(poses)
    how = settings.selection if selection is None else selection
    if chosen is None:
        groups = pool.group_index
        labels, first = np.unique(groups, return_index=True)
        labels = labels[np.argsort(first)]
        if count > labels.size:
            what = "circles" if inst.name == "ballbar" else "poses"
            more = {
                "ballbar": "give more stations_m or circle_planes",
                "probe": "raise approach_directions (per sphere; on a plane artifact, touch points per face)",
            }.get(inst.name, "raise candidates")
            raise InvalidRequestError(
                f"{count} calibration {what} asked for, but the candidate pool has {labels.size}; "
                f"lower --poses or {more}"
            )
        members = [np.flatnonzero(groups == g) for g in labels]
        if how == "d-optimal":
            size = max(len(m) for m in members)
            gb = np.zeros((labels.size, size * r, blocks.shape[2]))
            for i, m in enumerate(members):
                gb[i, : len(m) * r] = blocks[m].reshape(-1, blocks.shape[2])
            need = inst.required(pool.points_m, pool.station_index)
            group_of = {int(g): i for i, g in enumerate(labels)}
            fixed = np.unique([group_of[int(groups[k])] for k in need]).astype(int)
            picked = d_optimal(
                gb, count, fixed=fixed if fixed.size <= count else None, nuisance=inst.nuisance_count
            )
        else:
            picked = random_subset(labels.size, count, np.random.default_rng(settings.seed + 7919 * count))
        chosen = np.concatenate([members[i] for i in picked])
    chosen = np.asarray(chosen, dtype=int)
    maps = pool.subset(chosen)
    system = linear_system(inst, maps, settings.noise_m)
    H = system.effective
    ident = identifiability(
        H, columns, pset.names, pset.units, scale, chosen.size, settings.noise_m, settings.rank_tolerance
    )
    unknowns = ident_pool.rank + system.nuisance_rank
    if H.shape[0] < unknowns:
        raise InvalidRequestError(
            f"{chosen.size} poses × {r} value(s) give {H.shape[0]} measured values, fewer than the "
            f"{ident_pool.rank} identifiable combinations of the controller model and "
            f"{system.nuisance_rank} nuisance parameters of the {inst.name}; measure more poses"
            + (" or more targets" if inst.name.startswith("tracker") else "")
        )
    Hs = H[:, base] * scale[base][None, :]
    sign, log_det = np.linalg.slogdet(Hs.T @ Hs)
    return CalibrationPlan(
        settings=settings,
        targets_m=targets,
        chosen=chosen,
        maps=maps,
        H=H,
        ident=ident,
        scale=scale,
        prior_sigma=scale[columns] if settings.prior else None,
        log_det=float(log_det) if sign > 0 else float("-inf"),
        instrument=inst,
        system=system,
        pool_rank=ident_pool.rank,
    )
