"""Identification on exact kinematics: the fit of the controller model to an instrument's data.

Every residual is a measured value minus the exact model of the mechanism perturbed by the
current estimate, at the commanded actuator readings (:class:`Machine`). The unknowns are the base
parameters of :mod:`pkmtol.calibration.identifiability` (least squares), or every parameter of the
controller model with a Gaussian prior (MAP, ``prior_sigma``), plus the instrument's nuisance
parameters. The iteration, and how its stop is certified on the Jacobian at the estimate, is
:mod:`pkmtol.calibration.gauss_newton`.
"""

from __future__ import annotations

import numpy as np

from pkmtol.calibration.estimate_maps import twist_maps_at
from pkmtol.calibration.gauss_newton import EstimateRows, Identification, Rows, gauss_newton, solved_poses
from pkmtol.calibration.identifiability import Identifiability
from pkmtol.calibration.instruments.base import Instrument
from pkmtol.calibration.instruments.tracker import TrackerPoints
from pkmtol.calibration.linear_system import value_weights
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.maps import PoseMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import InvalidRequestError
from pkmtol.kinematics.solutions import Solutions
from pkmtol.model.mechanism import Mechanism

__all__ = [
    "Identification",
    "identify",
    "identify_with",
    "machine_poses",
    "model_positions",
    "solved_poses",
]


def model_positions(
    machine: Machine, commands: np.ndarray, q0: np.ndarray, targets_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact target positions of ``machine`` at readings ``commands`` (N, f).

    Returns:
        ``(positions (N, t, 3) [m], q (N, Σ nq))``.

    Raises:
        IdentificationError: a pose cannot be solved (names it).
    """
    targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
    sols = solved_poses(machine, commands, q0)
    out = sols.translation[:, None, :] + np.einsum("kij,tj->kti", sols.rotation, targets)
    return out, sols.q


def machine_poses(
    machine: Machine, commands: np.ndarray, q0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact platform poses of ``machine`` at readings ``commands`` (N, f).

    Returns:
        ``(origin (N, 3) [m], rotation (N, 3, 3), q (N, Σ nq))``.

    Raises:
        IdentificationError: a pose cannot be solved (names it).
    """
    sols = solved_poses(machine, commands, q0)
    return sols.translation, sols.rotation, sols.q


def identify(
    mechanism: Mechanism,
    pset: ParameterSet,
    ident: Identifiability,
    H: np.ndarray,
    commands: np.ndarray,
    q_guess: np.ndarray,
    measured_m: np.ndarray,
    targets_m: np.ndarray,
    prior_sigma: np.ndarray | None = None,
) -> Identification:
    """Fit the controller model to tracker positions (a registered frame) by Gauss–Newton on exact kinematics.

    Args:
        mechanism: The nominal mechanism.
        pset: Its parameter set (``n`` parameters).
        ident: The base parameters of the controller model on these poses.
        H: Shape (3·N·t, n): measured coordinates per unit parameter at the nominal point, rows in
            the order pose, target, axis (:meth:`PoseMaps.measurement_rows`, reshaped).
        commands: Shape (N, f): commanded actuator readings of the calibration poses.
        q_guess: Shape (N, Σ nq): initial joint values at those poses (e.g. the nominal ones).
        measured_m: Shape (N, t, 3): measured target positions in K [m].
        targets_m: Shape (t, 3): targets in the platform frame [m].
        prior_sigma: Shape (p,): prior σ of each controller parameter (MAP); None: least squares on
            the base parameters.

    Raises:
        InvalidRequestError: the shapes disagree.
        IdentificationError: the model cannot be solved at a pose during the iterations.
    """
    N = len(commands)
    targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
    measured = np.asarray(measured_m, dtype=float)
    if measured.shape != (N, targets.shape[0], 3) or H.shape[0] != measured.size:
        raise InvalidRequestError(
            f"measurements of shape {measured.shape} and a Jacobian of {H.shape[0]} rows do not fit "
            f"{N} poses × {targets.shape[0]} targets × 3 coordinates"
        )
    tracker = TrackerPoints(targets, ident.noise_m)
    out = gauss_newton(
        mechanism,
        pset,
        ident,
        tracker,
        np.zeros(N, dtype=int),
        commands,
        q_guess,
        measured.reshape(N, -1),
        H,
        np.zeros((H.shape[0], 0)),
        np.ones(H.shape[0]),
        prior_sigma,
        at_estimate=rows_at_estimate(tracker, np.zeros(N, dtype=int)),
    )
    return _reshaped(out, (N, targets.shape[0], 3))


def identify_with(
    mechanism: Mechanism,
    pset: ParameterSet,
    ident: Identifiability,
    maps: PoseMaps,
    instrument: Instrument,
    measured: np.ndarray,
    prior_sigma: np.ndarray | None = None,
) -> Identification:
    """Fit the controller model and the instrument's nuisance parameters to any instrument's data.

    The instrument first fixes where to linearise (:meth:`Instrument.start`: a tracker frame is
    registered in closed form); the frozen Jacobian is its twist rows times the nominal twist maps
    and its nuisance rows there, every value whitened by its σ to ``ident.noise_m``.

    Args:
        mechanism: The nominal mechanism.
        pset: Its parameter set.
        ident: The base parameters of the controller model (on the projected system).
        maps: The nominal maps at the measured poses (commands, joints, twists, stations).
        instrument: The measurement model.
        measured: Shape (N, r): the measured values [m or rad].
        prior_sigma: The MAP prior of each controller parameter (None: least squares).

    Raises:
        InvalidRequestError: the shapes disagree, or the data cannot start the instrument.
        IdentificationError: the model cannot be solved at a pose during the iterations.
    """
    N, r = len(maps), instrument.values_per_pose
    y = np.asarray(measured, dtype=float)
    if y.shape != (N, r):
        raise InvalidRequestError(f"measurements of shape {y.shape} do not fit {N} poses × {r} values")
    nominal = Machine(mechanism, pset, np.zeros(len(pset)))
    origin, rot, q0 = machine_poses(nominal, maps.commands, maps.q)
    inst, pi0 = instrument.start(y, origin, rot, maps.station_index)
    st = maps.station_index

    def rows_at(o: np.ndarray, R: np.ndarray, pi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rows = inst.twist_rows(o, R, st, pi)
        H = np.einsum("kra,kan->krn", rows, maps.measurement_twist).reshape(N * r, -1)
        return H, inst.nuisance_rows(o, R, st, pi).reshape(N * r, -1)

    H, Hp = rows_at(origin, rot, pi0)
    w = value_weights(inst, N, ident.noise_m)
    refresh = rows_at if inst.refresh_rows else None
    return gauss_newton(
        mechanism,
        pset,
        ident,
        inst,
        st,
        maps.commands,
        q0,
        y,
        H,
        Hp,
        w,
        prior_sigma,
        pi0,
        refresh,
        # a tracker on a hybrid's spindle nose reads another body's twist: no analytic maps there yet
        rows_at_estimate(inst, st) if maps.measured_twist is None else None,
    )


def rows_at_estimate(inst: Instrument, stations: np.ndarray) -> EstimateRows:
    """The Gauss–Newton rows of ``inst`` on the analytic Jacobian at an estimate.

    The callback takes the estimate's machine, its solved poses and the nuisance parameters, and
    returns ``(H, H_π)`` there (:func:`pkmtol.calibration.estimate_maps.twist_maps_at` times the
    instrument's rows at those poses), or None where the maps are not available (a hybrid).
    """

    def rows(machine: Machine, sols: Solutions, pi: np.ndarray) -> Rows | None:
        twist = twist_maps_at(machine, sols)
        if twist is None:
            return None
        M = twist.shape[0] * inst.values_per_pose
        twist_rows = inst.twist_rows(sols.translation, sols.rotation, stations, pi)
        H = np.einsum("kra,kan->krn", twist_rows, twist).reshape(M, -1)
        return H, inst.nuisance_rows(sols.translation, sols.rotation, stations, pi).reshape(M, -1)

    return rows


def _reshaped(out: Identification, shape: tuple[int, ...]) -> Identification:
    return Identification(
        method=out.method,
        names=out.names,
        identified=out.identified,
        covariance=out.covariance,
        estimate=out.estimate,
        residuals_m=out.residuals_m.reshape(shape),
        residuals_before_m=out.residuals_before_m.reshape(shape),
        iterations=out.iterations,
        converged=out.converged,
        q=out.q,
        nuisance=out.nuisance,
        nuisance_covariance=out.nuisance_covariance,
        instrument=out.instrument,
        weighted_rms=out.weighted_rms,
    )
