"""The error model of a :class:`~pkmtol.model.loop_tree.LoopTree`: its loops eliminated, its limbs separated.

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

import pkmtol.values as values
from pkmtol.error_model.separation import Separation
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.tree_parameters import TreeParameters
from pkmtol.error_model.tree_wrenches import LOOP_RANK_TOLERANCE, limb_fields
from pkmtol.exceptions import ClosedLoopError, InvalidArgumentError, KinematicsError, MobilityError
from pkmtol.kinematics.continuation import continuation
from pkmtol.kinematics.solutions import Solutions
from pkmtol.kinematics.tree_chain import TreeBatch
from pkmtol.kinematics.tree_frames import forward, loop_jacobians, raw_world, to_k_prime
from pkmtol.model.loop_tree import LoopTree


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


def _pinv(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pseudo-inverse, left and right null bases and ranks (b,) of stacked ``a`` (b, r, k), by SVD."""
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


def _check_tree(tree: object, params: object = None, batch: object = None) -> None:
    """The tree, its parameter set and its solver (when given), checked to belong together."""
    values.instance("tree", tree, LoopTree, "a pkmtol LoopTree (pkmtol.tree_from_urdf)")
    assert isinstance(tree, LoopTree)
    if params is not None or batch is not None:
        values.instance("params", params, TreeParameters, "the tree's TreeParameters (pkmtol.tree_urdf_set)")
        assert isinstance(params, TreeParameters)
        if params.selection.shape[0] != tree.n_raw:
            raise InvalidArgumentError("params", params.kind, "belongs to another tree (tree_urdf_set(tree))")
    if batch is not None:
        values.instance("batch", batch, TreeBatch, "a TreeBatch of the tree, or None")
        assert isinstance(batch, TreeBatch)
        if batch.tree is not tree:
            raise InvalidArgumentError("batch", batch.tree.name, "solves another tree; give TreeBatch(tree)")


def frame_maps(tree: LoopTree, q: np.ndarray, frame: int) -> FrameMaps:
    """The motion of ``frame`` at poses ``q`` (b, n) with the loops eliminated (module docstring).

    The Jacobian of the frame's pose with respect to the actuated joints (``actuation``) and to the
    raw errors (``errors``; a parameter set's columns are ``errors @ selection``), through the exact
    closed chain: what a measurement model needs (its residual's Jacobian is its rows of these).

    Raises:
        MobilityError: a passive motion that keeps the loops closed moves the frame (the
            actuators do not hold it there).
    """
    _check_tree(tree)
    q = values.array("q", q)
    q = values.array_of_shape("q", q[None] if q.ndim == 1 else q, (None, tree.nq))
    frame = values.index("frame", frame, tree.model.nframes)
    poses = forward(TreeBatch(tree).tables, q)
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


def separate_tree(
    tree: LoopTree,
    params: TreeParameters,
    sols: Solutions,
    batch: TreeBatch | None = None,
    general: bool = False,
) -> list[Separation | KinematicsError]:
    """The separation (:class:`~pkmtol.error_model.separation.Separation`) at every solved pose.

    Args:
        tree: The mechanism (its task frame on the platform body).
        params: The parameter set.
        sols: Solved poses (:meth:`TreeBatch.inverse`).
        batch: The solver that produced them (its tables are reused).
        general: Split every limb's loop system, serial limbs included (the same results to
            round-off; the reduction test); default: serial limbs take their joints' columns.

    Returns:
        Per problem: its separation, or its error (the solver's, a :class:`SingularPoseError` of W,
        a :class:`MobilityError`).
    """
    _check_tree(tree, params, batch)
    values.instance("sols", sols, Solutions, "the Solutions of TreeBatch.inverse")
    if sols.q.ndim != 2 or sols.q.shape[1] != tree.nq:
        raise InvalidArgumentError(
            "sols", f"q of shape {sols.q.shape}", f"expected solutions of this tree ({tree.nq} joints)"
        )
    values.flag("general", general)
    if (tree.support(tree.task_frame) & ~tree.support(tree.platform_frame)).any():
        raise ClosedLoopError(
            tree.name,
            tree.model.frames[tree.task_frame].name,
            "the task frame is beyond the platform body: the separation needs it on the platform "
            "(frame_maps gives its motion through the joints between)",
        )
    out: list[Separation | KinematicsError | None] = list(sols.errors)
    idx = np.array([k for k, e in enumerate(sols.errors) if e is None], dtype=int)
    if idx.size:
        batch = batch or TreeBatch(tree)
        fields = limb_fields(tree, params, forward(batch.tables, sols.q[idx]), general)
        for pos, k in enumerate(idx):
            f = fields[pos]
            out[int(k)] = f if isinstance(f, KinematicsError) else Separation(pose=sols.pose(int(k)), **f)
    return [e for e in out if e is not None]


def tree_sweep(
    tree: LoopTree,
    params: TreeParameters,
    points_m: np.ndarray,
    batch: TreeBatch | None = None,
    guesses: np.ndarray | None = None,
    general: bool = False,
) -> Sweep:
    """Inverse kinematics at every point and the separation there (a :class:`Sweep`).

    Without ``guesses`` the points are reached by continuation from the refined home.

    Raises:
        KinematicsError: the first point (in order) that cannot be solved or separated.
    """
    _check_tree(tree, params, batch)
    points = values.points("points_m", points_m)
    if guesses is not None:
        guesses = values.array_of_shape("guesses", guesses, (len(points), tree.nq))
    batch = batch or TreeBatch(tree)
    if guesses is None:
        sols = continuation(batch, points, batch.chain.home())
    else:
        sols = batch.inverse(points, guesses)
    seps = separate_tree(tree, params, sols, batch, general)
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
