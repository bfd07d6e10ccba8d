"""Exact-kinematics checks shared by the error-model and machine tests (DESIGN.md, "The truth test")."""

from __future__ import annotations

import numpy as np

from pkmtol.error_model.separation import separate
from pkmtol.error_model.twists import pose_error_twist
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.perturbation import perturbed_limb_models


def compensatable_residual_ratios(mech, chain, ps, classes, points, rng) -> list[float]:
    """Truth test step 3 at each point: ‖pose error after Eq. 25‖ / ‖pose error before‖.

    Only the parameters classed compensatable are perturbed (size 1e-5); the perturbed mechanism is
    solved exactly with the actuators at nominal, then at nominal + the Eq. 25 correction.
    """
    comp = np.array([c == "compensatable" for c in classes])
    ratios = []
    q = chain.home()
    for p in points:
        pose = chain.inverse(p, q)
        sep = separate(mech, ps, chain, pose)
        eta = np.where(comp, rng.normal(0.0, 1e-5, len(ps)), 0.0)
        eps, offsets = ps.perturbation(eta, mech)
        pert = ClosedChain(mech, perturbed_limb_models(mech, eps), check_limits=False)
        u = pose.q_all[chain.actuated_idx]
        t_raw = pose_error_twist(pose.oMp, pert.forward(u, pose.q_all, offsets).oMp)
        t_cor = pose_error_twist(pose.oMp, pert.forward(u + sep.correction @ eta, pose.q_all, offsets).oMp)
        ratios.append(float(np.linalg.norm(t_cor) / np.linalg.norm(t_raw)))
    return ratios


def relative(a: np.ndarray, b: np.ndarray) -> float:
    """‖a − b‖ / ‖a‖: the mismatch of a linear prediction ``b`` of the exact ``a``."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(a))


def linear_mismatches(mech, ps, chain, pose, sep, eta, q_start=None) -> tuple[float, float]:
    """Truth test steps 1 and 2 at one pose: the relative mismatch of ``twist_map η`` against the exact
    pose error with the actuators at nominal, and of ``uncompensated_map η`` against it after Eq. 25.

    The mechanism perturbed by ``eta`` is solved exactly from ``q_start`` (default: the pose's joints).
    """
    q0 = pose.q_all if q_start is None else q_start
    eps, offsets = ps.perturbation(eta, mech)
    pert = ClosedChain(mech, perturbed_limb_models(mech, eps), check_limits=False)
    u = pose.q_all[chain.actuated_idx]
    t1 = pose_error_twist(pose.oMp, pert.forward(u, q0, offsets).oMp)
    t2 = pose_error_twist(pose.oMp, pert.forward(u + sep.correction @ eta, q0, offsets).oMp)
    return relative(t1, sep.twist_map @ eta), relative(t2, sep.uncompensated_map @ eta)


def tree_mismatches(tree, params, sep, eta) -> tuple[float, float]:
    """Truth test steps 1 and 2 on the general formulation (a LoopTree) at one separated pose.

    The tree perturbed by ``eta`` (:func:`pkmtol.kinematics.tree_chain.perturbed_tree`) is solved
    exactly with the actuators at nominal, then at nominal + Eq. 25; the platform frame's pose
    errors against ``twist_map η`` and ``uncompensated_map η``.
    """
    t1, t2 = tree_pose_errors(tree, params, sep, eta)
    return relative(t1, sep.twist_map @ eta), relative(t2, sep.uncompensated_map @ eta)


def tree_pose_errors(tree, params, sep, eta) -> tuple[np.ndarray, np.ndarray]:
    """Exact platform pose errors (K') of the tree perturbed by ``eta``: actuators nominal, then corrected."""
    from pkmtol.kinematics.tree_chain import TreeBatch, perturbed_tree

    pert, offsets = perturbed_tree(tree, params.raw(eta))
    batch = TreeBatch(pert, check_limits=False)
    q = sep.pose.q_all
    u = q[list(tree.actuated)]
    out = []
    for cmd in (u, u + sep.correction @ eta):
        sols = batch.forward(cmd[None], q[None], offsets[None])
        out.append(pose_error_twist(sep.pose.oMp, sols.pose(0).oMp))
    return out[0], out[1]
