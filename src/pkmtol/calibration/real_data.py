"""Calibration from real tracker data: measured poses → nominal solutions → identification.

The commands of each measured pose are solved by the nominal mechanism's exact forward kinematics
(started from the grid pose with the closest commands, by continuation if Newton does not reach
it directly); the linear maps there give the identification Jacobian; Gauss–Newton on exact
kinematics fits the controller model (:func:`pkmtol.calibration.identification.identify`).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pkmtol.calibration.hybrid_poses import measured_sweep
from pkmtol.calibration.identifiability import Identifiability, identifiability
from pkmtol.calibration.identification import Identification, identify
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.calibration.measurement_files import Measurements, actuator_columns
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.error_model.task import grid_sweep
from pkmtol.exceptions import KinematicsError, MeasurementFileError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism

#: Continuation steps from the nearest grid pose when Newton does not reach a pose directly.
CONTINUATION_STEPS = 16


@dataclass(frozen=True, eq=False)
class RealCalibration:
    """A calibration from measured data.

    Attributes:
        measurements: What was read.
        maps: The nominal linear maps at the measured poses.
        H: Shape (3·N·t, n): the identification Jacobian there.
        ident: Identifiability of the controller model on these poses.
        result: The identification.
        pool_rank: Rank of the controller model over the whole task-space grid (what a rich plan
            would identify).
    """

    measurements: Measurements
    maps: PoseMaps
    H: np.ndarray
    ident: Identifiability
    result: Identification
    pool_rank: int


def nominal_poses(
    mechanism: Mechanism, chain: ClosedChain, grid: Sweep, commands: np.ndarray, path: Path, lines: np.ndarray
) -> np.ndarray:
    """Nominal joint values (N, Σ nq) at each commanded pose (exact forward kinematics).

    Raises:
        MeasurementFileError: a command is outside its joint's limits, or the nominal mechanism
            cannot reach it (names the line).
    """
    acts = actuator_columns(mechanism)
    idx = chain.actuated_idx
    lower, upper = chain.lower[idx], chain.upper[idx]
    grid_q = np.array([p.q_all for p in grid.poses])
    grid_u = grid_q[:, idx]
    span = np.maximum(grid_u.max(axis=0) - grid_u.min(axis=0), 1e-9)
    out = np.empty((len(commands), grid_q.shape[1]))
    for k, u in enumerate(commands):
        bad = np.flatnonzero((u < lower - 1e-12) | (u > upper + 1e-12))
        if bad.size:
            j = int(bad[0])
            raise MeasurementFileError(
                path,
                int(lines[k]),
                acts[j][0],
                f"command {u[j]:.6g} is outside the joint's limits "
                f"[{lower[j]:.6g}, {upper[j]:.6g}] (SI units: m or rad)",
            )
        near = int(np.argmin(np.sum(((grid_u - u) / span) ** 2, axis=1)))
        q0 = grid_q[near]
        try:
            out[k] = chain.forward(u, q0).q_all
            continue
        except KinematicsError:
            pass
        q = q0.copy()
        try:
            for s in np.linspace(0.0, 1.0, CONTINUATION_STEPS + 1)[1:]:
                q = chain.forward(grid_u[near] + s * (u - grid_u[near]), q).q_all
        except KinematicsError as err:
            raise MeasurementFileError(
                path,
                int(lines[k]),
                "",
                f"the nominal mechanism cannot reach these commands ({err}); check the commands and units",
            ) from err
        out[k] = q
    return out


def calibrate_measurements(
    mechanism: Mechanism,
    pset: ParameterSet,
    classes: list[str],
    settings: CalibrationSettings,
    measurements: Measurements,
    path: Path | str,
    sigma: np.ndarray | None = None,
    chain: ClosedChain | None = None,
    grid: Sweep | None = None,
    check: Callable[[PoseMaps], None] | None = None,
) -> RealCalibration:
    """Identify the controller model from measured data.

    Args:
        mechanism: The nominal mechanism.
        pset: Its parameter set.
        classes: The class of every parameter.
        settings: Targets, noise σ_m, controller model, prior, rank tolerance.
        measurements: What :func:`read_measurements` read.
        path: The file (for error messages).
        sigma: Expected size of every parameter (column scaling, prior); default manufacturing σ.
        chain: Solver workspace (created if None).
        grid: The task-space grid sweep (created if None).
        check: Called with the nominal maps at the measured poses before the fit; it may raise to
            refuse the data without fitting them (``pkmtol calibrate``: :func:`data_verdict`).

    Raises:
        MeasurementFileError: commands outside the limits or unreachable, or fewer measured
            coordinates than the controller model's identifiable combinations.
    """
    path = Path(path)
    chain = chain or ClosedChain(mechanism)
    grid = grid or grid_sweep(mechanism, pset, chain)  # a hybrid's: TCP × tool axis
    targets = settings.targets(mechanism)
    scale = settings.manufacturing_sigma(pset) if sigma is None else np.asarray(sigma, dtype=float)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, settings.manufacturing_sigma(pset))
    columns = settings.controller_columns(pset, classes)
    pool = _pool_identifiability(mechanism, pset, settings, chain, grid, targets, columns, scale)
    if mechanism.tool is not None:  # a hybrid: its TCP at the commands (calibration/hybrid_poses.py)
        sw: Sweep = measured_sweep(mechanism, pset, grid, measurements.commands, path, measurements.lines)
    else:
        q = nominal_poses(mechanism, chain, grid, measurements.commands, path, measurements.lines)
        points = np.array([chain.forward(u, qk).p_m for u, qk in zip(measurements.commands, q, strict=True)])
        sw = sweep(mechanism, pset, points, chain, guesses=q)
    maps = pose_maps(sw, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    H = maps.measurement_rows(targets).reshape(-1, len(pset))
    if H.shape[0] < pool.rank:
        raise MeasurementFileError(
            path,
            0,
            "",
            f"{measurements.commands.shape[0]} poses × {targets.shape[0]} target(s) give {H.shape[0]} "
            f"measured coordinates, fewer than the {pool.rank} identifiable combinations of the "
            f"'{settings.controller_label}' controller model; measure more poses",
        )
    ident = identifiability(
        H, columns, pset.names, pset.units, scale, len(maps), settings.noise_m, settings.rank_tolerance
    )
    if check is not None:
        check(maps)
    result = identify(
        mechanism,
        pset,
        ident,
        H,
        maps.commands,
        maps.q,
        measurements.measured_m,
        targets,
        scale[columns] if settings.prior else None,
    )
    return RealCalibration(
        measurements=measurements, maps=maps, H=H, ident=ident, result=result, pool_rank=pool.rank
    )


#: The pool's identifiability per grid sweep (the grid's QR is the largest fixed cost of a run).
_POOLS: weakref.WeakKeyDictionary[Sweep, dict[tuple, Identifiability]] = weakref.WeakKeyDictionary()


def _pool_identifiability(
    mechanism: Mechanism,
    pset: ParameterSet,
    settings: CalibrationSettings,
    chain: ClosedChain,
    grid: Sweep,
    targets: np.ndarray,
    columns: np.ndarray,
    scale: np.ndarray,
) -> Identifiability:
    """Identifiability of the controller model over the grid, once per grid sweep and settings."""
    key = (
        tuple(pset.names),
        np.asarray(targets, dtype=float).tobytes(),
        np.asarray(columns).tobytes(),
        np.asarray(scale, dtype=float).tobytes(),
        float(settings.noise_m),
        float(settings.rank_tolerance),
    )
    per_grid = _POOLS.setdefault(grid, {})
    if key not in per_grid:
        grid_maps = pose_maps(
            grid, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection
        )
        H_grid = grid_maps.measurement_rows(targets).reshape(-1, len(pset))
        per_grid[key] = identifiability(
            H_grid,
            columns,
            pset.names,
            pset.units,
            scale,
            len(grid_maps),
            settings.noise_m,
            settings.rank_tolerance,
        )
    return per_grid[key]
