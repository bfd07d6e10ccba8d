"""The whole machine's error model over a task grid: TCP points × tool axes, solved and separated.

:func:`hybrid_sweep` returns a :class:`ToolSweep`, a :class:`~pkmtol.error_model.sweep.Sweep`
whose poses are the TCP's and whose separations are :class:`ToolSeparation` (the TCP's maps),
so the design stage reads it as it reads the module's sweep: ``J`` is the TCP position error,
the separations' rotation rows give the tool axis (``[design] tool_axis`` = z of the TCP frame).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

import pkmtol.values as values
from pkmtol.error_model.parameters import check_set
from pkmtol.error_model.separation import separate_many
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.tool_chain import HybridParameterSet, ToolSeparation, task_targets, tool_separation
from pkmtol.exceptions import InvalidRequestError, KinematicsError
from pkmtol.kinematics.hybrid import HybridChain, HybridPose, task_grid
from pkmtol.kinematics.hybrid_continuation import hybrid_continuation
from pkmtol.model.mechanism import Mechanism

#: Poses separated together.
CHUNK = 512
#: Where a hybrid's calibration tracker targets can sit (``[calibration] tracker_on``).
TRACKER_POINTS = ("tcp", "nose")


@dataclass(frozen=True, eq=False)
class ToolSweep(Sweep):
    """Separations of the whole machine at a list of task targets (TCP position, tool axis).

    Attributes:
        axes: Shape (m, 3): the target tool axes (None for a locked wrist).
        hybrid_poses: The machine's poses.
        scope: ``machine`` or ``module`` (:mod:`pkmtol.error_model.tool_chain`).
        tool_actuated: The actuated joints of the tool chain (indices into its q).
        tracker_on: Where a calibration's tracker targets sit: ``tcp`` (on the TCP frame) or
            ``nose`` (on the spindle: the tool's own errors do not move them);
            ``[calibration] tracker_on`` of the mechanism.
    """

    axes: np.ndarray | None = None
    hybrid_poses: tuple[HybridPose, ...] = ()
    scope: str = "machine"
    tool_actuated: tuple[int, ...] = ()
    tracker_on: str = "tcp"


def tracker_on(mechanism: Mechanism) -> str:
    """Where a calibration's tracker targets sit on a hybrid: ``tcp`` (default) or ``nose``.

    ``[calibration] tracker_on`` (``pkmtol calibrate --tracker-on``).

    Raises:
        InvalidRequestError: another value.
    """
    value = (mechanism.extra.get("calibration") or {}).get("tracker_on", "tcp")
    if value not in TRACKER_POINTS:
        raise InvalidRequestError(
            f"calibration.tracker_on = {value!r}: use one of {', '.join(TRACKER_POINTS)} (the TCP frame, "
            "or the spindle nose: targets that the tool's own errors do not move)"
        )
    return str(value)


def tool_task_grid(mechanism: Mechanism) -> tuple[np.ndarray, np.ndarray | None]:
    """The task grid: every TCP point with every tool axis (:func:`pkmtol.kinematics.hybrid.task_grid`)."""
    return task_grid(mechanism)


def tool_task_sample(
    mechanism: Mechanism, rng: np.random.Generator, count: int
) -> tuple[np.ndarray, np.ndarray | None]:
    """``count`` random targets: TCP points uniform in the task space, axes uniform over the cone."""
    points = mechanism.task_space.sample(rng, count)
    if mechanism.tool_directions is None:
        return points, None
    return points, mechanism.tool_directions.sample(rng, count)


def hybrid_sweep(
    mechanism: Mechanism,
    pset: HybridParameterSet,
    tcp_m: np.ndarray,
    axes: np.ndarray | None,
    chain: HybridChain | None = None,
    scope: str = "machine",
    guesses: Sequence[HybridPose] | None = None,
    progress: bool = False,
) -> ToolSweep:
    """Solve the machine at every target and separate its errors there.

    Args:
        mechanism: The hybrid machine.
        pset: Its parameter set (:func:`~pkmtol.error_model.tool_chain.hybrid_parameter_set`).
        tcp_m: Shape (m, 3): TCP targets in K [m].
        axes: Shape (m, 3): target tool axes (None for a locked wrist).
        chain: The solver (created if None).
        scope: ``machine`` or ``module``.
        guesses: One solved pose per target to start from (default: continuation from home).
        progress: Show a progress bar.

    Raises:
        KinematicsError: the first target (in order) that cannot be solved or separated.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism with a [tool] chain")
    if not isinstance(pset, HybridParameterSet):
        raise InvalidRequestError(
            "a hybrid machine needs its hybrid_parameter_set (module + tool parameters)"
        )
    check_set(pset, mechanism)
    tcp = values.points("tcp_m", tcp_m)
    m = len(tcp)
    axes = values.optional(values.array_of_shape, "axes", axes, (m, 3))
    values.optional(values.instance, "chain", chain, HybridChain, "a HybridChain of the mechanism, or None")
    values.choice("scope", scope, ("machine", "module"))
    if guesses is not None:
        guesses = values.instances("guesses", guesses, HybridPose, "solved HybridPose", m)
    values.flag("progress", progress)
    hc = chain or HybridChain(mechanism)
    bar = tqdm(total=m, desc="poses", unit="pose", disable=not progress, leave=False)
    if guesses is None:
        solved = hybrid_continuation(hc, tcp, axes, progress=bar.update)
    else:
        solved = hc.inverse_many(tcp, axes, list(guesses))
    bar.close()
    failed = next((s for s in solved if isinstance(s, KinematicsError)), None)
    if failed is not None:
        raise failed
    poses = [s for s in solved if isinstance(s, HybridPose)]
    targets = task_targets(mechanism)
    module_set = pset.module_set()
    seps: list[ToolSeparation] = []
    for start in range(0, m, CHUNK):
        part = poses[start : start + CHUNK]
        sols = hc.batch.inverse(
            np.array([h.module.p_m for h in part]), np.array([h.module.q_all for h in part])
        )
        for h, ms in zip(part, separate_many(mechanism, module_set, hc.batch, sols), strict=True):
            if isinstance(ms, KinematicsError):
                raise ms
            seps.append(tool_separation(mechanism, pset, h, ms, scope, targets))
    n = len(pset)
    return ToolSweep(
        points_m=tcp,
        poses=tuple(s.pose for s in seps),
        separations=tuple(seps),
        J=np.array([s.J for s in seps]).reshape(m, 3, n),
        J_total=np.array([s.J_total for s in seps]).reshape(m, 3, n),
        W_condition=np.array([s.W_condition for s in seps]),
        axes=None if axes is None else np.asarray(axes, dtype=float).reshape(m, 3),
        hybrid_poses=tuple(poses),
        scope=scope,
        tool_actuated=tuple(hc.actuated),
        tracker_on=tracker_on(mechanism),
    )


def nearest_poses(
    grid: ToolSweep, tcp_m: np.ndarray, axes: np.ndarray | None, axis_length_m: float = 0.3
) -> list[HybridPose]:
    """For each target, the grid's nearest solved pose (task metric ``(t, ℓ a)``) as its first guess."""
    tcp = np.asarray(tcp_m, dtype=float).reshape(-1, 3)
    g = grid.points_m
    d = ((tcp[:, None, :] - g[None]) ** 2).sum(-1)
    if axes is not None and grid.axes is not None:
        d = d + axis_length_m**2 * ((np.asarray(axes)[:, None, :] - grid.axes[None]) ** 2).sum(-1)
    return [grid.hybrid_poses[int(k)] for k in d.argmin(axis=1)]
