"""The machine after a real calibration, to first order: ``e_k = L_k δ + N_k ν`` (and its rotation).

A tracker measures targets at the calibration poses: ``y = H δ + ν`` (``H``: every parameter's
effect at held commands). The identification estimates the controller model's parameters as
``δ̂ = G y`` with ``G`` its pseudo-inverse (base parameters, or the MAP estimator). To put P at a
target, the controller re-solves its model's inverse kinematics: the commands change by
``Δu_k = −C_k⁺ J_k δ̂`` (``J_k`` P's error at held commands, ``C_k`` P's motion per command). The
true machine then moves by ``$_k = T_k δ + A_k Δu_k``:

    $_k = (T_k − A_k C_k⁺ J_k G H) δ − A_k C_k⁺ J_k G ν

whose position rows at P are DESIGN.md's ``L_k = J_k − J_k G H`` and ``N_k = −J_k G`` (when the
actuators move P in every direction, ``C_k C_k⁺ = I``), and whose rotation rows are what the
calibration leaves in the platform's orientation. A hybrid machine: ``J_k`` and ``C_k`` are the
rows of its task (the TCP position and the tool axis across its target) and the twist is the TCP's.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from pkmtol.calibration.identifiability import Identifiability
from pkmtol.calibration.maps import PoseMaps
from pkmtol.error_model.compensation import AccuracyMaps
from pkmtol.exceptions import InvalidRequestError


def estimator(H: np.ndarray, ident: Identifiability, prior_sigma: np.ndarray | None = None) -> np.ndarray:
    """``G`` of shape (n, M): the linearised identification ``δ̂ = G y`` of measurements ``y`` (M,).

    Least squares on the base parameters (``prior_sigma`` None): ``δ̂_B = H_B⁺ y``, zeros elsewhere.
    MAP: ``δ̂_id = (H_idᵀ H_id + σ_m² Σ_p⁻¹)⁻¹ H_idᵀ y``.
    """
    n = H.shape[1]
    G = np.zeros((n, H.shape[0]))
    if prior_sigma is None:
        cols = ident.base_columns
        G[cols] = linalg.pinv(H[:, cols])
    else:
        cols = ident.columns
        prior = np.asarray(prior_sigma, dtype=float)
        if prior.shape != (cols.size,) or np.any(~(prior > 0)):
            raise InvalidRequestError(
                f"prior_sigma needs {cols.size} positive values, got shape {prior.shape}"
            )
        Hx = H[:, cols]
        normal = Hx.T @ Hx + np.diag(ident.noise_m**2 / prior**2)
        G[cols] = linalg.cho_solve(linalg.cho_factor(normal), Hx.T)
    return G


def calibrated_maps(
    evaluation: PoseMaps,
    H: np.ndarray,
    ident: Identifiability,
    prior_sigma: np.ndarray | None = None,
) -> AccuracyMaps:
    """The ``calibrated`` accuracy maps at the evaluation poses.

    Args:
        evaluation: Maps at the poses where the machine is used (e.g. the task-space grid).
        H: Shape (M, n): the identification Jacobian of the calibration plan (every parameter).
        ident: Base parameters of the controller model on that plan.
        prior_sigma: The MAP prior (None: least squares).
    """
    G = estimator(H, ident, prior_sigma)
    J, C = evaluation.task_maps()  # (m, r, n), (m, r, f): P's position, or a hybrid's task
    C_pinv = np.linalg.pinv(C)  # (m, f, r)
    AC = np.einsum("kaf,kfb->kab", evaluation.actuation, C_pinv)  # (m, 6, r)
    JG = np.einsum("kin,nM->kiM", J, G)  # (m, r, M)
    JGH = np.einsum("kiM,Mn->kin", JG, H)  # (m, r, n)
    twist = evaluation.twist - np.einsum("kai,kin->kan", AC, JGH)  # (m, 6, n)
    noise = -np.einsum("kai,kiM->kaM", AC, JG)  # (m, 6, M)
    rows = evaluation.point_rows(evaluation.reference_point_m[None, :])  # (m, 3, 6)
    rows = evaluation.task_projection @ rows  # a planar task counts P's in-plane error
    return AccuracyMaps(
        mode="calibrated",
        position=np.einsum("kia,kan->kin", rows, twist),
        rotation=twist[:, 3:, :],
        position_noise=np.einsum("kia,kaM->kiM", rows, noise),
        rotation_noise=noise[:, 3:, :],
        noise_m=ident.noise_m,
        rotations=evaluation.rotations,
    )
