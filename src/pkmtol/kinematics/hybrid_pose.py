"""A solved pose of a hybrid machine, its task rows, and the same stacked over many poses.

:class:`HybridPose` is what :class:`~pkmtol.kinematics.hybrid.HybridChain` returns;
:func:`task_rows` the task residual and Jacobian at a TCP placement; :class:`StackedPoses` and the
stacked helpers are the working state of its batched Newton (one array per field, one row per
pose).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.kinematics.closed_chain import Pose

#: Largest Newton step on P [m] and on a wrist joint [rad or m] (keeps the assembly branch).
STEP_LIMIT_M = 0.2
STEP_LIMIT_JOINT = 0.6


@dataclass(frozen=True, eq=False)
class HybridPose:
    """A solved pose of the whole machine (frame K, SI units).

    Attributes:
        module: The parallel module's closed-chain pose (its ``p_m`` is the task point P).
        q_tool: Shape (nq_t,): the tool chain's joint values [rad or m].
        oMt: The TCP placement in K (its z axis is the tool axis).
        residual: Largest task residual at the solution [m, rad].
        condition: Condition number of the task Jacobian at the solution.
        twist_jacobian: Shape (6, 3 + w): the TCP twist ``[v; ω]`` (at the TCP, K's axes) per
            unit change of P [m] and of each actuated wrist joint [rad or m].
        tangent: Shape (N, 3): the module's ``∂q/∂P`` at its pose.
    """

    module: Pose
    q_tool: np.ndarray
    oMt: pin.SE3
    residual: float
    condition: float
    twist_jacobian: np.ndarray
    tangent: np.ndarray

    @property
    def tcp_m(self) -> np.ndarray:
        """Shape (3,): the TCP position in K [m]."""
        return np.asarray(self.oMt.translation, dtype=float).copy()

    @property
    def axis(self) -> np.ndarray:
        """Shape (3,): the tool axis in K (unit, from the spindle towards the tool tip)."""
        return np.asarray(self.oMt.rotation[:, 2], dtype=float).copy()

    @property
    def z(self) -> np.ndarray:
        """Shape (3 + w,): the unknowns: P [m] and the actuated wrist joints [rad or m]."""
        return np.concatenate([self.module.p_m, self.q_tool[list(self._act)]])

    @property
    def _act(self) -> tuple[int, ...]:
        return tuple(range(self.twist_jacobian.shape[1] - 3))


def task_rows(twist: np.ndarray, oMt: pin.SE3, target_m: np.ndarray, across: np.ndarray | None):
    """Task residual and Jacobian at a TCP placement: ``([tcp − t*; Q* a], [J_v; −Q*[a]× J_ω])``.

    Args:
        twist: Shape (6, k): TCP twist columns (K's axes).
        oMt: The TCP placement.
        target_m: Shape (3,): TCP target [m].
        across: Shape (2, 3): ``Q*`` for the target axis; None: the TCP position only.
    """
    r = oMt.translation - target_m
    if across is None:
        return r, twist[:3]
    a = oMt.rotation[:, 2]
    res = np.concatenate([r, across @ a])
    jac = np.vstack([twist[:3], -across @ pin.skew(a) @ twist[3:]])
    return res, jac


@dataclass(frozen=True, eq=False)
class StackedPoses:
    """The stacked state of ``HybridChain.inverse_many``: b poses, their TCPs and twist Jacobians."""

    p: np.ndarray  # (b, 3) module task points
    qm: np.ndarray  # (b, N) module joints
    qt: np.ndarray  # (b, nt) tool joints
    tangent: np.ndarray  # (b, N, 3)
    rot_p: np.ndarray  # (b, 3, 3) platform
    pos_p: np.ndarray  # (b, 3)
    rot: np.ndarray  # (b, 3, 3) TCP
    pos: np.ndarray  # (b, 3)
    twist: np.ndarray  # (b, 6, 3 + w)
    residual: np.ndarray  # (b,) module residual
    condition: np.ndarray  # (b,) module condition bound
    offsets: tuple[int, ...]

    @staticmethod
    def of(poses: list[HybridPose]) -> StackedPoses:
        """Solved poses stacked."""
        return StackedPoses(
            p=np.array([h.module.p_m for h in poses]),
            qm=np.array([h.module.q_all for h in poses]),
            qt=np.array([h.q_tool for h in poses]),
            tangent=np.array([h.tangent for h in poses]),
            rot_p=np.array([h.module.oMp.rotation for h in poses]),
            pos_p=np.array([h.module.oMp.translation for h in poses]),
            rot=np.array([h.oMt.rotation for h in poses]),
            pos=np.array([h.oMt.translation for h in poses]),
            twist=np.array([h.twist_jacobian for h in poses]),
            residual=np.array([h.module.residual for h in poses]),
            condition=np.array([h.module.condition for h in poses]),
            offsets=tuple(int(x) for x in np.cumsum([0] + [len(q) for q in poses[0].module.q])),
        )

    @staticmethod
    def from_solutions(sols, idx, qt, rt, pt, jt, act, nq0) -> StackedPoses:  # noqa: ANN001 - internal
        """Module solutions ``idx`` of ``sols`` with tool joints ``qt`` and their frames (rt, pt, jt)."""
        rp, tp = sols.rotation[idx], sols.translation[idx]
        tangent = sols.system_inverse[idx][:, :, -3:]
        plat = sols.jacobians[0][idx] @ tangent[:, :nq0]  # (b, 6, 3) platform twist (its frame) per ΔP
        v, w = plat[:, :3], plat[:, 3:]
        twist = np.empty((len(idx), 6, 3 + len(act)))
        twist[:, :3, :3] = rp @ (v + cross_columns(w, pt))
        twist[:, 3:, :3] = rp @ w
        rot = rp @ rt
        twist[:, :3, 3:] = rot @ jt[:, :3][:, :, act]
        twist[:, 3:, 3:] = rot @ jt[:, 3:][:, :, act]
        return StackedPoses(
            p=sols.p_m[idx],
            qm=sols.q[idx],
            qt=qt,
            tangent=tangent,
            rot_p=rp,
            pos_p=tp,
            rot=rot,
            pos=tp + np.einsum("bij,bj->bi", rp, pt),
            twist=twist,
            residual=sols.residual[idx],
            condition=sols.condition[idx],
            offsets=tuple(int(x) for x in sols.limb_offsets),
        )

    def take(self, mask: np.ndarray) -> StackedPoses:
        """The rows ``mask`` (boolean or indices)."""
        return StackedPoses(**{f: getattr(self, f)[mask] for f in _FIELDS}, offsets=self.offsets)

    def pose(self, k: int, residual: float = 0.0, condition: float = 0.0) -> HybridPose:
        """Row ``k`` as a :class:`HybridPose` (its arrays are views of this stack's)."""
        o = self.offsets
        qk = self.qm[k]
        module = Pose(
            q=tuple(qk[a:c] for a, c in zip(o[:-1], o[1:], strict=True)),
            oMp=pin.SE3(self.rot_p[k], self.pos_p[k]),
            p_m=self.p[k],
            residual=float(self.residual[k]),
            condition=float(self.condition[k]),
            tangent=self.tangent[k],
        )
        oMt = pin.SE3(self.rot[k], self.pos[k])
        return HybridPose(module, self.qt[k], oMt, residual, condition, self.twist[k], self.tangent[k])


_FIELDS = ("p", "qm", "qt", "tangent", "rot_p", "pos_p", "rot", "pos", "twist", "residual", "condition")


def task_rows_many(twist, rot, pos, targets, across):  # noqa: ANN001, ANN202 - internal
    """:func:`task_rows` stacked: residuals (b, rows) and Jacobians (b, rows, 3 + w)."""
    r = pos - targets
    if across is None:
        return r, twist[:, :3]
    a = rot[:, :, 2]
    res = np.concatenate([r, np.einsum("bij,bj->bi", across, a)], axis=1)
    axw = -cross_columns(twist[:, 3:], a)  # a × ω per column
    jac = np.concatenate([twist[:, :3], -np.einsum("bij,bjk->bik", across, axw)], axis=1)
    return res, jac


def cross_columns(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m[:, :, k] × v`` for every column k: ``m`` (b, 3, k), ``v`` (b, 3) → (b, 3, k)."""
    x, y, z = m[:, 0], m[:, 1], m[:, 2]
    vx, vy, vz = v[:, 0, None], v[:, 1, None], v[:, 2, None]
    return np.stack([y * vz - z * vy, z * vx - x * vz, x * vy - y * vx], axis=1)


def exp3_many(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices (b, 3, 3) of rotation vectors (b, 3) [rad] (Rodrigues)."""
    angle = np.sqrt((theta * theta).sum(axis=1))
    k = np.zeros((len(theta), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -theta[:, 2], theta[:, 1], -theta[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = theta[:, 2], -theta[:, 1], theta[:, 0]
    small = angle < 1e-8
    a = np.where(small, 1.0 - angle**2 / 6, np.sin(angle) / np.where(small, 1.0, angle))
    b = np.where(small, 0.5 - angle**2 / 24, (1.0 - np.cos(angle)) / np.where(small, 1.0, angle) ** 2)
    return np.eye(3) + a[:, None, None] * k + b[:, None, None] * (k @ k)


def solve_many(a: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Stacked square solves ``a x = rhs`` (least squares where a system is singular)."""
    try:
        return np.linalg.solve(a, rhs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        return np.array([np.linalg.lstsq(m, r, rcond=None)[0] for m, r in zip(a, rhs, strict=True)])


def limited_many(step: np.ndarray) -> np.ndarray:
    """Newton steps (b, 3 + w) scaled down to :data:`STEP_LIMIT_M` on P and :data:`STEP_LIMIT_JOINT`."""
    big = np.abs(step[:, :3]).max(axis=1) / STEP_LIMIT_M
    if step.shape[1] > 3:
        big = np.maximum(big, np.abs(step[:, 3:]).max(axis=1) / STEP_LIMIT_JOINT)
    return step / np.maximum(big, 1.0)[:, None]
