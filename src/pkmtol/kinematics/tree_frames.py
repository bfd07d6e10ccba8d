"""Forward kinematics of a :class:`~pkmtol.model.loop_tree.LoopTree` stacked over poses, in spatial twists.

For ``b`` configurations at once, joint by joint in tree order (numpy, no call into Pinocchio per
pose): each joint's placement ``oMi_j = oMi_parent · jointPlacements[j] · exp(S_j q_j)`` and its
pre-motion frame ``X_j = oMi_parent · jointPlacements[j]``. Every motion is a *spatial* twist
``[v_O; ω]`` in K (the velocity of the point of the moving body at the origin of K): then a frame's
motion is the sum of the motions of the joints and errors that move it, with no transport:

* joint ``j``'s column ``s_j = Ad(oMi_j) S_j``;
* a joint placement error ``ε_j`` (``jointPlacements[j] · exp6(ε_j)``, in the joint's frame):
  ``Ad(X_j) ε_j`` (6 columns, ``G_j = Ad(X_j)``);
* a frame's placement error ``oMF · exp6(ε)`` (an error frame, or a loop's frame b): ``Ad(oMF) ε``.

A frame's LOCAL twist is ``Ad(oMf⁻¹)`` of its spatial one; the K' twist (origin at the frame,
axes of K) is ``[I −[p×]; 0 I]`` of it. The numbers agree with Pinocchio's ``forwardKinematics``,
``getFrameJacobian`` and ``computeFrameKinematicRegressor`` to round-off (``tests/test_loop_tree.py``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from functools import cache
from types import ModuleType

import numpy as np

from pkmtol.kinematics import acceleration, se3_batch
from pkmtol.model.loop_tree import LoopTree


@cache
def tree_kernel() -> ModuleType | None:
    """:mod:`pkmtol.kinematics.tree_kernels` when the compiled kernels run, else None."""
    if acceleration.kernels() is None:
        return None
    return importlib.import_module("pkmtol.kinematics.tree_kernels")


@dataclass(frozen=True, eq=False)
class TreeTables:
    """The joint tables of a tree (``n`` joints).

    Attributes:
        parent: Shape (n,): parent joint index (−1: the base).
        revolute: Shape (n,): True for a revolute joint.
        axis: Shape (n, 3): unit axis in the joint frame.
        placement: Shape (n, 4, 4): ``jointPlacements`` (nominal, or perturbed).
    """

    parent: np.ndarray
    revolute: np.ndarray
    axis: np.ndarray
    placement: np.ndarray

    @staticmethod
    def of(tree: LoopTree) -> TreeTables:
        """The tables of ``tree.model``."""
        m = tree.model
        n = tree.nq
        parent = np.array([int(m.parents[j]) - 1 for j in range(1, m.njoints)], dtype=int)
        revolute = np.zeros(n, dtype=bool)
        axis = np.zeros((n, 3))
        placement = np.zeros((n, 4, 4))
        for j in range(1, m.njoints):
            data = m.joints[j].createData()
            m.joints[j].calc(data, np.zeros(1))
            s = np.asarray(data.S).reshape(6)
            revolute[j - 1] = bool(np.any(s[3:]))
            axis[j - 1] = s[3:] if revolute[j - 1] else s[:3]
            placement[j - 1] = m.jointPlacements[j].homogeneous
        return TreeTables(parent, revolute, axis, placement)


@dataclass(frozen=True, eq=False)
class TreePoses:
    """The tree at ``b`` configurations (K, SI units).

    Attributes:
        joint: Shape (b, n, 4, 4): ``oMi`` of each joint (after its motion).
        pre: Shape (b, n, 4, 4): ``X_j``, each joint's frame before its motion.
        columns: Shape (b, 6, n): spatial twist of each joint per unit of its value.
    """

    joint: np.ndarray
    pre: np.ndarray
    columns: np.ndarray
    _frames: dict = field(default_factory=dict, repr=False)

    def frame(self, tree: LoopTree, fid: int) -> np.ndarray:
        """Placements (b, 4, 4) of frame ``fid``."""
        key = (id(tree), fid)
        if key in self._frames:
            return self._frames[key]
        self._frames[key] = out = self._frame(tree, fid)
        return out

    def _frame(self, tree: LoopTree, fid: int) -> np.ndarray:
        f = tree.model.frames[fid]
        j = int(f.parentJoint)
        place = f.placement.homogeneous
        if j == 0:
            return np.broadcast_to(place, (self.joint.shape[0], 4, 4)).copy()
        return self.joint[:, j - 1] @ place


def forward(tables: TreeTables, q: np.ndarray) -> TreePoses:
    """Joint placements and spatial columns at configurations ``q`` (b, n) [rad or m]."""
    q = np.ascontiguousarray(q, dtype=float).reshape(-1, len(tables.parent))
    b, n = q.shape
    joint = np.empty((b, n, 4, 4))
    pre = np.empty((b, n, 4, 4))
    cols = np.empty((b, 6, n))
    kernel = tree_kernel()
    if kernel is not None:
        kernel.tree_forward(
            q, tables.parent, tables.revolute, tables.axis, tables.placement, joint, pre, cols
        )
        return TreePoses(joint, pre, cols)
    eye = np.eye(4)
    for j in range(n):
        p = tables.parent[j]
        base = tables.placement[j] if p < 0 else joint[:, p] @ tables.placement[j]
        if p < 0:
            base = np.broadcast_to(base, (b, 4, 4))
        pre[:, j] = base
        motion = np.broadcast_to(eye, (b, 4, 4)).copy()
        u = tables.axis[j]
        if tables.revolute[j]:
            s, c = np.sin(q[:, j]), np.cos(q[:, j])
            k = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
            motion[:, :3, :3] = eye[:3, :3] + s[:, None, None] * k + (1.0 - c)[:, None, None] * (k @ k)
        else:
            motion[:, :3, 3] = q[:, j, None] * u
        joint[:, j] = base @ motion
        r, t = joint[:, j, :3, :3], joint[:, j, :3, 3]
        w = r @ u
        if tables.revolute[j]:
            cols[:, 3:, j] = w
            cols[:, :3, j] = np.cross(t, w)
        else:
            cols[:, :3, j] = w
            cols[:, 3:, j] = 0.0
    return TreePoses(joint, pre, cols)


def adjoint(h: np.ndarray) -> np.ndarray:
    """``Ad(M)`` (b, 6, 6) of placements ``h`` (b, 4, 4): a twist ``[v; ω]`` in M's frame to K."""
    r, p = h[:, :3, :3], h[:, :3, 3]
    out = np.zeros((len(h), 6, 6))
    out[:, :3, :3] = r
    out[:, 3:, 3:] = r
    out[:, :3, 3:] = _skew(p) @ r
    return out


def adjoint_inverse(h: np.ndarray) -> np.ndarray:
    """``Ad(M⁻¹)`` (b, 6, 6): a spatial twist in K to M's frame (LOCAL)."""
    r, p = h[:, :3, :3], h[:, :3, 3]
    rt = np.swapaxes(r, 1, 2)
    out = np.zeros((len(h), 6, 6))
    out[:, :3, :3] = rt
    out[:, 3:, 3:] = rt
    out[:, :3, 3:] = -rt @ _skew(p)
    return out


def to_k_prime(p: np.ndarray, world: np.ndarray) -> np.ndarray:
    """Spatial twists (b, 6, k) as K' twists at points ``p`` (b, 3): ``v_p = v_O − p × ω``."""
    out = world.copy()
    w = world[:, 3:]
    out[:, :3] -= np.stack(
        [
            p[:, 1, None] * w[:, 2] - p[:, 2, None] * w[:, 1],
            p[:, 2, None] * w[:, 0] - p[:, 0, None] * w[:, 2],
            p[:, 0, None] * w[:, 1] - p[:, 1, None] * w[:, 0],
        ],
        axis=1,
    )
    return out


def point_rows(p: np.ndarray, world: np.ndarray) -> np.ndarray:
    """The velocity (b, 3, k) of points ``p`` (b, 3) moving with spatial twists ``world`` (b, 6, k)."""
    return to_k_prime(p, world)[:, :3]


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(len(v))
    x, y, w = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([z, -w, y, w, z, -x, -y, x, z], axis=1).reshape(-1, 3, 3)


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


def loop_rows(kind: str, ha: np.ndarray, hb: np.ndarray, va: np.ndarray, vb: np.ndarray) -> np.ndarray:
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
        c.append(loop_rows(lp.kind, ha, hb, poses.columns * sa, poses.columns * sb))
        d.append(loop_rows(lp.kind, ha, hb, raw * tree.moved_by(lp.frame_a), raw * tree.moved_by(lp.frame_b)))
    return np.concatenate(c, axis=1), np.concatenate(d, axis=1)
