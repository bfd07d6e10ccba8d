"""A hybrid machine's calibration poses: the candidate pool and the held-out poses over its task space.

The task space of a hybrid is TCP points × tool axes (:func:`pkmtol.error_model.tool_sweep.tool_task_grid`).
The candidate pool is that grid plus ``settings.candidates`` random targets (TCP uniform in the
task space, axis uniform over the cone), the held-out poses ``count`` random targets; each is
solved from its nearest grid pose, unreachable or singular draws are skipped, and the solved poses
are separated by the whole machine's error model (:func:`hybrid_sweep`) so that
:func:`pkmtol.calibration.maps.pose_maps` gives their maps at the TCP. The instrument is a tracker
on the TCP (``tracker``, ``tracker-multi`` with targets in the TCP frame, or ``tracker-6d``: a 6D
probe on the TCP frame reading the TCP and the frame's orientation; on the spindle nose with
``tracker_on = "nose"``). Measured poses
(``pkmtol calibrate --measurements``) are solved by the nominal machine's forward kinematics at
their commands (:func:`measured_sweep`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from pkmtol.calibration.hybrid_machine import HybridMachine, nominal_poses
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.calibration.measurement_files import actuator_columns
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.task import grid_sweep, tool_scope
from pkmtol.error_model.tool_chain import HybridParameterSet
from pkmtol.error_model.tool_sweep import (
    ToolSweep,
    hybrid_sweep,
    nearest_poses,
    tool_task_sample,
    tracker_on,
)
from pkmtol.exceptions import InvalidRequestError, MeasurementFileError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.hybrid import HybridChain, HybridPose
from pkmtol.model.mechanism import Mechanism

#: The instruments a hybrid's calibration models (a tracker's targets, or its 6D probe, on the TCP frame).
INSTRUMENTS = ("tracker", "tracker-multi", "tracker-6d")


def check_instrument(mechanism: Mechanism, settings: CalibrationSettings) -> None:
    """Refuse an instrument the hybrid's calibration does not model.

    Raises:
        InvalidRequestError: not a tracker (a ballbar's circles and a probe's artifact are placed
            in the module's task space, around P; docs/hybrid.md).
    """
    if settings.instrument not in INSTRUMENTS:
        raise InvalidRequestError(
            f"'{mechanism.name}' is a hybrid machine: its calibration models a laser tracker whose "
            f"targets (or 6D probe) sit on the TCP frame (instrument = {', '.join(INSTRUMENTS)}), not a "
            f"{settings.instrument}; set [calibration] instrument or --instrument to tracker"
        )


def with_tracker_on(mechanism: Mechanism, point: str) -> Mechanism:
    """The mechanism with ``[calibration] tracker_on = point`` (``tcp`` or ``nose``).

    Raises:
        InvalidRequestError: the mechanism has no tool chain, or ``point`` is neither.
    """
    if mechanism.tool is None:
        raise InvalidRequestError(
            f"--tracker-on {point}: '{mechanism.name}' has no tool chain; the tracker's targets of a "
            "module sit on its platform ([calibration] targets_m)"
        )
    table = {**(mechanism.extra.get("calibration") or {}), "tracker_on": point}
    out = dataclasses.replace(mechanism, extra={**mechanism.extra, "calibration": table})
    tracker_on(out)  # checks the value
    return out


def _tool_grid(
    mechanism: Mechanism, pset: ParameterSet, chain: ClosedChain | None, grid: Sweep | None
) -> ToolSweep:
    sw = grid if grid is not None else grid_sweep(mechanism, pset, chain)
    if not isinstance(sw, ToolSweep):
        raise InvalidRequestError(
            f"'{mechanism.name}': a hybrid machine's poses need its grid sweep (grid_sweep)"
        )
    return sw


def solved_targets(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: ToolSweep,
    tcp_m: np.ndarray,
    axes: np.ndarray | None,
    chain: ClosedChain | None = None,
) -> tuple[ToolSweep | None, int]:
    """The whole machine's sweep at the reachable targets among ``tcp_m``/``axes``, and how many were skipped.

    Each target starts from its nearest grid pose; a target that does not solve (out of reach, a
    wrist limit, a singular pose) is skipped. None when none solves.
    """
    assert isinstance(pset, HybridParameterSet)
    hc = HybridChain(mechanism, chain)
    solved = hc.inverse_many(tcp_m, axes, nearest_poses(grid, tcp_m, axes))
    keep = np.array([i for i, s in enumerate(solved) if isinstance(s, HybridPose)], dtype=int)
    skipped = len(solved) - keep.size
    if not keep.size:
        return None, skipped
    guesses = [s for s in solved if isinstance(s, HybridPose)]
    sw = hybrid_sweep(
        mechanism,
        pset,
        np.asarray(tcp_m)[keep],
        None if axes is None else np.asarray(axes)[keep],
        hc,
        tool_scope(mechanism),
        guesses=guesses,
    )
    return sw, skipped


def hybrid_pool(
    mechanism: Mechanism,
    pset: ParameterSet,
    settings: CalibrationSettings,
    chain: ClosedChain | None = None,
    grid: Sweep | None = None,
) -> PoseMaps:
    """The candidate poses of a hybrid's plan: the task grid and ``settings.candidates`` random targets.

    Raises:
        InvalidRequestError: an instrument other than a tracker.
    """
    check_instrument(mechanism, settings)
    sw = _tool_grid(mechanism, pset, chain, grid)
    act = ClosedChain(mechanism).actuated_idx if chain is None else chain.actuated_idx
    if settings.candidates == 0:
        return pose_maps(sw, act, np.zeros(3))
    tcp, axes = tool_task_sample(mechanism, np.random.default_rng(settings.seed), settings.candidates)
    extra, _ = solved_targets(mechanism, pset, sw, tcp, axes, chain)
    if extra is None:
        return pose_maps(sw, act, np.zeros(3))
    both_axes = None if sw.axes is None or extra.axes is None else np.vstack([sw.axes, extra.axes])
    both = hybrid_sweep(
        mechanism,
        pset,  # type: ignore[arg-type]
        np.vstack([sw.points_m, extra.points_m]),
        both_axes,
        HybridChain(mechanism, chain),
        tool_scope(mechanism),
        guesses=list(sw.hybrid_poses) + list(extra.hybrid_poses),
    )
    return pose_maps(both, act, np.zeros(3))


def hybrid_holdout_sweep(
    mechanism: Mechanism,
    pset: ParameterSet,
    count: int,
    rng: np.random.Generator,
    chain: ClosedChain | None = None,
) -> tuple[ToolSweep, int]:
    """``count`` random targets of the task (TCP × axis), solved and separated; and the draws skipped.

    Raises:
        InvalidRequestError: not one draw is reachable.
    """
    grid = _tool_grid(mechanism, pset, chain, None)
    tcp, axes = tool_task_sample(mechanism, rng, count)
    sw, skipped = solved_targets(mechanism, pset, grid, tcp, axes, chain)
    if sw is None:
        raise InvalidRequestError(
            f"'{mechanism.name}': no random target of the TCP's task space is reachable; check the task space"
        )
    return sw, skipped


def measured_sweep(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep | None,
    commands: np.ndarray,
    path: Path,
    lines: np.ndarray,
) -> ToolSweep:
    """The nominal machine at measured commands (N, f + w): its TCP and tool axis there, separated.

    Each pose is solved by the nominal machine's exact forward kinematics from the grid pose with
    the closest commands.

    Raises:
        MeasurementFileError: a command outside its joint's limits, or commands the nominal machine
            cannot reach from the grid (names the line).
    """
    sw = _tool_grid(mechanism, pset, None, grid)
    chain = ClosedChain(mechanism)
    gm = pose_maps(sw, chain.actuated_idx, np.zeros(3))
    tool = mechanism.tool
    assert tool is not None
    act = list(tool.actuated)
    lower = np.concatenate([chain.lower[chain.actuated_idx], tool.model.lowerPositionLimit[act]])
    upper = np.concatenate([chain.upper[chain.actuated_idx], tool.model.upperPositionLimit[act]])
    names = [c for c, _ in actuator_columns(mechanism)]
    u = np.atleast_2d(np.asarray(commands, dtype=float))
    for k, row in enumerate(u):
        bad = np.flatnonzero((row < lower - 1e-12) | (row > upper + 1e-12))
        if bad.size:
            j = int(bad[0])
            raise MeasurementFileError(
                path,
                int(lines[k]),
                names[j],
                f"command {row[j]:.6g} is outside the joint's limits [{lower[j]:.6g}, {upper[j]:.6g}] "
                "(SI units: m or rad)",
            )
    span = np.maximum(np.ptp(gm.commands, axis=0), 1e-9)
    near = np.argmin((((gm.commands[None] - u[:, None]) / span) ** 2).sum(axis=2), axis=1)
    sols = HybridMachine(mechanism, pset, np.zeros(len(pset))).forward_many(u, gm.q[near])
    for k, err in enumerate(sols.errors):
        if err is not None:
            raise MeasurementFileError(
                path,
                int(lines[k]),
                "",
                f"the nominal machine cannot reach these commands ({err}); check the commands and units",
            )
    axes = None if mechanism.tool_directions is None else sols.rotation[:, :, 2]
    return hybrid_sweep(
        mechanism,
        pset,  # type: ignore[arg-type]
        sols.translation,
        axes,
        HybridChain(mechanism, chain),
        tool_scope(mechanism),
        guesses=nominal_poses(mechanism, sols.q),
    )
