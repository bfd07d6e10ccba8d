"""The identification's Jacobian at the estimate: the error model of the perturbed machine, analytic.

Gauss–Newton on the nominal Jacobian converges to the point where the *nominal* Jacobian is
orthogonal to the residual, which differs from the least-squares optimum by the Jacobian's change
over the estimate amplified by the plan's conditioning. On a well-conditioned plan the difference
is far below the noise; on an ill-conditioned one (the Delta's 53-parameter full plan, smallest
singular value 1e-4 of the largest) it is several σ, and the frozen iteration stalls there. The
cure is the Jacobian at the estimate, and it is cheap: the separation of
:func:`pkmtol.error_model.separation.separate_many` run on the *perturbed* machine's models at its
solved poses gives the platform twist per unit parameter at held commands, exactly (no finite
differences; the test compares it with them).

One correction makes it the derivative with respect to the parameters rather than to a further
perturbation: an origin error enters as ``M · exp6(ε)``, so a change ``dε`` at ``ε`` is the right
perturbation ``exp6(Jr(ε) dε)`` of the perturbed origin, with ``Jr`` Pinocchio's ``Jexp6``; each
origin's rows of the parameter selection are multiplied by it.

A hybrid machine's TCP twist is the module's, shifted from O' to the TCP, and the tool chain's
columns (its perturbed model's regressor at the solved wrist joints), as
:func:`pkmtol.error_model.tool_chain.tool_separation` builds them at the nominal machine.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from pkmtol.calibration.machine import Machine
from pkmtol.error_model.compensation import skew_batch
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.separation import Separation, separate_many
from pkmtol.error_model.tool_chain import HybridParameterSet
from pkmtol.error_model.tool_sweep import tracker_on
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.solutions import Solutions
from pkmtol.kinematics.tool_chain import split_tool_eps, tool_regressor, world_axes
from pkmtol.model.mechanism import Mechanism

if TYPE_CHECKING:
    from pkmtol.calibration.hybrid_machine import HybridMachine, HybridSolutions


def origin_jacobians(selection: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """``selection`` (raw rows, k) with each origin's 6 rows times ``Jr(ε_o)`` (``eps`` (o, 6)).

    The rows after the origins' (joint zero offsets) are unchanged.
    """
    out = np.array(selection, dtype=float, copy=True)
    for o, e in enumerate(np.asarray(eps, dtype=float).reshape(-1, 6)):
        if e.any():
            rows = slice(6 * o, 6 * o + 6)
            out[rows] = pin.Jexp6(pin.Motion(e)) @ selection[rows]
    return out


def selections_at(pset: ParameterSet, mechanism: Mechanism, delta: np.ndarray) -> ParameterSet:
    """``pset`` (a module's set) with each origin's selection rows times ``Jr(ε)`` at errors ``delta``.

    Its columns are then the derivatives of the perturbed models' raw errors (a right
    perturbation of each perturbed origin, the joint offsets unchanged) per unit parameter.
    """
    eps, _ = pset.perturbation(delta, mechanism)
    sels = [origin_jacobians(sel, e) for sel, e in zip(pset.selections, eps, strict=True)]
    return replace(pset, selections=tuple(sels))


def _module_maps(
    mechanism: Mechanism, pset: ParameterSet, delta: np.ndarray, batch: BatchChain, sols: Solutions
) -> np.ndarray | None:
    seps = separate_many(mechanism, selections_at(pset, mechanism, delta), batch, sols)
    if not all(isinstance(s, Separation) for s in seps):
        return None
    return np.array([s.twist_map for s in seps if isinstance(s, Separation)])


def twist_maps_at(machine: Machine | HybridMachine, sols: Solutions | HybridSolutions) -> np.ndarray | None:
    """Twist per unit parameter at held commands of ``machine`` at its solved poses, exactly.

    Args:
        machine: A machine (the mechanism with errors ``machine.delta``), or a hybrid machine
            with the tracker's targets on the TCP frame.
        sols: Its forward solutions at the calibration poses (``machine.forward_many``).

    Returns:
        Shape (N, 6, n): ``T_k`` at the estimate, the platform's twist in K' of each solved pose,
        or a hybrid's TCP twist (at the TCP, K's axes): the twists the instruments'
        :meth:`~pkmtol.calibration.instruments.base.Instrument.twist_rows` take. None when a pose
        cannot be separated there (a singular pose of the perturbed machine: the caller keeps the
        Jacobian it has), or for a tracker on a hybrid's spindle nose.
    """
    from pkmtol.calibration.hybrid_machine import HybridMachine, HybridSolutions

    if isinstance(machine, HybridMachine):
        if not isinstance(sols, HybridSolutions) or tracker_on(machine.mechanism) == "nose":
            return None  # the nose reads the spindle's twist, not the TCP's
        return _hybrid_maps(machine, sols)
    if machine.mechanism.tool is not None or not isinstance(sols, Solutions):
        return None
    return _module_maps(machine.mechanism, machine.pset, machine.delta, machine.batch, sols)


def _hybrid_maps(machine: HybridMachine, sols: HybridSolutions) -> np.ndarray | None:
    """The TCP's twist (at the TCP, K's axes): the module's shifted to the TCP, and the tool chain's."""
    pset = machine.pset
    assert isinstance(pset, HybridParameterSet) and pset.tool_selection is not None
    tool, n0 = machine.tool, machine.nq_module
    offsets = machine.offsets[:n0]
    q_mod = sols.q[:, :n0]
    readings = q_mod[:, machine.module_actuated] - offsets[machine.module_actuated]
    batch = machine.chain.batch
    mod = batch.forward(readings, q_mod, np.broadcast_to(offsets, q_mod.shape))  # solved: one step
    if not mod.ok.all():
        return None
    k = pset.module_count
    module = _module_maps(machine.mechanism, pset.module_set(), machine.delta[:k], batch, mod)
    if module is None:
        return None
    N = len(sols.q)
    lever = sols.translation - mod.translation
    shift = np.zeros((N, 6, 6))
    shift[:, :3, :3] = shift[:, 3:, 3:] = np.eye(3)
    shift[:, :3, 3:] = -skew_batch(lever)
    out = np.zeros((N, 6, len(pset)))
    out[:, :, :k] = shift @ module
    t_eps, _ = split_tool_eps(pset.tool_raw(machine.delta), tool)
    selection = origin_jacobians(pset.tool_selection, t_eps)
    model = machine.chain.tool_model
    data = model.createData()
    for b in range(N):
        raw = tool_regressor(tool, model, data, sols.q[b, n0:])
        out[b, :, pset.tool_slice] = world_axes(sols.rotation[b], raw @ selection)
    return out
