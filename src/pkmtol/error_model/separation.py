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

import pkmtol.values as values
from pkmtol.error_model.limb_motion import loop_motion
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.twists import raw_columns_local, to_k_prime
from pkmtol.exceptions import KinematicsError, MobilityError, SingularPoseError
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.kinematics.solutions import Solutions
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
        joint_twists: Per limb, shape (6, nq_i): unit joint twists; for a limb with internal loops
            its motion space ``T̃`` (6, k), the actuated motion first (docs/theory.md, "General loops").
        error_columns: Shape (6, n): error twist of each parameter on its own limb (``T_c`` of Eq. 4;
            ``E'`` for a limb with loops: its loops closed again by passive motion).
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
        J: Shape (3, n): position error of P after compensation, ``Δλ = ‖J η‖`` (Eq. 23); for a
            planar task its in-plane part (``Mechanism.task_projection``).
        J_total: Shape (3, n): position error of P without compensation (traditional method).
        redundancy: ``f + c − 6`` (number of linearly dependent wrenches, over-constraint) plus
            the number of dependent loop equations inside the limbs.
        incompatible_map: Shape (f + c + inner, n): ``Y − Wᵀ twist_map``, then the loop rows no
            joint motion of their limb closes (:mod:`pkmtol.error_model.limb_motion`); non-zero
            columns are errors that an over-constrained mechanism cannot assemble with rigid links
            (assembly errors).
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


def separate(
    mechanism: Mechanism, pset: ParameterSet, chain: ClosedChain, pose: Pose, general: bool = False
) -> Separation:
    """The error model and its separation at ``pose``.

    Args:
        mechanism: The mechanism.
        pset: The error-parameter set.
        chain: A solver workspace of the mechanism (its models and datas are reused).
        pose: A closed-chain pose of the mechanism.
        general: Treat every limb as a limb with loops (its motion space ``T̃`` and columns ``E'``,
            :mod:`pkmtol.error_model.limb_motion`), serial ones included: the same results to
            round-off (the reduction test); default: serial limbs take the direct path.

    Raises:
        SingularPoseError: W is singular (or nearly) at this pose.
        MobilityError: the actuation and constraint wrenches do not make a basis of 6 wrenches.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism")
    values.instance("pset", pset, ParameterSet, "a ParameterSet (pkmtol.parameter_set)")
    values.instance("chain", chain, ClosedChain, "a pkmtol.ClosedChain of the mechanism")
    values.instance("pose", pose, Pose, "a pkmtol.Pose (ClosedChain.inverse)")
    n = len(pset)
    twists, cols = [], np.zeros((6, n))
    W_a, W_c, act_limb, con_limb, lam = [], [], [], [], []
    Y_rows_a: list[np.ndarray] = []
    Y_rows_c: list[np.ndarray] = []
    inner: list[np.ndarray] = []  # rows of errors no joint motion closes inside a limb
    rot = pose.oMp.rotation
    for i, limb in enumerate(mechanism.limbs):
        sl = pset.slices[i]
        acts: tuple[int, ...] = limb.actuated
        if limb.loops or general:
            # the limb's loops eliminated: motion space T̃ (actuator first) and error columns E'
            lm = loop_motion(
                limb,
                chain.models[i],
                chain.datas[i],
                pose.q[i][None],
                rot[None],
                pset.selections[i],
                pose.p_m[None],
            )
            t_i, e_i, acts = lm.twists[0], lm.errors[0], lm.actuated
            for row in lm.incompatible[0]:
                full = np.zeros(n)
                full[sl] = row
                inner.append(full)
        else:
            raw, jac, _ = raw_columns_local(limb, chain.models[i], chain.datas[i], pose.q[i])
            t_i = to_k_prime(rot, jac)
            e_i = to_k_prime(rot, raw @ pset.selections[i])
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
        for a in acts:
            # w ∈ range(T_i) (⟂ W_c) and reciprocal to the passive twists: row a of the
            # pseudo-inverse T_i⁺ = V_r S_r⁻¹ U_rᵀ, since T_i⁺ T_i = I when the joints are independent
            w = u[:, :rank] @ (vt[:rank, a] / sv[:rank])
            passive = [j for j in range(t_i.shape[1]) if j != a]
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
    incompatible = np.vstack([Y - W.T @ twist_map] + [np.array(inner).reshape(-1, n)])
    lever = rot @ mechanism.reference_point_m
    to_p = mechanism.task_projection @ np.hstack([np.eye(3), -pin.skew(lever)])
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
        redundancy=W.shape[1] - 6 + len(inner),
        incompatible_map=incompatible,
        actuation_map=W_inv_T[:, :f] * lam_arr[None, :],
    )


def separate_many(
    mechanism: Mechanism, pset: ParameterSet, batch: BatchChain, sols: Solutions
) -> list[Separation | KinematicsError]:
    """:func:`separate` at every solved pose of a batch, the numpy work stacked over the poses.

    Per pose and limb, Pinocchio gives the kinematic regressor (one ``forwardKinematics`` and one
    ``computeFrameKinematicRegressor`` on the batch's reused ``Data``); the joint twists are the
    Jacobians the solver left in ``sols``. The rest is stacked: the wrenches of a 6-joint limb
    from the stacked inverse of its joint twists (its pseudo-inverse, since the twists are then
    a basis; an SVD only where the inverse's condition bound cannot certify rank 6), of a limb with
    fewer joints from a stacked SVD (the same basis of constraint wrenches as :func:`separate`),
    W's condition number from a stacked SVD, ``W⁻ᵀ`` from a stacked inverse.

    Args:
        mechanism: The mechanism.
        pset: The error-parameter set.
        batch: The batch solver that produced ``sols`` (its nominal models and datas are reused).
        sols: Solutions of inverse problems.

    Returns:
        Per problem of ``sols``: its :class:`Separation`, or the error :func:`separate` (or the
        solver) raised for it — :class:`SingularPoseError`, :class:`MobilityError`, or the
        solver's error.
    """
    out: list[Separation | KinematicsError | None] = list(sols.errors)
    idx = np.array([k for k, e in enumerate(sols.errors) if e is None], dtype=int)
    if not idx.size:
        return [e for e in out if e is not None]
    poses = [sols.pose(int(k)) for k in idx]
    blocks = _stacked(mechanism, pset, batch, sols, idx)
    for pos, k in enumerate(idx):
        block = blocks[pos]
        result: Separation | KinematicsError
        if block is None:  # an unusual rank at this pose: the per-pose path decides
            try:
                result = separate(mechanism, pset, batch.chain, poses[pos])
            except KinematicsError as err:
                result = err
        elif isinstance(block, dict):
            result = Separation(pose=poses[pos], **block)
        else:
            result = block
        out[int(k)] = result
    return [e for e in out if e is not None]


def _stacked(
    mechanism: Mechanism, pset: ParameterSet, batch: BatchChain, sols: Solutions, idx: np.ndarray
) -> list[dict | KinematicsError | None]:
    """The fields of each pose's Separation (a dict), its error, or None for the per-pose path."""
    b, n = len(idx), len(pset)
    rot = sols.rotation[idx]
    p_m = sols.p_m[idx]
    cols = np.zeros((b, 6, n))
    twists, wa, wc, act_limb, con_limb, lam, ya_rows, yc_rows = [], [], [], [], [], [], [], []
    errors: list[KinematicsError | None] = [None] * b
    fallback = np.zeros(b, dtype=bool)
    inner: list[np.ndarray] = []
    for i, limb in enumerate(mechanism.limbs):
        model, data, fid = batch.models[i], batch.datas[i], batch.fids[i]
        cols_q = slice(int(batch.offsets[i]), int(batch.offsets[i + 1]))
        sl = pset.slices[i]
        acts: tuple[int, ...] = limb.actuated
        if limb.loops:
            try:
                lm = loop_motion(limb, model, data, sols.q[idx, cols_q], rot, pset.selections[i], p_m)
            except MobilityError:  # the per-pose path names the pose
                return [None] * b
            t_i, e_i, acts = lm.twists, lm.errors, lm.actuated
            fallback |= lm.bad
            for k in range(lm.incompatible.shape[1]):
                row = np.zeros((b, n))
                row[:, sl] = lm.incompatible[:, k]
                inner.append(row)
        else:
            jac = sols.jacobians[i][idx]
            n_reg = 6 * limb.nq
            reg = np.empty((b, 6, n_reg))
            for pos, k in enumerate(idx):
                pin.forwardKinematics(model, data, sols.q[k, cols_q])
                reg[pos] = pin.computeFrameKinematicRegressor(model, data, fid, pin.LOCAL)
            sel = pset.selections[i]
            local = reg @ sel[:n_reg] + sel[n_reg : n_reg + 6] + jac @ sel[n_reg + 6 :]
            t_i = _to_k_prime(rot, jac)
            e_i = _to_k_prime(rot, local)
        cols[:, :, sl] = e_i
        twists.append(t_i)
        pinv, basis, bad = _twist_split(t_i)
        fallback |= bad
        for k in range(basis.shape[2]):
            wc.append(basis[:, :, k])
            con_limb.append(i)
            row = np.zeros((b, n))
            row[:, sl] = np.einsum("bj,bjm->bm", basis[:, :, k], e_i)
            yc_rows.append(row)
        for a in acts:
            w = pinv[:, a, :]  # row a of T_i⁺: reciprocal to the passive joints, w · t_a = 1
            passive = [j for j in range(t_i.shape[2]) if j != a]
            dots = np.einsum("bj,bjk->bk", w, t_i)
            recip = np.abs(dots[:, a] - 1.0)
            if passive:
                recip = np.maximum(recip, np.abs(dots[:, passive]).max(axis=1))
            for bad_pose in np.flatnonzero(~(recip < 1e-6) & ~fallback):
                pos = int(bad_pose)
                errors[pos] = errors[pos] or MobilityError(
                    f"limb '{limb.name}': the actuated joint moves the platform only within the "
                    f"passive joints' span at P = {p_m[pos]} m (actuation singularity)"
                )
            f_norm = np.linalg.norm(w[:, :3], axis=1)
            scale = np.where(
                f_norm > 1e-9 * np.linalg.norm(w, axis=1), f_norm, np.linalg.norm(w[:, 3:], axis=1)
            )
            w = w / scale[:, None]
            wa.append(w)
            act_limb.append(i)
            lam.append(np.einsum("bj,bj->b", w, t_i[:, :, a]))
            row = np.zeros((b, n))
            row[:, sl] = np.einsum("bj,bjm->bm", w, e_i)
            ya_rows.append(row)
    f, c = len(wa), len(wc)
    W = np.concatenate(
        [
            np.stack(wa, axis=2) if f else np.zeros((b, 6, 0)),
            np.stack(wc, axis=2) if c else np.zeros((b, 6, 0)),
        ],
        axis=2,
    )
    if f + c < 6:
        err = MobilityError(
            f"only {f} actuation + {c} constraint wrenches at P = {p_m[0]} m; the platform keeps "
            f"{6 - f - c} uncontrolled freedom(s). Check the actuated joints in mechanism.toml"
        )
        return [None if fallback[pos] else err for pos in range(b)]
    sv = np.linalg.svd(W, compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(sv[:, 5] > 0, sv[:, 0] / sv[:, 5], np.inf)
    singular = cond > W_SINGULAR_CONDITION
    y_a = np.stack(ya_rows, axis=1) if f else np.zeros((b, 0, n))
    y_c = np.stack(yc_rows, axis=1) if c else np.zeros((b, 0, n))
    usable = ~singular & ~fallback
    w_inv_t = np.full((b, 6, f + c), np.nan)
    if usable.any():
        wu = W[usable]
        w_inv_t[usable] = (
            np.swapaxes(np.linalg.inv(wu), 1, 2) if f + c == 6 else np.linalg.pinv(np.swapaxes(wu, 1, 2))
        )
    y = np.concatenate([y_a, y_c], axis=1)
    twist_map = w_inv_t @ y
    unc = w_inv_t[:, :, f:] @ y_c
    incompatible = y - np.swapaxes(W, 1, 2) @ twist_map
    if inner:
        incompatible = np.concatenate([incompatible, np.stack(inner, axis=1)], axis=1)
    lever = rot @ mechanism.reference_point_m
    to_p = np.zeros((b, 3, 6))
    to_p[:, :, :3] = np.eye(3)
    to_p[:, :, 3:] = -_skew_rows(lever)
    to_p = mechanism.task_projection @ to_p  # a planar task: the in-plane part of P's error
    lam_arr = np.stack(lam, axis=1) if f else np.zeros((b, 0))
    correction = -(y_a / lam_arr[:, :, None]) if f else np.zeros((b, 0, n))
    J, J_total = to_p @ unc, to_p @ twist_map
    actuation = w_inv_t[:, :, :f] * lam_arr[:, None, :]  # W⁻ᵀ [diag(Λ_a); 0]
    out: list[dict | KinematicsError | None] = []
    for pos in range(b):
        if fallback[pos]:
            out.append(None)
        elif errors[pos] is not None:
            out.append(errors[pos])
        elif singular[pos]:
            out.append(SingularPoseError("the wrench matrix W", float(cond[pos]), p_m[pos]))
        else:
            out.append(
                {
                    "joint_twists": tuple(t[pos] for t in twists),
                    "error_columns": cols[pos],
                    "W_a": W[pos, :, :f],
                    "W_c": W[pos, :, f:],
                    "constraint_limb": np.array(con_limb, dtype=int),
                    "actuated_limb": np.array(act_limb, dtype=int),
                    "Lambda_a": lam_arr[pos],
                    "Y_a": y_a[pos],
                    "Y_c": y_c[pos],
                    "W_condition": float(cond[pos]),
                    "twist_map": twist_map[pos],
                    "correction": correction[pos],
                    "uncompensated_map": unc[pos],
                    "lever_m": lever[pos],
                    "J": J[pos],
                    "J_total": J_total[pos],
                    "redundancy": f + c - 6 + len(inner),
                    "incompatible_map": incompatible[pos],
                    "actuation_map": actuation[pos],
                }
            )
    return out


def _to_k_prime(rot: np.ndarray, local: np.ndarray) -> np.ndarray:
    """:func:`to_k_prime` on stacks: ``rot`` (b, 3, 3), ``local`` (b, 6, k)."""
    out = np.empty_like(local)
    out[:, :3] = rot @ local[:, :3]
    out[:, 3:] = rot @ local[:, 3:]
    return out


def _skew_rows(v: np.ndarray) -> np.ndarray:
    z = np.zeros(len(v))
    x, y, w = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([z, -w, y, w, z, -x, -y, x, z], axis=1).reshape(-1, 3, 3)


def _twist_split(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pseudo-inverse (b, nq, 6) and constraint-wrench basis (b, 6, 6 − rank) of joint twists (b, 6, nq).

    The rank must be the same at every pose; a pose where it differs (or cannot be certified) is
    flagged in the mask for the per-pose path.
    """
    b, _, nq = t.shape
    if nq == 6:
        try:
            inv = np.linalg.inv(t)
        except np.linalg.LinAlgError:
            inv = np.full_like(t, np.nan)
        fro = np.linalg.norm(t, axis=(1, 2))
        bound = fro * np.linalg.norm(inv, axis=(1, 2))
        # s_max ≥ ‖T‖_F/√6 and s_min ≥ s_max/κ_F: rank 6 by the rule of null_space() when
        # s_max/(√6 κ_F) > RANK_TOLERANCE · max(‖T‖_F, 1)
        sure = np.isfinite(bound) & (fro / (np.sqrt(6.0) * bound) > RANK_TOLERANCE * np.maximum(fro, 1.0))
        return inv, np.zeros((b, 6, 0)), ~sure
    u, sv, vt = np.linalg.svd(t)
    ranks = np.sum(sv > RANK_TOLERANCE * np.maximum(sv[:, :1], 1.0), axis=1)
    rank = int(np.bincount(ranks).argmax())
    r = slice(0, rank)
    pinv = np.swapaxes(vt[:, r], 1, 2) @ (np.swapaxes(u[:, :, r], 1, 2) / sv[:, r, None])
    return pinv, u[:, :, rank:], ranks != rank
