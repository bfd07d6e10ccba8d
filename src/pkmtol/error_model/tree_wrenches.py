"""The limbs of a :class:`~pkmtol.model.loop_tree.LoopTree` at solved poses: motion spaces, wrenches, columns.

For limb L (:attr:`LoopTree.limbs`) the unknowns are its joints' motions ``dq_L`` and the
platform frame's spatial twist τ. Its loops give rows; a loop frame on the platform body, or hanging
below it, moves by τ plus the joints and errors between it and the platform frame; the limb that
carries the platform in the tree adds ``τ = T_P dq + E_P δ``. So ``R_L [dq_L; τ] + D_L δ = 0``.
From one SVD of ``R_L`` (per pose, stacked):

* ``null(R_L)``: the limb's motions; their τ part in K' spans its motion space ``S_L``;
* ``W_c,L = null(S_Lᵀ)``; for an actuator a of L, ``w_a`` = the minimum-norm solution of
  ``S_Lᵀ w = Q_aᵀ`` (``Q_a`` its motion in each null vector), i.e. reciprocal to every motion of L
  that keeps ``dq_a = 0`` and orthogonal to ``W_c,L``; then a unit screw, ``Λ_a = 1 / scale``;
* ``E'_L``: ``x = −R_L⁺ D_L`` corrected along ``null(R_L)`` so that every actuator of L is held,
  its τ part in K'; the rows of ``D_L`` outside ``range(R_L)`` are the limb's assembly errors.

Then :func:`limb_fields` assembles Eqs. 5–8 and 25 as :mod:`pkmtol.error_model.separation` does.
Poses where a rank differs from the others' are assembled in their own group, with their own ranks.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from pkmtol.error_model.separation import RANK_TOLERANCE, W_SINGULAR_CONDITION
from pkmtol.error_model.tree_parameters import TreeParameters
from pkmtol.exceptions import ClosedLoopError, KinematicsError, MobilityError, SingularPoseError
from pkmtol.kinematics import se3_batch
from pkmtol.kinematics.stacked_solve import condition_bound
from pkmtol.kinematics.tree_frames import TreePoses, adjoint_inverse, raw_world
from pkmtol.model.loop_tree import LoopTree, TreeLimb

#: Relative singular-value threshold of the limbs' loop systems.
LOOP_RANK_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class _Plan:
    """What one limb's rows need, fixed by the topology: columns, and each loop side's coefficients.

    The variables are ``[dq_L, τ, the limb's raw errors]`` (m of them); a loop side moves by
    ``G c`` with ``G`` the stacked spatial columns and ``c`` its coefficients (0, ±1).
    """

    joints: np.ndarray
    rc: np.ndarray
    six: tuple[int, ...]
    three: tuple[int, ...]
    ca: np.ndarray
    cb: np.ndarray
    ref: np.ndarray | None
    simple: np.ndarray | None = None


@lru_cache(maxsize=64)
def _plan(tree: LoopTree, limb: TreeLimb) -> _Plan:
    pf = tree.platform_frame
    sup_p, mov_p = tree.support(pf), tree.moved_by(pf)
    pjoint = int(tree.model.frames[pf].parentJoint) - 1
    cols = list(limb.joints)
    nj = len(cols)
    frames = [f for k in limb.loops for f in (tree.loops[k].frame_a, tree.loops[k].frame_b)]
    used = np.zeros(tree.n_raw, dtype=bool)
    for f in frames:
        used |= tree.moved_by(f)
    if limb.holds_platform or any(pjoint >= 0 and tree.support(f)[pjoint] for f in frames):
        used |= mov_p
    rc = np.flatnonzero(used)
    m = nj + 6 + len(rc)

    def coefficients(x: int) -> np.ndarray:
        sup, mov = tree.support(x), tree.moved_by(x)[rc].astype(float)
        c = np.zeros(m)
        if pjoint >= 0 and sup[pjoint]:  # on the platform body or below it: through τ
            sup, mov = sup & ~sup_p, mov - mov_p[rc]
            c[nj : nj + 6] = 1.0
        stray = set(np.flatnonzero(sup).tolist()) - set(cols)
        if stray:
            name = tree.model.frames[x].name
            raise ClosedLoopError(
                tree.name,
                name,
                f"frame '{name}' is moved by joint '{tree.joint_names[min(stray)]}' of another limb; "
                "a loop frame must hang on its own limb or on the platform",
            )
        c[:nj] = sup[cols]
        c[nj + 6 :] = mov
        return c

    loops = list(limb.loops)
    six = tuple(k for k in loops if tree.loops[k].kind == "6d")
    three = tuple(k for k in loops if tree.loops[k].kind == "3d")
    order = list(six) + list(three)
    ca = np.array([coefficients(tree.loops[k].frame_a) for k in order]).reshape(-1, m)
    cb = np.array([coefficients(tree.loops[k].frame_b) for k in order]).reshape(-1, m)
    ref = None
    if limb.holds_platform:
        ref = np.zeros(m)
        ref[:nj] = -sup_p[cols].astype(float)
        ref[nj : nj + 6] = 1.0
        ref[nj + 6 :] = -mov_p[rc].astype(float)
    return _Plan(np.array(cols, dtype=int), rc, six, three, ca, cb, ref, _simple(nj, six, three, ca, cb, ref))


def _simple(
    nj: int,
    six: tuple[int, ...],
    three: tuple[int, ...],
    ca: np.ndarray,
    cb: np.ndarray,
    ref: np.ndarray | None,
) -> np.ndarray | None:
    """The coefficients ``c`` with ``τ = G c`` when the limb is a serial chain to the platform, else None.

    A limb that carries the platform and has no loop (``τ = T_P dq + E_P δ``), or one closed on the
    platform by a single ``6d`` loop with one side on the platform body only (``τ`` = its other
    side's motion, relative errors): its motion space is then its joints' columns and its error
    columns a difference of frame motions, with no loop system to split (the limb path's serial limb).
    """
    if ref is not None and not six and not three:
        return ref * np.r_[-np.ones(nj), np.zeros(6), -np.ones(len(ref) - nj - 6)]
    if ref is not None or len(six) != 1 or three:
        return None
    a, b = ca[0], cb[0]
    for plat, limb in ((a, b), (b, a)):
        if np.all(plat[nj : nj + 6] == 1.0) and not np.any(plat[:nj]) and not np.any(limb[nj : nj + 6]):
            out = limb.copy()
            out[nj + 6 :] = limb[nj + 6 :] - plat[nj + 6 :]
            out[nj : nj + 6] = 0.0
            return out
    return None


def _cross(p: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``p × w`` column by column: p (..., 3), w (..., 3, m)."""
    p0, p1, p2 = p[..., 0, None], p[..., 1, None], p[..., 2, None]
    w0, w1, w2 = w[..., 0, :], w[..., 1, :], w[..., 2, :]
    return np.stack([p1 * w2 - p2 * w1, p2 * w0 - p0 * w2, p0 * w1 - p1 * w0], axis=-2)


def _limb_system(
    tree: LoopTree, limb: TreeLimb, poses: TreePoses, raw: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``R_L`` (b, rows, nJ + 6), ``D_L`` (b, rows, k) and the k raw columns it has.

    Every loop of the limb at once: ``6d`` rows ``Jlog6(E) Ad(oMb⁻¹) G (c_b − c_a)``, ``3d`` rows
    ``[I −[p_b×]] G c_b − [I −[p_a×]] G c_a``, then the platform's own rows ``G c_ref``.
    """
    plan = _plan(tree, limb)
    b = len(raw)
    nj = len(plan.joints)
    g = np.empty((b, 6, nj + 6 + len(plan.rc)))
    g[:, :, :nj] = poses.columns[:, :, plan.joints]
    g[:, :, nj : nj + 6] = np.eye(6)
    g[:, :, nj + 6 :] = raw[:, :, plan.rc]
    parts = []
    n6 = len(plan.six)
    if n6:
        ha = np.stack([poses.frame(tree, tree.loops[k].frame_a) for k in plan.six]).reshape(-1, 4, 4)
        hb = np.stack([poses.frame(tree, tree.loops[k].frame_b) for k in plan.six]).reshape(-1, 4, 4)
        rat = np.swapaxes(ha[:, :3, :3], 1, 2)
        re = rat @ hb[:, :3, :3]
        pe = (rat @ (hb[:, :3, 3] - ha[:, :3, 3])[:, :, None])[:, :, 0]
        _, jl, _ = se3_batch.log6_and_jacobian(re, pe)
        mm = (jl @ adjoint_inverse(hb)).reshape(n6, b, 6, 6)
        diff = g[None] * (plan.cb[:n6] - plan.ca[:n6])[:, None, None, :]
        parts.append(np.swapaxes(mm @ diff, 0, 1).reshape(b, 6 * n6, -1))
    if plan.three:
        pa = np.stack([poses.frame(tree, tree.loops[k].frame_a)[:, :3, 3] for k in plan.three])
        pb = np.stack([poses.frame(tree, tree.loops[k].frame_b)[:, :3, 3] for k in plan.three])
        va = g[None] * plan.ca[n6:, None, None, :]
        vb = g[None] * plan.cb[n6:, None, None, :]
        rows3 = (vb[:, :, :3] - _cross(pb, vb[:, :, 3:])) - (va[:, :, :3] - _cross(pa, va[:, :, 3:]))
        parts.append(np.swapaxes(rows3, 0, 1).reshape(b, 3 * len(plan.three), -1))
    if plan.ref is not None:
        parts.append(g * plan.ref)
    if not parts:
        return np.zeros((b, 0, nj + 6)), np.zeros((b, 0, len(plan.rc))), plan.rc
    rows = np.concatenate(parts, axis=1)
    return rows[:, :, : nj + 6], rows[:, :, nj + 6 :], plan.rc


def _ranks(sv: np.ndarray, tol: float) -> np.ndarray:
    if not sv.shape[1]:
        return np.zeros(len(sv), dtype=int)
    return np.sum(sv > tol * np.maximum(sv[:, :1], 1.0), axis=1)


class _Split:
    """Rank, null basis, pseudo-inverse and left null basis of stacked matrices ``a`` (b, r, c).

    Where ``r ≤ c`` and a QR factorisation ``aᵀ = Q [T; 0]`` certifies rank ``r`` (the bound
    ``‖T‖_F ‖T⁻¹‖_F`` keeps the smallest singular value above ``tol`` times the largest, the rule of
    the SVD path), ``null = Q[:, r:]`` and ``a⁺ = Q[:, :r] T⁻ᵀ``; elsewhere an SVD decides, with the
    same relative tolerance. Results of one rank are stored together (:meth:`at`).
    """

    def __init__(self, a: np.ndarray, tol: float) -> None:
        b, r, c = a.shape
        self.ranks = np.full(b, -1, dtype=int)
        self.groups: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        self.where = np.zeros(b, dtype=int)
        rest = np.arange(b)
        if 0 < r == c:  # square: its inverse, certified by the bound κ_F (compiled when numba runs)
            bound, inv = condition_bound(a)
            fro = np.sqrt(np.einsum("bij,bij->b", a, a))
            with np.errstate(invalid="ignore", divide="ignore"):
                sure = np.isfinite(bound) & (fro / (np.sqrt(r) * bound) > tol * np.maximum(fro, 1.0))
            idx = np.flatnonzero(sure)
            if idx.size:
                self._store(r, idx, np.zeros((idx.size, c, 0)), inv[idx], np.zeros((idx.size, r, 0)))
            rest = np.flatnonzero(~sure)
        elif 0 < r < c:
            q, t = np.linalg.qr(np.swapaxes(a, 1, 2), mode="complete")
            t = t[:, :r]
            try:
                inv = np.linalg.inv(t)
            except np.linalg.LinAlgError:
                inv = np.full_like(t, np.nan)
            fro = np.sqrt(np.einsum("bij,bij->b", t, t))
            bound = fro * np.sqrt(np.einsum("bij,bij->b", inv, inv))
            with np.errstate(invalid="ignore", divide="ignore"):
                sure = np.isfinite(bound) & (fro / (np.sqrt(r) * bound) > tol * np.maximum(fro, 1.0))
            idx = np.flatnonzero(sure)
            if idx.size:
                pinv = q[idx][:, :, :r] @ np.swapaxes(inv[idx], 1, 2)
                self._store(r, idx, q[idx][:, :, r:], pinv, np.zeros((idx.size, r, 0)))
            rest = np.flatnonzero(~sure)
        if rest.size:
            u, sv, vt = np.linalg.svd(a[rest])
            ranks = _ranks(sv, tol)
            for k in np.unique(ranks):
                sub = np.flatnonzero(ranks == k)
                kk = int(k)
                uu, ss, vv = u[sub], sv[sub], vt[sub]
                pinv = np.swapaxes(vv[:, :kk], 1, 2) @ (np.swapaxes(uu[:, :, :kk], 1, 2) / ss[:, :kk, None])
                self._store(kk, rest[sub], np.swapaxes(vv[:, kk:], 1, 2), pinv, uu[:, :, kk:])

    def _store(
        self, rank: int, idx: np.ndarray, null: np.ndarray, pinv: np.ndarray, left: np.ndarray
    ) -> None:
        self.ranks[idx] = rank
        if rank in self.groups:
            old = self.groups[rank]
            idx = np.concatenate([old[0], idx])
            null, pinv, left = (
                np.concatenate([o, x]) for o, x in zip(old[1:], (null, pinv, left), strict=True)
            )
        self.groups[rank] = (idx, null, pinv, left)
        self.where[idx] = np.arange(len(idx))

    def at(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(null, pinv, left)`` at ``poses`` (all of one rank)."""
        _, null, pinv, left = self.groups[int(self.ranks[poses[0]])]
        pos = self.where[poses]
        return null[pos], pinv[pos], left[pos]


def limb_fields(
    tree: LoopTree, params: TreeParameters, poses: TreePoses, general: bool = False
) -> list[dict | KinematicsError]:
    """The :class:`~pkmtol.error_model.separation.Separation` fields (a dict) or the error of each pose.

    ``general``: split every limb's loop system, serial limbs included (the reduction test);
    default: a serial limb (:func:`_simple`) takes its joints' columns directly.
    """
    raw = raw_world(tree, poses)
    b = len(raw)
    limbs = [lb for lb in tree.limbs if lb.reaches_base]
    simple = {
        li: _simple_part(tree, li, lb, poses, raw)
        for li, lb in enumerate(limbs)
        if _plan(tree, lb).simple is not None
    }
    systems = {li: _limb_system(tree, lb, poses, raw) for li, lb in enumerate(limbs) if li not in simple}
    splits = {li: _Split(r, LOOP_RANK_TOLERANCE) for li, (r, _, _) in systems.items()}
    key = np.stack(
        [splits[li].ranks if li in splits else np.zeros(b, dtype=int) for li in range(len(limbs))], axis=1
    )
    out: list[dict | KinematicsError | None] = [None] * b
    for k_r in np.unique(key, axis=0):
        at = np.flatnonzero((key == k_r).all(axis=1))
        parts = [
            _take_rows(simple[li], at)
            if li in simple
            else _limb_part(tree, li, lb, systems[li][1][at], systems[li][2], splits[li].at(at), poses, at)
            for li, lb in enumerate(limbs)
        ]
        key_s = np.stack([p["split_s"].ranks for p in parts], axis=1)
        for k_s in np.unique(key_s, axis=0):
            sub = np.flatnonzero((key_s == k_s).all(axis=1))
            fields = _assemble(tree, params, [_take(p, sub) for p in parts], poses, at[sub])
            for pos, f in zip(at[sub], fields, strict=True):
                out[int(pos)] = f
    return [f for f in out if f is not None]


def _simple_part(tree: LoopTree, li: int, limb: TreeLimb, poses: TreePoses, raw: np.ndarray) -> dict:
    """A serial limb (:func:`_simple`) at every pose: ``S = K' T_L``, ``E' = K' E_L``, no loop split."""
    plan = _plan(tree, limb)
    assert plan.simple is not None
    nj = len(plan.joints)
    c = plan.simple
    to_k = _k_prime(poses.frame(tree, tree.platform_frame)[:, :3, 3])
    s = to_k @ (poses.columns[:, :, plan.joints] * c[:nj])
    e = to_k @ (raw[:, :, plan.rc] * c[nj + 6 :])
    b = len(raw)
    act = [limb.joints.index(a) for a in tree.actuated if a in limb.joints]
    return {
        "limb": li,
        "limb_obj": limb,
        "act": act,
        "null": np.broadcast_to(np.eye(nj), (b, nj, nj)),  # the null motions: each joint alone
        "s": s,
        "e": e,
        "rc": plan.rc,
        "inner": np.zeros((b, 0, len(plan.rc))),
        "split_s": _Split(np.swapaxes(s, 1, 2), RANK_TOLERANCE),
    }


def _limb_part(
    tree: LoopTree,
    li: int,
    limb: TreeLimb,
    d: np.ndarray,
    rc: np.ndarray,
    split: tuple[np.ndarray, np.ndarray, np.ndarray],
    poses: TreePoses,
    at: np.ndarray,
) -> dict:
    """One limb at poses ``at`` (its loop system of one rank): its motion space and columns."""
    nj = len(limb.joints)
    act = [limb.joints.index(a) for a in tree.actuated if a in limb.joints]
    null, pinv, left = split
    x = -(pinv @ d)  # a solution of R x = −D (b, nJ + 6, k)
    to_k = _k_prime(poses.frame(tree, tree.platform_frame)[at, :3, 3])
    s = to_k @ null[:, nj:]
    if act:  # hold the limb's actuators: move x along null(R) so that its dq_a vanish
        q_a = null[:, act]  # (b, f_L, d)
        if len(act) == 1:
            qq = np.einsum("bij,bij->b", q_a, q_a)
            c = np.swapaxes(q_a, 1, 2) * (x[:, act] / np.where(qq > 0, qq, 1.0)[:, None, None])
        else:
            c = np.linalg.pinv(q_a) @ x[:, act]
        tau = x[:, nj:] - null[:, nj:] @ c
    else:
        tau = x[:, nj:]
    return {
        "limb": li,
        "limb_obj": limb,
        "act": act,
        "null": null,
        "s": s,
        "e": to_k @ tau,
        "rc": rc,
        "inner": np.swapaxes(left, 1, 2) @ d,
        "split_s": _Split(np.swapaxes(s, 1, 2), RANK_TOLERANCE),
    }


def _k_prime(p: np.ndarray) -> np.ndarray:
    """Shape (b, 6, 6): spatial twists to K' twists at points ``p`` (b, 3): ``[I −[p×]; 0 I]``."""
    out = np.zeros((len(p), 6, 6))
    out[:, np.arange(6), np.arange(6)] = 1.0
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    out[:, 0, 4], out[:, 0, 5] = z, -y
    out[:, 1, 3], out[:, 1, 5] = -z, x
    out[:, 2, 3], out[:, 2, 4] = y, -x
    return out


def _take_rows(part: dict, at: np.ndarray) -> dict:
    """A part at poses ``at``, its motion-space split restricted to them."""
    if len(at) == len(part["s"]):
        return part
    p = {k: (v[at] if isinstance(v, np.ndarray) and v.ndim >= 2 else v) for k, v in part.items()}
    p["split_s"] = _Split(np.swapaxes(p["s"], 1, 2), RANK_TOLERANCE)
    return p


def _take(part: dict, sub: np.ndarray) -> dict:
    """The part at poses ``sub`` (one motion-space rank): its constraint wrenches and ``(Sᵀ)⁺``."""
    p = {k: (v[sub] if isinstance(v, np.ndarray) and v.ndim >= 2 else v) for k, v in part.items()}
    p["wc"], p["s_pinv"], _ = part["split_s"].at(sub)
    return p


def _assemble(
    tree: LoopTree, params: TreeParameters, parts: list[dict], poses: TreePoses, at: np.ndarray
) -> list[dict | KinematicsError]:
    """Eqs. 5–8, 25 at poses ``at`` (every rank the same): the formulas of ``separation._stacked``."""
    b, n = len(at), len(params)
    sel = params.selection
    hp = poses.frame(tree, tree.platform_frame)[at]
    where = tree.task.position(poses.frame(tree, tree.task_frame)[at])
    errors: list[KinematicsError | None] = [None] * b
    wa, wc, ya, yc, lam, act_limb, con_limb, inner = [], [], [], [], [], [], [], []
    cols = np.zeros((b, 6, n))
    for p in parts:
        sl = sel[p["rc"]]
        pc = np.flatnonzero(np.any(sl != 0.0, axis=0))  # the parameters this limb sees
        e_pc = (p["e"].reshape(-1, len(p["rc"])) @ sl[:, pc]).reshape(b, 6, len(pc))
        cols[:, :, pc] += e_pc  # each parameter's twist through the limbs that see it (one, for limbs)
        ws = [p["wc"][:, :, k] for k in range(p["wc"].shape[2])]
        con_limb += [p["limb"]] * len(ws)
        n_c = len(ws)
        for a in p["act"]:
            rhs = p["null"][:, a, :]  # dq_a of each null motion (b, d)
            w = (p["s_pinv"] @ rhs[:, :, None])[:, :, 0]  # the minimum-norm w with Sᵀ w = rhs
            miss = np.abs(np.einsum("bjd,bj->bd", p["s"], w) - rhs).max(axis=1, initial=0.0)
            f_norm = np.linalg.norm(w[:, :3], axis=1)
            scale = np.where(
                f_norm > 1e-9 * np.linalg.norm(w, axis=1), f_norm, np.linalg.norm(w[:, 3:], axis=1)
            )
            for k in np.flatnonzero(~(miss < 1e-6) | ~(scale > 0)):
                joint = tree.joint_names[p["limb_obj"].joints[a]]
                errors[int(k)] = errors[int(k)] or MobilityError(
                    f"limb {p['limb'] + 1} of '{tree.name}': actuated joint '{joint}' moves the platform "
                    f"only within the passive motions at P = {where[k]} m (actuation singularity, or its "
                    "loops lock it)"
                )
            scale = np.where(scale > 0, scale, 1.0)
            ws.append(w / scale[:, None])
            lam.append(1.0 / scale)
            act_limb.append(p["limb"])
        if ws:
            w_l = np.stack(ws, axis=2)  # (b, 6, m_L): constraint wrenches, then actuation wrenches
            y_l = np.zeros((b, len(ws), n))
            y_l[:, :, pc] = np.swapaxes(w_l, 1, 2) @ e_pc
            wc += [w_l[:, :, k] for k in range(n_c)]
            yc += [y_l[:, k] for k in range(n_c)]
            wa += [w_l[:, :, k] for k in range(n_c, len(ws))]
            ya += [y_l[:, k] for k in range(n_c, len(ws))]
        if p["inner"].shape[1]:
            inner.append(p["inner"] @ sl)
    f, c = len(wa), len(wc)
    if f + c < 6:
        err = MobilityError(
            f"only {f} actuation + {c} constraint wrenches at P = {where[0]} m; the platform keeps "
            f"{6 - f - c} uncontrolled freedom(s). Check the actuated joints"
        )
        return [err] * b
    w_all = np.concatenate(
        [
            np.stack(wa, axis=2) if f else np.zeros((b, 6, 0)),
            np.stack(wc, axis=2) if c else np.zeros((b, 6, 0)),
        ],
        axis=2,
    )
    sv = np.linalg.svd(w_all, compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(sv[:, 5] > 0, sv[:, 0] / sv[:, 5], np.inf)
    y_a = np.stack(ya, axis=1) if f else np.zeros((b, 0, n))
    y_c = np.stack(yc, axis=1) if c else np.zeros((b, 0, n))
    usable = cond <= W_SINGULAR_CONDITION
    w_inv_t = np.full((b, 6, f + c), np.nan)
    if usable.any():
        wu = w_all[usable]
        w_inv_t[usable] = (
            np.swapaxes(np.linalg.inv(wu), 1, 2) if f + c == 6 else np.linalg.pinv(np.swapaxes(wu, 1, 2))
        )
    y = np.concatenate([y_a, y_c], axis=1)
    twist_map = w_inv_t @ y
    unc = w_inv_t[:, :, f:] @ y_c
    incompatible = y - np.swapaxes(w_all, 1, 2) @ twist_map
    n_inner = sum(x.shape[1] for x in inner)
    if inner:
        incompatible = np.concatenate([incompatible] + inner, axis=1)
    lever = where - hp[:, :3, 3]
    to_p = tree.task.of_twist(lever)
    lam_arr = np.stack(lam, axis=1) if f else np.zeros((b, 0))
    correction = -(y_a / lam_arr[:, :, None]) if f else np.zeros((b, 0, n))
    j_c, j_t = to_p @ unc, to_p @ twist_map
    actuation = w_inv_t[:, :, :f] * lam_arr[:, None, :]
    out: list[dict | KinematicsError] = []
    for pos in range(b):
        failed = errors[pos]
        if failed is not None:
            out.append(failed)
        elif not usable[pos]:
            out.append(SingularPoseError("the wrench matrix W", float(cond[pos]), where[pos]))
        else:
            out.append(
                {
                    "joint_twists": tuple(p["s"][pos] for p in parts),
                    "error_columns": cols[pos],
                    "W_a": w_all[pos, :, :f],
                    "W_c": w_all[pos, :, f:],
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
                    "J": j_c[pos],
                    "J_total": j_t[pos],
                    "redundancy": f + c - 6 + n_inner,
                    "incompatible_map": incompatible[pos],
                    "actuation_map": actuation[pos],
                }
            )
    return out
