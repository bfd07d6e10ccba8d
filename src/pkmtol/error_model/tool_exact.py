"""Exact errors of a hybrid machine built with given geometric errors (the verification's truth).

The machine with errors ``δ``: the module's limbs perturbed as the module's parameter set says
(:func:`pkmtol.kinematics.perturbation.perturbed_limb_models`), the tool chain's placements by
:func:`pkmtol.kinematics.tool_chain.perturbed_tool_model`, every joint's zero offset added to its
command. Its TCP at the nominal commands, or at the nominal commands plus the whole machine's
correction (``ToolSeparation.correction``), is solved exactly.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from pkmtol.error_model.tool_chain import HybridParameterSet, ToolSeparation
from pkmtol.error_model.tool_sweep import ToolSweep
from pkmtol.exceptions import KinematicsError
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.kinematics.hybrid import HybridChain
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.kinematics.tool_chain import perturbed_tool_model, split_tool_eps
from pkmtol.model.mechanism import Mechanism

#: ``(pose index, parameter vector, noise) → (TCP error (3,), tool rotation (3,))`` or None.
ExactToolError = Callable[[int, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray] | None]


class HybridMachine:
    """The hybrid machine built with errors ``delta`` (n,) of a :class:`HybridParameterSet`."""

    def __init__(self, mechanism: Mechanism, pset: HybridParameterSet, delta: np.ndarray) -> None:
        assert mechanism.tool is not None
        d = np.asarray(delta, dtype=float)
        eps, self.module_offsets = pset.module_set().perturbation(d[: pset.module_count], mechanism)
        t_eps, self.tool_offsets = split_tool_eps(pset.tool_raw(d), mechanism.tool)
        chain = ClosedChain(mechanism, perturbed_limb_models(mechanism, eps), check_limits=False)
        self.solver = HybridChain(
            mechanism, chain, perturbed_tool_model(mechanism.tool, t_eps), check_limits=False
        )
        self.actuated = list(mechanism.tool.actuated)

    def tcp(self, sep: ToolSeparation, du: np.ndarray | None = None) -> tuple[Pose, pin.SE3]:
        """The TCP at ``sep``'s nominal commands plus ``du`` (module's actuators, then the wrist's)."""
        h = sep.hybrid
        assert h is not None
        u = h.module.q_all[self.solver.chain.actuated_idx].copy()
        q_tool = h.q_tool.copy()
        if du is not None:
            f = len(u)
            u = u + du[:f]
            q_tool[self.actuated] += du[f:]
        return self.solver.forward(u, q_tool, h.module.q_all, self.module_offsets, self.tool_offsets)


def tool_exact(
    mechanism: Mechanism, pset: HybridParameterSet, sweep_: ToolSweep, corrected: bool
) -> ExactToolError:
    """Exact TCP errors with the whole machine's correction (``corrected``) or the nominal commands."""

    def error(k: int, delta: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        sep = sweep_.separations[k]
        assert isinstance(sep, ToolSeparation)
        try:
            _, actual = HybridMachine(mechanism, pset, delta).tcp(
                sep, sep.correction @ delta if corrected else None
            )
        except KinematicsError:
            return None
        nominal = sep.pose.oMp
        r = nominal.rotation
        return actual.translation - nominal.translation, r @ pin.log3(r.T @ actual.rotation)

    return error
