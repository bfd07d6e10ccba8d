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
