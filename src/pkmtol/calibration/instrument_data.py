"""Calibration from an instrument's real data: measured poses → nominal solutions → identification.

As :mod:`pkmtol.calibration.real_data` for the tracker (whose readers and nominal solutions it
reuses): each pose's commands are solved by the nominal mechanism's exact forward kinematics, the
instrument's system there is whitened and has its nuisance parameters projected out
(:mod:`pkmtol.calibration.linear_system`), the controller model's base parameters are found on it,
and Gauss–Newton on exact kinematics fits the machine and the nuisance together
(:func:`pkmtol.calibration.identification.identify_with`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pkmtol.calibration.hybrid_poses import measured_sweep
from pkmtol.calibration.identifiability import Identifiability, identifiability
from pkmtol.calibration.identification import Identification, identify_with
from pkmtol.calibration.instrument_files import InstrumentMeasurements
from pkmtol.calibration.instruments import Instrument, instrument_for
from pkmtol.calibration.linear_system import LinearSystem, linear_system
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.calibration.plan import candidate_pool
from pkmtol.calibration.real_data import nominal_poses
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.error_model.task import grid_sweep
from pkmtol.exceptions import MeasurementFileError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class InstrumentCalibration:
    """A calibration from an instrument's measured data.

    Attributes:
        measurements: What was read.
        instrument: The measurement model.
        maps: The nominal linear maps at the measured poses (with their stations).
        system: The instrument's linear system there.
        ident: Identifiability of the controller model on these poses (nuisance projected out).
        result: The identification (machine and nuisance).
        pool_rank: Rank of the controller model over the instrument's whole candidate pool.
    """

    measurements: InstrumentMeasurements
    instrument: Instrument
    maps: PoseMaps
    system: LinearSystem
    ident: Identifiability
    result: Identification
    pool_rank: int

    @property
    def H(self) -> np.ndarray:
        """The identification Jacobian the estimate used (whitened, nuisance projected out)."""
        return self.system.effective


def calibrate_instrument_data(
    mechanism: Mechanism,
    pset: ParameterSet,
    classes: list[str],
    settings: CalibrationSettings,
    measurements: InstrumentMeasurements,
    path: Path | str,
    sigma: np.ndarray | None = None,
    chain: ClosedChain | None = None,
    grid: Sweep | None = None,
    check: Callable[[PoseMaps], None] | None = None,
) -> InstrumentCalibration:
    """Identify the controller model (and the instrument's nuisance) from measured data.

    ``check`` is called with the nominal maps at the measured poses before the fit; it may raise
    to refuse the data without fitting them (``pkmtol calibrate``: :func:`data_verdict`).

    Raises:
        MeasurementFileError: commands outside the limits or unreachable, or fewer measured values
            than the unknowns.
    """
    path = Path(path)
    chain = chain or ClosedChain(mechanism)
    grid = grid or grid_sweep(mechanism, pset, chain)  # a hybrid's: TCP × tool axis
    inst = instrument_for(settings, mechanism)
    scale = settings.manufacturing_sigma(pset) if sigma is None else np.asarray(sigma, dtype=float)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, settings.manufacturing_sigma(pset))
    columns = settings.controller_columns(pset, classes)
    pool = candidate_pool(
        mechanism, pset, replace(settings, candidates=min(settings.candidates, 60)), chain, grid
    )
    pool_sys = linear_system(inst, pool, settings.noise_m)
    pool_ident = identifiability(
        pool_sys.effective,
        columns,
        pset.names,
        pset.units,
        scale,
        len(pool),
        settings.noise_m,
        settings.rank_tolerance,
    )
    if mechanism.tool is not None:  # a hybrid: its TCP at the commands (calibration/hybrid_poses.py)
        sw: Sweep = measured_sweep(mechanism, pset, grid, measurements.commands, path, measurements.lines)
    else:
        q = nominal_poses(mechanism, chain, grid, measurements.commands, path, measurements.lines)
        points = np.array([chain.forward(u, qk).p_m for u, qk in zip(measurements.commands, q, strict=True)])
        sw = sweep(mechanism, pset, points, chain, guesses=q)
    maps = pose_maps(sw, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection)
    maps = replace(maps, stations=measurements.stations)
    system = linear_system(inst, maps, settings.noise_m)
    unknowns = pool_ident.rank + system.nuisance_rank
    if system.effective.shape[0] < unknowns:
        raise MeasurementFileError(
            path,
            0,
            "",
            f"{len(maps)} poses give {system.effective.shape[0]} measured values, fewer than the "
            f"{pool_ident.rank} identifiable combinations of the '{settings.controller_label}' controller "
            f"model and the {system.nuisance_rank} nuisance parameters of the {inst.name}; "
            "measure more poses",
        )
    ident = identifiability(
        system.effective,
        columns,
        pset.names,
        pset.units,
        scale,
        len(maps),
        settings.noise_m,
        settings.rank_tolerance,
    )
    if check is not None:
        check(maps)
    result = identify_with(
        mechanism, pset, ident, maps, inst, measurements.values, scale[columns] if settings.prior else None
    )
    return InstrumentCalibration(
        measurements=measurements,
        instrument=inst,
        maps=maps,
        system=system,
        ident=ident,
        result=result,
        pool_rank=pool_ident.rank,
    )
