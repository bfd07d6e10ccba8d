"""Exact-kinematics checks of hybrid machines (the whole machine's truth test, docs/hybrid.md)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pkmtol.error_model.tool_chain import HybridParameterSet, ToolSeparation
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.hybrid import HybridChain
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.kinematics.tool_chain import perturbed_tool_model, split_tool_eps


def perturbed_machine(mech, ps: HybridParameterSet, eta):
    """The machine built with errors ``eta``: its solver and its joints' zero offsets (module, tool)."""
    eps, offsets = ps.module_set().perturbation(eta[: ps.module_count], mech)
    t_eps, t_off = split_tool_eps(ps.tool_raw(eta), mech.tool)
    chain = ClosedChain(mech, perturbed_limb_models(mech, eps), check_limits=False)
    return (
        HybridChain(mech, chain, perturbed_tool_model(mech.tool, t_eps), check_limits=False),
        offsets,
        t_off,
    )


def exact_tcp(mech, ps, sep: ToolSeparation, eta, du=None) -> pin.SE3:
    """The perturbed machine's TCP with the nominal commands (plus ``du``: module's, then the wrist's)."""
    h = sep.hybrid
    hc, off, t_off = perturbed_machine(mech, ps, eta)
    u = h.module.q_all[hc.chain.actuated_idx].copy()
    q_tool = h.q_tool.copy()
    if du is not None:
        f = len(u)
        u += du[:f]
        q_tool[list(mech.tool.actuated)] += du[f:]
    return hc.forward(u, q_tool, h.module.q_all, off, t_off)[1]


def error_twist(nominal: pin.SE3, actual: pin.SE3) -> np.ndarray:
    """The TCP error twist (6,) at the TCP, K's axes: ``log6(X_nom⁻¹ X_act)`` rotated by ``R_nom``."""
    local = pin.log6(nominal.actInv(actual)).vector
    r = nominal.rotation
    return np.concatenate([r @ local[:3], r @ local[3:]])


def task_error(sep: ToolSeparation, actual: pin.SE3) -> np.ndarray:
    """The exact 5-row task error: the TCP's displacement and the tool axis's across the nominal axis."""
    nominal = sep.pose.oMp
    s = sep.task_rows
    assert s is not None
    across = -s[3:, 3:] @ pin.skew(nominal.rotation[:, 2]).T  # Q, from S's rows −Q[a]×
    return np.concatenate(
        [actual.translation - nominal.translation, across @ (actual.rotation[:, 2] - nominal.rotation[:, 2])]
    )


def relative(a: np.ndarray, b: np.ndarray) -> float:
    """‖a − b‖ / ‖a‖."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(a))


def exact_compensation(mech, ps, sep: ToolSeparation, eta, targets, iterations: int = 4) -> np.ndarray:
    """The task error left by the best exact compensation (Gauss–Newton over every actuator command).

    Minimises ``‖D e‖`` (``D``: the split's metric, rows over Δλ*, Δα*) of the exact task error
    ``e`` of the perturbed machine, from the linear correction; the step uses the linear map
    ``S B`` (exact at the solution's first order, so the iteration converges to the exact minimum).
    """
    d = np.array([1 / targets[0]] * 3 + [1 / targets[1]] * 2)
    sb = d[:, None] * (sep.task_rows @ sep.actuation_map)
    du = sep.correction @ eta
    for _ in range(iterations):
        e = task_error(sep, exact_tcp(mech, ps, sep, eta, du))
        du = du - np.linalg.lstsq(sb, d * e, rcond=None)[0]
    return task_error(sep, exact_tcp(mech, ps, sep, eta, du))
