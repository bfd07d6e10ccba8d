"""The hybrid machine's inverse kinematics over a task grid: waves of batched solves from solved neighbours.

As :func:`pkmtol.kinematics.continuation.continuation` does for the module alone, but in the
hybrid's task coordinates: a target is the TCP position and, with two wrist actuators, the tool
axis, compared as the 6-vector ``(t, ℓ a)`` with ``ℓ`` = :data:`AXIS_LENGTH_M` (an axis turned by
an angle φ counts as a TCP move of ``ℓ φ``). Each target starts from its nearest solved target's
pose; the first Newton iteration of :meth:`HybridChain.inverse_many` is then the tangent
predictor off that pose.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from pkmtol.exceptions import KinematicsError
from pkmtol.kinematics.hybrid import HybridChain, HybridPose

#: Length that converts an axis angle into a distance in the task metric [m per rad].
AXIS_LENGTH_M = 0.3
#: Poses solved in one lockstep batch.
CHUNK = 512
#: A wave reaches this factor times its spacing.
REACH = 3.0


def hybrid_continuation(
    chain: HybridChain,
    tcp_m: np.ndarray,
    axes: np.ndarray | None,
    start: HybridPose | None = None,
    progress: Callable[[int], object] | None = None,
) -> list[HybridPose | KinematicsError]:
    """Solve every target (TCP position, tool axis) by continuation from ``start`` (default: home).

    Args:
        chain: The hybrid solver.
        tcp_m: Shape (m, 3): TCP targets in K [m].
        axes: Shape (m, 3): target tool axes (None for a locked wrist).
        start: A solved pose the first target is reached from (default: ``chain.home()``).
        progress: Called with the number of targets of each wave.

    Returns:
        Per target: its pose or its error (a failed target is no one's parent).
    """
    tcp = np.asarray(tcp_m, dtype=float).reshape(-1, 3)
    m = len(tcp)
    coords = (
        tcp if axes is None else np.hstack([tcp, AXIS_LENGTH_M * np.asarray(axes, dtype=float).reshape(m, 3)])
    )
    out: list[HybridPose | KinematicsError | None] = [None] * m
    begin = start if start is not None else chain.home()
    at = np.concatenate([begin.tcp_m] + ([] if axes is None else [AXIS_LENGTH_M * begin.axis]))
    first = int(np.argmin(np.linalg.norm(coords - at, axis=1)))
    try:
        out[first] = chain.inverse(tcp[first], None if axes is None else axes[first], begin)
    except KinematicsError as err:
        out[first] = err
    if progress is not None:
        progress(1)
    spacing = _spacing(coords)
    near_d = np.full(m, np.inf)
    near_i = np.full(m, -1)
    todo = np.ones(m, dtype=bool)
    todo[first] = False
    fresh = [first] if isinstance(out[first], HybridPose) else []
    if not fresh:  # the rest from the start pose, in one batch
        rest = np.flatnonzero(todo)
        sols = chain.inverse_many(tcp[rest], None if axes is None else axes[rest], [begin] * len(rest))
        for k, s in zip(rest, sols, strict=True):
            out[k] = s
        return [o for o in out if o is not None]
    while todo.any():
        if fresh:
            dist, best = cKDTree(coords[fresh]).query(coords[todo])
            rows = np.flatnonzero(todo)
            closer = dist < near_d[rows]
            near_i[rows[closer]] = np.asarray(fresh)[best[closer]]
            near_d[rows[closer]] = dist[closer]
        cand = np.flatnonzero(todo & (near_i >= 0))
        if not cand.size:  # the rest have no solved neighbour: from the start pose
            cand = np.flatnonzero(todo)
            guesses = [begin] * len(cand)
            wave = cand
        else:
            reach = max(spacing, float(near_d[cand].min())) * REACH
            wave = cand[near_d[cand] <= reach][:CHUNK]
            guesses = [out[int(near_i[k])] for k in wave]  # type: ignore[misc]
        sols = chain.inverse_many(tcp[wave], None if axes is None else axes[wave], guesses)  # type: ignore[arg-type]
        todo[wave] = False
        fresh = []
        for k, s in zip(wave, sols, strict=True):
            out[int(k)] = s
            if isinstance(s, HybridPose):
                fresh.append(int(k))
        if progress is not None:
            progress(len(wave))
    return [o for o in out if o is not None]


def _spacing(coords: np.ndarray) -> float:
    """The largest distance from a target to its nearest other target (task metric) [m]."""
    if len(coords) < 2:
        return 0.0
    dist, _ = cKDTree(coords).query(coords, k=2)
    return float(dist[:, 1].max())
