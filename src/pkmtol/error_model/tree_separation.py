"""The error model of a :class:`~pkmtol.model.loop_tree.LoopTree`: loops eliminated through the constraint Jacobian.

At a closed pose the loops' rows are ``C dq + D δ = 0`` (``C`` the constraint Jacobian, ``D`` its
columns per raw error, :func:`loop_jacobians`) and a frame f moves by ``T_f dq + E_f δ``
(spatial twists, :mod:`pkmtol.kinematics.tree_frames`).

**Any frame, loops eliminated** (:func:`frame_maps`). With the actuators held, the passive joints
close the loops again, ``dq_p = −C_p⁺ (C_a dq_a + D δ)``, so frame f's K' twist is
``A_f dq_a + B_f δ`` with ``A_f = T_f,a − T_f,p C_p⁺ C_a`` (the actuated joints' span at f) and
``B_f = E_f − T_f,p C_p⁺ D``. A passive motion that keeps the loops closed and moves f
(``T_f,p null(C_p) ≠ 0``) means f is not held by the actuators (:class:`MobilityError`); rows of
``D`` outside ``range(C)`` are errors no joint motion closes (assembly errors).

**Separation** (:func:`separate_tree`). Compensability is the actuated span: an error is
compensatable when its twist at the platform lies in ``range(A)`` at every pose, uncompensatable
otherwise. What the compensated residual is depends on a choice of actuation wrenches (a complement
of ``range(A)``; docs/theory.md, "One tree with loops"). The choice made here is the limb path's,
generalised: the mechanism's *limbs* are its connected parts once the base and the platform body are
removed (:attr:`LoopTree.limbs`). For limb L, with the platform's twist τ as an unknown, its joints
and loops give rows ``R_L [dq_L; τ] + D_L δ = 0``; its motion space is the τ part ``S_L`` of
``null(R_L)`` (in K'), its constraint wrenches ``W_c,L = null(S_Lᵀ)``, and each actuator's wrench the
minimum-norm ``w`` with ``w · τ(z) = dq_a(z)`` for every ``z ∈ null(R_L)`` (reciprocal to the limb's
passive motions, orthogonal to ``W_c,L``), scaled to a unit screw. The limb's error columns are
``E'_L`` = the τ part of ``−R_L,(p,τ)⁺ D_L`` (its loops closed by passive motion, actuators held).
Then Eqs. 5–8 and 25 as in :mod:`pkmtol.error_model.separation`: ``Y = [W_aᵀ E'; W_cᵀ E']``,
``$ = W⁻ᵀ Y η``, ``Δu = −Λ⁻¹ Y_a η``, the residual ``W⁻ᵀ [0; Y_c] η``. For a tree made from limbs
(:func:`~pkmtol.model.tree_from_limbs.tree_from_mechanism`) these are the limb path's maps, classes
and allocation (``tests/test_loop_tree.py``, 1e-10 on every bundled robot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.error_model.separation import RANK_TOLERANCE, W_SINGULAR_CONDITION, Separation
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.tree_parameters import TreeParameters
from pkmtol.exceptions import ClosedLoopError, KinematicsError, MobilityError, SingularPoseError
from pkmtol.kinematics import se3_batch
from pkmtol.kinematics.continuation import continuation
from pkmtol.kinematics.solutions import Solutions
from pkmtol.kinematics.tree_chain import TreeBatch
from pkmtol.kinematics.tree_frames import TreePoses, adjoint, adjoint_inverse, forward, point_rows, to_k_prime
from pkmtol.model.loop_tree import LoopTree

#: Relative singular-value threshold of the loop systems' ranks.
LOOP_RANK_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class FrameMaps:
    """A frame's motion at ``b`` poses with the loops eliminated (K' at the frame's origin, SI units).

    Attributes:
        actuation: Shape (b, 6, f): twist per unit motion of each actuated joint (``A_f``).
        errors: Shape (b, 6, n_raw): twist per raw error, actuators held (``B_f``).
        incompatible: Shape (b, k, n_raw): the loop rows no joint motion closes (assembly errors).
        placement: Shape (b, 4, 4): the frame's placement in K.
    """

    actuation: np.ndarray
    errors: np.ndarray
    incompatible: np.ndarray
    placement: np.ndarray


def raw_world(tree: LoopTree, poses: TreePoses) -> np.ndarray:
    """Spatial twist (b, 6, n_raw) of every raw error (module docstring of tree_frames)."""
    b = len(poses.joint)
    out = np.zeros((b, 6, tree.n_raw))
    g = adjoint(poses.pre.reshape(-1, 4, 4)).reshape(b, tree.nq, 6, 6)
    out[:, :, : 6 * tree.nq] = np.swapaxes(g, 1, 2).reshape(b, 6, 6 * tree.nq)
    for k, ef in enumerate(tree.error_frames):
        out[:, :, tree.raw_block("frame", k)] = adjoint(poses.frame(tree, ef.frame))
    for k, lp in enumerate(tree.loops):
        out[:, :, tree.raw_block("loop", k)] = adjoint(poses.frame(tree, lp.frame_b))
    out[:, :, tree.offset_start :] = poses.columns
    return out


def _rows(kind: str, ha: np.ndarray, hb: np.ndarray, va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """A loop's rows (b, rows, k) for spatial motions ``va``/``vb`` (b, 6, k) of its frames a and b."""
    if kind == "3d":
        return point_rows(hb[:, :3, 3], vb) - point_rows(ha[:, :3, 3], va)
    rat = np.swapaxes(ha[:, :3, :3], 1, 2)
    re = rat @ hb[:, :3, :3]
    pe = (rat @ (hb[:, :3, 3] - ha[:, :3, 3])[:, :, None])[:, :, 0]
    _, jl, _ = se3_batch.log6_and_jacobian(re, pe)
    return (jl @ adjoint_inverse(hb)) @ (vb - va)


def loop_jacobians(tree: LoopTree, poses: TreePoses, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The constraint Jacobian ``C`` (b, rows, n) and its error columns ``D`` (b, rows, n_raw)."""
    c, d = [np.zeros((len(raw), 0, tree.nq))], [np.zeros((len(raw), 0, tree.n_raw))]
    for lp in tree.loops:
        ha, hb = poses.frame(tree, lp.frame_a), poses.frame(tree, lp.frame_b)
        sa, sb = tree.support(lp.frame_a), tree.support(lp.frame_b)
        c.append(_rows(lp.kind, ha, hb, poses.columns * sa, poses.columns * sb))
        d.append(_rows(lp.kind, ha, hb, raw * tree.moved_by(lp.frame_a), raw * tree.moved_by(lp.frame_b)))
    return np.concatenate(c, axis=1), np.concatenate(d, axis=1)


def _pinv(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pseudo-inverse (b, k, r), left null basis (b, r, r − rank), right null basis, ranks (b,) of stacked ``a``."""
    u, sv, vt = np.linalg.svd(a)
    ranks = np.sum(sv > LOOP_RANK_TOLERANCE * np.maximum(sv[:, :1] if sv.shape[1] else 1.0, 1.0), axis=1)
    b, rows, cols = a.shape
    pinv = np.zeros((b, cols, rows))
    left = []
    right = []
    for r in np.unique(ranks):
        at = np.flatnonzero(ranks == r)
        s = slice(0, int(r))
        pinv[at] = np.swapaxes(vt[at][:, s], 1, 2) @ (np.swapaxes(u[at][:, :, s], 1, 2) / sv[at][:, s, None])
        left.append((at, u[at][:, :, int(r) :]))
        right.append((at, np.swapaxes(vt[at][:, int(r) :], 1, 2)))
    rank = int(np.bincount(ranks).argmax())
    lb = np.full((b, rows, rows - rank), np.nan)
    rb = np.full((b, cols, cols - rank), np.nan)
    for (at, lu), (_, rv) in zip(left, right, strict=True):
        if lu.shape[2] == rows - rank:
            lb[at], rb[at] = lu, rv
    return pinv, lb, rb, ranks


def frame_maps(tree: LoopTree, q: np.ndarray, frame: int) -> FrameMaps:
    """The motion of ``frame`` at poses ``q`` (b, n) with the loops eliminated (module docstring).

    The Jacobian of the frame's pose with respect to the actuated joints (``actuation``) and to the
    raw errors (``errors``; a parameter set's columns are ``errors @ selection``), through the exact
    closed chain: what a measurement model needs (its residual's Jacobian is its rows of these).

    Raises:
        MobilityError: a passive motion that keeps the loops closed moves the frame (the
            actuators do not hold it there).
    """
    poses = forward(TreeBatch(tree).tables, np.asarray(q, dtype=float).reshape(-1, tree.nq))
    raw = raw_world(tree, poses)
    c, d = loop_jacobians(tree, poses, raw)
    act = np.array(tree.actuated, dtype=int)
    pas = np.array(tree.passive, dtype=int)
    pinv, left, right, _ = _pinv(c[:, :, pas])
    h = poses.frame(tree, frame)
    t = poses.columns * tree.support(frame)
    e = raw * tree.moved_by(frame)
    tp = t[:, :, pas]
    if right.shape[2] and np.isfinite(right).all():
        idle = np.abs(tp @ right).max(initial=0.0)
        if idle > 1e-9 * max(1.0, float(np.abs(tp).max(initial=0.0))):
            raise MobilityError(
                f"{tree.name}: a passive motion that keeps the loops closed moves frame "
                f"'{tree.model.frames[frame].name}' ({idle:.2g} per unit); add an actuator or a loop"
            )
    p = h[:, :3, 3]
    a_map = to_k_prime(p, t[:, :, act] - tp @ (pinv @ c[:, :, act]))
    b_map = to_k_prime(p, e - tp @ (pinv @ d))
    inc = np.swapaxes(left, 1, 2) @ d
    return FrameMaps(a_map, b_map, inc, h)


def _limb_system(
    tree: LoopTree, limb_joints: tuple[int, ...], loops: tuple[int, ...], holds: bool, poses: TreePoses, raw: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A limb's rows ``R_L`` (b, rows, nJ + 6) over ``[dq_L; τ]`` and ``D_L`` (b, rows, n_raw)."""
    pf = tree.platform_frame
    sup_p, mov_p = tree.support(pf), tree.moved_by(pf)
    pjoint = int(tree.model.frames[pf].parentJoint) - 1
    cols = list(limb_joints)
    b = len(raw)
    r_rows, d_rows = [], []

    def motion(x: int) -> tuple[np.ndarray, np.ndarray]:
        sup, mov = tree.support(x), tree.moved_by(x)
        v = np.zeros((b, 6, len(cols) + 6))
        on_platform = pjoint >= 0 and sup[pjoint]
        if on_platform:
            sup, mov = sup & ~sup_p, mov.astype(float) - mov_p
            v[:, :, len(cols) :] = np.eye(6)
        stray = set(np.flatnonzero(sup).tolist()) - set(cols)
        if stray:
            raise ClosedLoopError(
                tree.name,
                tree.model.frames[x].name,
                f"frame '{tree.model.frames[x].name}' is moved by joint '{tree.joint_names[min(stray)]}' of "
                "another limb; a loop frame must hang on its own limb or on the platform",
            )
        v[:, :, : len(cols)] = poses.columns[:, :, cols] * sup[cols]
        return v, raw * mov

    for k in loops:
        lp = tree.loops[k]
        ha, hb = poses.frame(tree, lp.frame_a), poses.frame(tree, lp.frame_b)
        (va, ea), (vb, eb) = motion(lp.frame_a), motion(lp.frame_b)
        r_rows.append(_rows(lp.kind, ha, hb, va, vb))
        d_rows.append(_rows(lp.kind, ha, hb, ea, eb))
    if holds:
        v = np.zeros((b, 6, len(cols) + 6))
        v[:, :, : len(cols)] = -poses.columns[:, :, cols] * sup_p[cols]
        v[:, :, len(cols) :] = np.eye(6)
        r_rows.append(v)
        d_rows.append(-(raw * mov_p))
    if not r_rows:
        return np.zeros((b, 0, len(cols) + 6)), np.zeros((b, 0, tree.n_raw))
    return np.concatenate(r_rows, axis=1), np.concatenate(d_rows, axis=1)


def separate_tree(
    tree: LoopTree, params: TreeParameters, sols: Solutions, batch: TreeBatch | None = None
) -> list[Separation | KinematicsError]:
    """The separation (:class:`~pkmtol.error_model.separation.Separation`) at every solved pose.

    Args:
        tree: The mechanism (its task frame on the platform body).
        params: The parameter set.
        sols: Solved poses (:meth:`TreeBatch.inverse`).
        batch: The solver that produced them (its tables are reused).

    Returns:
        Per problem: its separation, or its error (the solver's, a :class:`SingularPoseError` of W,
        a :class:`MobilityError`).
    """
    out: list[Separation | KinematicsError | None] = list(sols.errors)
    idx = np.array([k for k, e in enumerate(sols.errors) if e is None], dtype=int)
    if idx.size:
        batch = batch or TreeBatch(tree)
        fields = _fields(tree, params, forward(batch.tables, sols.q[idx]))
        for pos, k in enumerate(idx):
            f = fields[pos]
            out[int(k)] = f if isinstance(f, KinematicsError) else Separation(pose=sols.pose(int(k)), **f)
    return [e for e in out if e is not None]


def _fields(tree: LoopTree, params: TreeParameters, poses: TreePoses) -> list[dict | KinematicsError]:
    """The Separation fields (a dict) or the error of each pose."""
    raw = raw_world(tree, poses)
    sel = params.selection
    b, n = len(raw), len(params)
    hp = poses.frame(tree, tree.platform_frame)
    o_p = hp[:, :3, 3]
    ht = poses.frame(tree, tree.task_frame)
    if (tree.support(tree.task_frame) & ~tree.support(tree.platform_frame)).any():
        raise ClosedLoopError(
            tree.name,
            tree.model.frames[tree.task_frame].name,
            "the task frame is beyond the platform body: the separation needs it on the platform "
            "(frame_maps gives its motion through the joints between)",
        )
    errors: list[KinematicsError | None] = [None] * b
    wa, wc, ya, yc, lam, twists, act_limb, con_limb, inner = [], [], [], [], [], [], [], [], []
    cols = np.zeros((b, 6, n))
    best = np.zeros((b, n))
    where = tree.task.position(ht)
    for li, limb in enumerate(tree.limbs):
        if not limb.reaches_base:
            continue
        r, d = _limb_system(tree, limb.joints, limb.loops, limb.holds_platform, poses, raw)
        nj = len(limb.joints)
        act_pos = [limb.joints.index(a) for a in tree.actuated if a in limb.joints]
        pas_pos = [i for i in range(nj) if i not in act_pos] + list(range(nj, nj + 6))
        _, _, null, ranks_r = _pinv(r)
        pinv_p, left_p, _, ranks_p = _pinv(r[:, :, pas_pos])
        s = to_k_prime(o_p, null[:, nj:])  # the limb's motion space in K'
        u, sv, vt = np.linalg.svd(s)
        rank_s = int(np.bincount(np.sum(sv > RANK_TOLERANCE * np.maximum(sv[:, :1], 1.0), axis=1)).argmax())
        twists.append(s)
        e_lim = to_k_prime(o_p, -(pinv_p @ d)[:, -6:]) @ sel  # (b, 6, n)
        norms = np.linalg.norm(e_lim, axis=1)
        take = norms > best
        cols = np.where(take[:, None, :], e_lim, cols)
        best = np.maximum(best, norms)
        for k in range(6 - rank_s):
            w = u[:, :, rank_s + k]
            wc.append(w)
            con_limb.append(li)
            yc.append(np.einsum("bj,bjm->bm", w, e_lim))
        for a in act_pos:
            rhs = null[:, a, :]  # dq_a of each null motion
            w = u[:, :, :rank_s] @ ((vt[:, :rank_s] @ rhs[:, :, None])[:, :, 0] / sv[:, :rank_s])[:, :, None]
            w = w[:, :, 0]
            miss = np.abs(np.einsum("bjd,bj->bd", s, w) - rhs).max(axis=1, initial=0.0)
            for k in np.flatnonzero(~(miss < 1e-6)):
                errors[int(k)] = errors[int(k)] or MobilityError(
                    f"limb {li + 1} of '{tree.name}': actuated joint '{tree.joint_names[limb.joints[a]]}' moves "
                    f"the platform only within the passive motions at P = {where[k]} m (actuation singularity)"
                )
            f_norm = np.linalg.norm(w[:, :3], axis=1)
            scale = np.where(f_norm > 1e-9 * np.linalg.norm(w, axis=1), f_norm, np.linalg.norm(w[:, 3:], axis=1))
            wa.append(w / scale[:, None])
            lam.append(1.0 / scale)
            act_limb.append(li)
            ya.append(np.einsum("bj,bjm->bm", w / scale[:, None], e_lim))
        if left_p.shape[2]:
            inner.append(np.swapaxes(left_p, 1, 2) @ d @ sel)
        for k in np.flatnonzero(ranks_r != np.bincount(ranks_r).argmax()):
            errors[int(k)] = errors[int(k)] or SingularPoseError(
                f"the loop equations of limb {li + 1} (their rank changes)", float("inf"), where[k]
            )
    return _assemble(tree, b, n, wa, wc, ya, yc, lam, twists, act_limb, con_limb, inner, cols, hp, ht, errors)


def _assemble(
    tree: LoopTree,
    b: int,
    n: int,
    wa: list,
    wc: list,
    ya: list,
    yc: list,
    lam: list,
    twists: list,
    act_limb: list,
    con_limb: list,
    inner: list,
    cols: np.ndarray,
    hp: np.ndarray,
    ht: np.ndarray,
    errors: list,
) -> list[dict | KinematicsError]:
    """Eqs. 5–8, 25 from the limbs' wrenches and rows (the formulas of :mod:`pkmtol.error_model.separation`)."""
    f, c = len(wa), len(wc)
    where = tree.task.position(ht)
    if f + c < 6:
        err = MobilityError(
            f"only {f} actuation + {c} constraint wrenches at P = {where[0]} m; the platform keeps "
            f"{6 - f - c} uncontrolled freedom(s). Check the actuated joints"
        )
        return [err] * b
    w = np.concatenate(
        [np.stack(wa, axis=2) if f else np.zeros((b, 6, 0)), np.stack(wc, axis=2) if c else np.zeros((b, 6, 0))],
        axis=2,
    )
    sv = np.linalg.svd(w, compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(sv[:, 5] > 0, sv[:, 0] / sv[:, 5], np.inf)
    y_a = np.stack(ya, axis=1) if f else np.zeros((b, 0, n))
    y_c = np.stack(yc, axis=1) if c else np.zeros((b, 0, n))
    usable = cond <= W_SINGULAR_CONDITION
    w_inv_t = np.full((b, 6, f + c), np.nan)
    if usable.any():
        wu = w[usable]
        w_inv_t[usable] = np.swapaxes(np.linalg.inv(wu), 1, 2) if f + c == 6 else np.linalg.pinv(np.swapaxes(wu, 1, 2))
    y = np.concatenate([y_a, y_c], axis=1)
    twist_map = w_inv_t @ y
    unc = w_inv_t[:, :, f:] @ y_c
    incompatible = y - np.swapaxes(w, 1, 2) @ twist_map
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
    for k in range(b):
        if errors[k] is not None:
            out.append(errors[k])
        elif not usable[k]:
            out.append(SingularPoseError("the wrench matrix W", float(cond[k]), where[k]))
        else:
            out.append(
                {
                    "joint_twists": tuple(t[k] for t in twists),
                    "error_columns": cols[k],
                    "W_a": w[k, :, :f],
                    "W_c": w[k, :, f:],
                    "constraint_limb": np.array(con_limb, dtype=int),
                    "actuated_limb": np.array(act_limb, dtype=int),
                    "Lambda_a": lam_arr[k],
                    "Y_a": y_a[k],
                    "Y_c": y_c[k],
                    "W_condition": float(cond[k]),
                    "twist_map": twist_map[k],
                    "correction": correction[k],
                    "uncompensated_map": unc[k],
                    "lever_m": lever[k],
                    "J": j_c[k],
                    "J_total": j_t[k],
                    "redundancy": f + c - 6 + n_inner,
                    "incompatible_map": incompatible[k],
                    "actuation_map": actuation[k],
                }
            )
    return out


def tree_sweep(
    tree: LoopTree,
    params: TreeParameters,
    points_m: np.ndarray,
    batch: TreeBatch | None = None,
    guesses: np.ndarray | None = None,
) -> Sweep:
    """Inverse kinematics at every point and the separation there (a :class:`~pkmtol.error_model.sweep.Sweep`).

    Without ``guesses`` the points are reached by continuation from the refined home.

    Raises:
        KinematicsError: the first point (in order) that cannot be solved or separated.
    """
    batch = batch or TreeBatch(tree)
    points = np.asarray(points_m, dtype=float).reshape(-1, 3)
    if guesses is None:
        sols = continuation(batch, points, batch.chain.home())
    else:
        sols = batch.inverse(points, guesses)
    seps = separate_tree(tree, params, sols, batch)
    failed = next((s for s in seps if not isinstance(s, Separation)), None)
    if failed is not None:
        raise failed
    done = [s for s in seps if isinstance(s, Separation)]
    m = len(points)
    return Sweep(
        points_m=points,
        poses=tuple(s.pose for s in done),
        separations=tuple(done),
        J=np.array([s.J for s in done]).reshape(m, 3, len(params)),
        J_total=np.array([s.J_total for s in done]).reshape(m, 3, len(params)),
        W_condition=np.array([s.W_condition for s in done]),
    )
