"""The task of any mechanism: its parameter set, its grid sweep and its random sweep (module or hybrid).

The design stage asks these three for what it evaluates, so one job runs a parallel module (P's
position, :func:`pkmtol.error_model.sweep.sweep`) and a hybrid machine (the TCP and the tool
axis, :func:`pkmtol.error_model.tool_sweep.hybrid_sweep`) alike. A hybrid's compensation scope
(``machine``: every actuator, the default; ``module``: the module's Eq. 25, the wrist held) is
``mechanism.extra["tool_scope"]`` (``pkmtol allocate --compensate-with``).
"""

from __future__ import annotations

import numpy as np

from pkmtol.error_model.parameters import ParameterSet, default_set, parameter_set
from pkmtol.error_model.sweep import Sweep, guesses_near, sweep
from pkmtol.error_model.tool_chain import SCOPES, HybridParameterSet, hybrid_parameter_set
from pkmtol.error_model.tool_sweep import (
    ToolSweep,
    hybrid_sweep,
    nearest_poses,
    tool_task_grid,
    tool_task_sample,
)
from pkmtol.exceptions import InvalidRequestError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.hybrid import HybridChain
from pkmtol.model.mechanism import Mechanism


def machine_parameter_set(mechanism: Mechanism, kind: str | None = None) -> ParameterSet:
    """The module's set (``kind``, default :func:`default_set`), then a hybrid's tool parameters."""
    k = kind or default_set(mechanism)
    return hybrid_parameter_set(mechanism, k) if mechanism.tool is not None else parameter_set(mechanism, k)


def tool_scope(mechanism: Mechanism) -> str:
    """The hybrid's compensation scope (``machine`` unless ``extra["tool_scope"]`` says ``module``)."""
    scope = str(mechanism.extra.get("tool_scope", "machine"))
    if scope not in SCOPES:
        raise InvalidRequestError(f"unknown compensation scope {scope!r}; use one of {', '.join(SCOPES)}")
    return scope


def grid_sweep(
    mechanism: Mechanism, pset: ParameterSet, chain: ClosedChain | None = None, progress: bool = False
) -> Sweep:
    """The error model over the task grid: P's points, or the TCP points × tool axes of a hybrid."""
    if mechanism.tool is None:
        return sweep(mechanism, pset, mechanism.task_space.grid(), chain, progress=progress)
    tcp, axes = tool_task_grid(mechanism)
    return hybrid_sweep(
        mechanism,
        _hybrid(pset),
        tcp,
        axes,
        HybridChain(mechanism, chain),
        tool_scope(mechanism),
        progress=progress,
    )


def sample_sweep(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep,
    rng: np.random.Generator,
    count: int,
    chain: ClosedChain | None = None,
    progress: bool = False,
) -> Sweep:
    """The error model at ``count`` random task targets, each solved from its nearest grid pose."""
    if mechanism.tool is None:
        points = mechanism.task_space.sample(rng, count)
        return sweep(mechanism, pset, points, chain, guesses=guesses_near(grid, points), progress=progress)
    if not isinstance(grid, ToolSweep):
        raise InvalidRequestError("a hybrid machine's random sweep needs its grid sweep (grid_sweep)")
    tcp, axes = tool_task_sample(mechanism, rng, count)
    return hybrid_sweep(
        mechanism,
        _hybrid(pset),
        tcp,
        axes,
        HybridChain(mechanism, chain),
        tool_scope(mechanism),
        guesses=nearest_poses(grid, tcp, axes),
        progress=progress,
    )


def _hybrid(pset: ParameterSet) -> HybridParameterSet:
    if not isinstance(pset, HybridParameterSet):
        raise InvalidRequestError(
            "a hybrid machine needs its parameter set with the tool's parameters (machine_parameter_set)"
        )
    return pset


def probe_sweep(mechanism: Mechanism, pset: ParameterSet, index: np.ndarray) -> Sweep:
    """The error model at the grid targets ``index`` only (e.g. a few, for a memory estimate)."""
    idx = np.asarray(index, dtype=int)
    if mechanism.tool is None:
        return sweep(mechanism, pset, mechanism.task_space.grid()[idx])
    tcp, axes = tool_task_grid(mechanism)
    return hybrid_sweep(
        mechanism, _hybrid(pset), tcp[idx], None if axes is None else axes[idx], scope=tool_scope(mechanism)
    )
