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
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from pkmtol.calibration.machine import Machine
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.separation import Separation, separate_many
from pkmtol.kinematics.solutions import Solutions


def selections_at(pset: ParameterSet, machine: Machine) -> ParameterSet:
    """``pset`` with each origin's selection rows times ``Jr(ε)`` at ``machine``'s errors.

    Its columns are then the derivatives of the perturbed models' raw errors (a right
    perturbation of each perturbed origin, the joint offsets unchanged) per unit parameter.
    """
    eps, _ = pset.perturbation(machine.delta, machine.mechanism)
    sels = []
    for limb, sel, e in zip(machine.mechanism.limbs, pset.selections, eps, strict=True):
        out = np.array(sel, dtype=float, copy=True)
        for o in range(limb.n_origins):
            if e[o].any():
                rows = slice(6 * o, 6 * o + 6)
                out[rows] = pin.Jexp6(pin.Motion(e[o])) @ sel[rows]
        sels.append(out)
    return replace(pset, selections=tuple(sels))


def twist_maps_at(machine: Machine, sols: Solutions) -> np.ndarray | None:
    """Platform twist per unit parameter at held commands of ``machine`` at its solved poses.

    Args:
        machine: A machine (the mechanism with errors ``machine.delta``); not a hybrid.
        sols: Its forward solutions at the calibration poses (``machine.forward_many``).

    Returns:
        Shape (N, 6, n): ``T_k`` at the estimate, in K' of each solved pose (the twist the
        instruments' :meth:`~pkmtol.calibration.instruments.base.Instrument.twist_rows` take);
        None when a pose cannot be separated there (a singular pose of the perturbed machine: the
        caller keeps the Jacobian it has).
    """
    if machine.mechanism.tool is not None or not isinstance(sols, Solutions):
        return None
    seps = separate_many(machine.mechanism, selections_at(machine.pset, machine), machine.batch, sols)
    if not all(isinstance(s, Separation) for s in seps):
        return None
    return np.array([s.twist_map for s in seps if isinstance(s, Separation)])
