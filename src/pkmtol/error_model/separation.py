"""Actuation and constraint wrenches, and the compensatable/uncompensatable split (Eqs. 5–8, 25).

At a pose, for each limb ``i`` with joint twists ``T_i`` (6, nq_i) in K':

* constraint wrenches ``W_c,i``: an orthonormal basis of the wrenches reciprocal to every joint
  of the limb (null space of ``T_iᵀ`` by SVD);
* actuation wrench ``w_a,i`` (actuated limbs): reciprocal to every *passive* joint of the limb
  and, among those, orthogonal (Euclidean, in K') to the limb's constraint wrenches — the choice
  that matters only for limbs that are both actuated and constrained (docs/theory.md). Since the
  orthogonal complement of ``W_c,i`` is the span of ``T_i``, this ``w_a,i`` is row ``a`` of the
  pseudo-inverse ``T_i⁺`` (reciprocal to every other joint, ``w · t_a = 1``), from the same SVD
  that gives ``W_c,i``; it is scaled to a unit screw (unit force, or unit couple if it has no
  force), so ``Λ_a > 0``.

Reciprocal product = ``wrench · twist`` (power; twist ``[v; ω]``, wrench ``[f; τ]``, both at O').
Projecting the limb's twist equation ``$_t = T_i q̇ + E_i η_i`` on the wrenches removes the
unknown passive motions: ``W_aᵀ $_t = Λ_a ξ_a + G_a η_a`` (7) and ``W_cᵀ $_t = G_c η_c`` (8). With
``W = [W_a W_c]`` square and invertible, the pose error twist is
``$_t = W⁻ᵀ [Λ_a ξ_a + G_a η_a; G_c η_c]`` (over-constrained mechanisms, ``W`` wider than 6 and
of rank 6: the least-squares solution, the rest reported as an assembly error); the actuator
correction of Eq. 25,
``ξ_a ← ξ_a − Λ_a⁻¹ (Λ_a ξ_a + G_a η_a)``, leaves the uncompensatable twist ``W⁻ᵀ [0; G_c η_c]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.twists import raw_columns_local, to_k_prime
from pkmtol.exceptions import MobilityError, SingularPoseError
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.model.mechanism import Mechanism

#: Relative singular-value threshold for null spaces (reciprocal screws).
RANK_TOLERANCE = 1e-9
#: Condition number of W above which the pose is called singular.
W_SINGULAR_CONDITION = 1e8


@dataclass(frozen=True, eq=False)
class Separation:
    """The error model of the whole mechanism at one pose (all arrays in K', SI units).

    ``n`` is the number of parameters of the set, ``f`` of actuators, ``c`` of constraint wrenches.

    Attributes:
        pose: The closed-chain pose.
        joint_twists: Per limb, shape (6, nq_i): unit joint twists.
        error_columns: Shape (6, n): error twist of each parameter on its own limb (``T_c`` of Eq. 4).
        W_a: Shape (6, f): actuation wrenches, limb order.
        W_c: Shape (6, c): constraint wrenches, limb order.
        constraint_limb: Shape (c,): limb index of each constraint wrench.
        actuated_limb: Shape (f,): limb index of each actuation wrench.
        Lambda_a: Shape (f,): ``w_a,k · t_a,k`` (the diagonal of Λ_a).
        Y_a: Shape (f, n): actuation rows ``[Λ_a | G_a]`` per parameter (actuator offsets give Λ).
        Y_c: Shape (c, n): constraint rows ``G_c`` per parameter.
        W_condition: Condition number of W.
        twist_map: Shape (6, n): ``$_t = twist_map · η`` (no compensation).
        correction: Shape (f, n): Eq. 25, actuator command change ``Δu = correction · η`` [m, rad].
        uncompensated_map: Shape (6, n): ``W⁻ᵀ [0; Y_c]``, the pose error left after Eq. 25.
        lever_m: Shape (3,): ``l``, vector O' → P in K [m].
        J: Shape (3, n): position error of P after compensation, ``Δλ = ‖J η‖`` (Eq. 23).
        J_total: Shape (3, n): position error of P without compensation (traditional method).
        redundancy: ``f + c − 6``: number of linearly dependent wrenches (over-constraint).
        incompatible_map: Shape (f + c, n): ``Y − Wᵀ twist_map``; non-zero columns are errors that
            an over-constrained mechanism cannot assemble with rigid links (assembly errors).
        actuation_map: Shape (6, f): platform twist per unit actuator motion [m or rad per m or
            rad], ``W⁻ᵀ [diag(Λ_a); 0]`` (from Eq. 7 with η = 0); a change ``Δu`` of the actuator
            commands moves the platform by ``actuation_map · Δu``.
    """

    pose: Pose
    joint_twists: tuple[np.ndarray, ...]
    error_columns: np.ndarray
    W_a: np.ndarray
    W_c: np.ndarray
    constraint_limb: np.ndarray
    actuated_limb: np.ndarray
    Lambda_a: np.ndarray
    Y_a: np.ndarray
    Y_c: np.ndarray
    W_condition: float
    twist_map: np.ndarray
    correction: np.ndarray
    uncompensated_map: np.ndarray
    lever_m: np.ndarray
    J: np.ndarray
    J_total: np.ndarray
    redundancy: int = 0
    incompatible_map: np.ndarray | None = None
    actuation_map: np.ndarray | None = None


def null_space(a: np.ndarray) -> np.ndarray:
    """Orthonormal basis of ``{x : a x = 0}`` (columns), by SVD with a relative tolerance."""
    if a.shape[0] == 0:
        return np.eye(a.shape[1])
    _, s, vt = np.linalg.svd(a)
    rank = int(np.sum(s > RANK_TOLERANCE * max(s[0], 1.0)))
    return vt[rank:].T.copy()


def unit_screw(w: np.ndarray) -> np.ndarray:
    """Scale a wrench to a unit force (or to a unit couple if its force part vanishes)."""
    f = np.linalg.norm(w[:3])
    return w / (f if f > 1e-9 * np.linalg.norm(w) else np.linalg.norm(w[3:]))


def separate(mechanism: Mechanism, pset: ParameterSet, chain: ClosedChain, pose: Pose) -> Separation:
    """The error model and its separation at ``pose``.

    Args:
        mechanism: The mechanism.
        pset: The error-parameter set.
        chain: A solver workspace of the mechanism (its models and datas are reused).
        pose: A closed-chain pose of the mechanism.

    Raises:
        SingularPoseError: W is singular (or nearly) at this pose.
        MobilityError: the actuation and constraint wrenches do not make a basis of 6 wrenches.
    """
    n = len(pset)
    twists, cols = [], np.zeros((6, n))
    W_a, W_c, act_limb, con_limb, lam = [], [], [], [], []
    Y_rows_a: list[np.ndarray] = []
    Y_rows_c: list[np.ndarray] = []
    rot = pose.oMp.rotation
    for i, limb in enumerate(mechanism.limbs):
        raw, jac, _ = raw_columns_local(limb, chain.models[i], chain.datas[i], pose.q[i])
        t_i = to_k_prime(rot, jac)
        e_i = to_k_prime(rot, raw @ pset.selections[i])
        sl = pset.slices[i]
        cols[:, sl] = e_i
        twists.append(t_i)
        # one SVD of the joint twists gives both wrench sets: T_i = U_r S_r V_rᵀ
        u, sv, vt = np.linalg.svd(t_i)
        rank = int(np.sum(sv > RANK_TOLERANCE * max(sv[0], 1.0)))
        wc = u[:, rank:]  # null(T_iᵀ): the constraint wrenches
        for k in range(wc.shape[1]):
            W_c.append(wc[:, k])
            con_limb.append(i)
            row = np.zeros(n)
            row[sl] = wc[:, k] @ e_i
            Y_rows_c.append(row)
        for a in limb.actuated:
            # w ∈ range(T_i) (⟂ W_c) and reciprocal to the passive twists: row a of the
            # pseudo-inverse T_i⁺ = V_r S_r⁻¹ U_rᵀ, since T_i⁺ T_i = I when the joints are independent
            w = u[:, :rank] @ (vt[:rank, a] / sv[:rank])
            passive = [k for k in range(limb.nq) if k != a]
            reciprocity = max(abs(w @ t_i[:, a] - 1.0), np.abs(w @ t_i[:, passive]).max(initial=0.0))
            if not reciprocity < 1e-6:
                raise MobilityError(
                    f"limb '{limb.name}': the actuated joint moves the platform only within the "
                    f"passive joints' span at P = {pose.p_m} m (actuation singularity)"
                )
            w = unit_screw(w)
            W_a.append(w)
            act_limb.append(i)
            lam.append(float(w @ t_i[:, a]))
            row = np.zeros(n)
            row[sl] = w @ e_i
            Y_rows_a.append(row)
    wa = np.array(W_a).T.reshape(6, -1)
    wcm = np.array(W_c).T.reshape(6, -1)
    W = np.hstack([wa, wcm])
    if W.shape[1] < 6:
        raise MobilityError(
            f"only {wa.shape[1]} actuation + {wcm.shape[1]} constraint wrenches at P = "
            f"{pose.p_m} m; the platform keeps {6 - W.shape[1]} uncontrolled freedom(s). "
            "Check the actuated joints in mechanism.toml"
        )
    sv = np.linalg.svd(W, compute_uv=False)
    cond = float(sv[0] / sv[5]) if sv[5] > 0 else np.inf
    if cond > W_SINGULAR_CONDITION:
        raise SingularPoseError("the wrench matrix W", cond, pose.p_m)
    Y_a = np.array(Y_rows_a).reshape(-1, n)
    Y_c = np.array(Y_rows_c).reshape(-1, n)
    f = wa.shape[1]
    # W is 6 × (f + c). Square: W⁻ᵀ. Over-constrained (f + c > 6, rank 6): the least-squares twist
    # (Wᵀ)⁺ y, and y − Wᵀ(Wᵀ)⁺y is the part no rigid platform motion can satisfy (assembly error).
    W_inv_T = np.linalg.inv(W).T if W.shape[1] == 6 else np.linalg.pinv(W.T)
    Y = np.vstack([Y_a, Y_c])
    twist_map = W_inv_T @ Y
    unc = W_inv_T[:, f:] @ Y_c
    incompatible = Y - W.T @ twist_map
    lever = rot @ mechanism.reference_point_m
    to_p = np.hstack([np.eye(3), -pin.skew(lever)])
    lam_arr = np.array(lam)
    return Separation(
        pose=pose,
        joint_twists=tuple(twists),
        error_columns=cols,
        W_a=wa,
        W_c=wcm,
        constraint_limb=np.array(con_limb, dtype=int),
        actuated_limb=np.array(act_limb, dtype=int),
        Lambda_a=lam_arr,
        Y_a=Y_a,
        Y_c=Y_c,
        W_condition=cond,
        twist_map=twist_map,
        correction=-(Y_a / lam_arr[:, None]) if f else np.zeros((0, n)),
        uncompensated_map=unc,
        lever_m=lever,
        J=to_p @ unc,
        J_total=to_p @ twist_map,
        redundancy=W.shape[1] - 6,
        incompatible_map=incompatible,
        actuation_map=W_inv_T[:, :f] * lam_arr[None, :],
    )
