"""The tool chain's own kinematics: TCP placement, frame Jacobian and perturbed models (Pinocchio).

The chain is rooted on the platform link, so its placements are relative to the platform frame
(``pMt``: platform → TCP). Its geometric errors enter as for the limbs (DESIGN.md, "Geometric
error parameters"): joint placements ``jointPlacements[j] · exp6(ε_j)``, the TCP frame's
placement (everything from the last joint to the tool tip: spindle, nose, tool) ``· exp6(ε_t)``,
and joint zero offsets ``q_actual = q + δq``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from pkmtol.model.tool import Tool


def tool_frames(tool: Tool, model: pin.Model, data: pin.Data, q: np.ndarray) -> tuple[pin.SE3, np.ndarray]:
    """The TCP placement in the platform frame and its frame Jacobian.

    Args:
        tool: The tool chain.
        model: Its model (nominal or perturbed).
        data: A ``Data`` of ``model`` (overwritten).
        q: Actual joint values (nq,) [rad or m].

    Returns:
        ``(pMt, J)``: the TCP placement relative to the platform frame, and its LOCAL frame
        Jacobian (6, nq) (the TCP twist in the TCP frame per unit joint rate).
    """
    pin.computeJointJacobians(model, data, q)
    placement = pin.updateFramePlacement(model, data, tool.tcp_frame)
    return placement.copy(), pin.getFrameJacobian(model, data, tool.tcp_frame, pin.LOCAL)


def tcp_placement(tool: Tool, model: pin.Model, data: pin.Data, q: np.ndarray) -> pin.SE3:
    """The TCP placement relative to the platform frame at actual joint values ``q`` (nq,)."""
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[tool.tcp_frame].copy()


def tool_regressor(tool: Tool, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """Raw error columns of the chain at the TCP, LOCAL (TCP frame), shape (6, 6·nq + 6 + nq).

    Columns: the ``6·nq`` joint-placement errors (Pinocchio's kinematic regressor), the 6 of
    the TCP frame's placement (the identity: ``oMt · exp6(ε_t)``), the ``nq`` zero offsets
    (the frame Jacobian).
    """
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    reg = pin.computeFrameKinematicRegressor(model, data, tool.tcp_frame, pin.LOCAL)
    jac = pin.getFrameJacobian(model, data, tool.tcp_frame, pin.LOCAL)
    return np.hstack([reg, np.eye(6), jac])


def perturbed_tool_model(tool: Tool, eps: np.ndarray) -> pin.Model:
    """The chain's model with placement errors ``eps`` (nq + 1, 6): joints, then the TCP frame.

    Joint ``j``'s placement becomes ``jointPlacements[j] · exp6(ε_j)``; the TCP frame's
    ``placement · exp6(ε_t)``. Zero offsets are added to ``q`` by the caller.
    """
    e = np.asarray(eps, dtype=float).reshape(tool.nq + 1, 6)
    model = tool.model.copy()
    for j in range(tool.nq):
        model.jointPlacements[j + 1] = model.jointPlacements[j + 1] * pin.exp6(pin.Motion(e[j]))
    f = model.frames[tool.tcp_frame]
    f.placement = f.placement * pin.exp6(pin.Motion(e[tool.nq]))
    model.frames[tool.tcp_frame] = f
    return model


def world_axes(rotation: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Twist columns (6, k) in a frame of orientation ``rotation`` to the same point with K's axes."""
    return np.vstack([rotation @ local[:3], rotation @ local[3:]])


def orthonormal_across(axis: np.ndarray) -> np.ndarray:
    """Shape (2, 3): two orthonormal rows across the unit vector ``axis`` (a right-handed pair)."""
    a = np.asarray(axis, dtype=float)
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    return np.array([u, np.cross(a, u)])


def across_many(axes: np.ndarray) -> np.ndarray:
    """:func:`orthonormal_across` of unit vectors (b, 3): shape (b, 2, 3) (the same rows)."""
    a = np.asarray(axes, dtype=float).reshape(-1, 3)
    helper = np.eye(3)[np.argmin(np.abs(a), axis=1)]
    u = _cross(a, helper)
    u /= np.sqrt((u * u).sum(axis=1))[:, None]
    return np.stack([u, _cross(a, u)], axis=1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (b, 3) arrays."""
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def tool_joint_limits(tool: Tool, model: pin.Model | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits (nq,) of the chain's joints [rad or m]."""
    m = tool.model if model is None else model
    return np.asarray(m.lowerPositionLimit, dtype=float), np.asarray(m.upperPositionLimit, dtype=float)


def split_tool_eps(raw: Sequence[float] | np.ndarray, tool: Tool) -> tuple[np.ndarray, np.ndarray]:
    """Raw tool errors (6·nq + 6 + nq,) to ``(eps (nq + 1, 6), offsets (nq,))``."""
    r = np.asarray(raw, dtype=float)
    n = 6 * (tool.nq + 1)
    return r[:n].reshape(tool.nq + 1, 6), r[n:]


class ToolKinematics:
    """The chain's TCP placement and LOCAL frame Jacobian for many joint vectors at once (numpy).

    The same numbers as :func:`tool_frames` (tested): each 1-DOF joint moves by ``exp6(S_j q_j)``
    (its constant motion subspace ``S_j`` in the joint frame: a rotation about, or a translation
    along, its axis), so the chain is a product of constant placements and joint motions; the
    Jacobian's column ``j`` is ``Ad(tMj) S_j``.

    Args:
        tool: The tool chain.
        model: Its model (default: the nominal one; a perturbed model of the same structure).
    """

    def __init__(self, tool: Tool, model: pin.Model | None = None) -> None:
        m = tool.model if model is None else model
        self.nq = tool.nq
        self.placements = [
            (np.asarray(m.jointPlacements[j].rotation), np.asarray(m.jointPlacements[j].translation))
            for j in range(1, m.njoints)
        ]
        subspaces = []
        for j in range(1, m.njoints):
            jd = m.joints[j].createData()
            m.joints[j].calc(jd, np.zeros(1))
            subspaces.append(np.asarray(jd.S).reshape(6))
        self.subspaces = np.array(subspaces).reshape(-1, 6)
        f = m.frames[tool.tcp_frame]
        self.tcp = (np.asarray(f.placement.rotation), np.asarray(f.placement.translation))

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(R (b, 3, 3), p (b, 3), J (b, 6, nq))``: pMt and its LOCAL Jacobian at joints ``q`` (b, nq)."""
        q = np.asarray(q, dtype=float).reshape(-1, self.nq)
        b = len(q)
        rot = np.tile(np.eye(3), (b, 1, 1))
        pos = np.zeros((b, 3))
        joints = []  # placement of each joint frame (after its motion) in the platform frame
        for j, (mr, mp) in enumerate(self.placements):
            pos = pos + rot @ mp
            rot = rot @ mr
            s = self.subspaces[j]
            if np.any(s[3:]):
                rot = rot @ _rodrigues(s[3:], q[:, j])
            else:
                pos = pos + (rot @ s[:3]) * q[:, j, None]
            joints.append((rot, pos))
        tr, tp = self.tcp
        pos_t = pos + rot @ tp
        rot_t = rot @ tr
        jac = np.empty((b, 6, self.nq))
        rt_t = np.swapaxes(rot_t, 1, 2)
        for j, (rj, pj) in enumerate(joints):
            s = self.subspaces[j]
            # tMj: rotation Rtᵀ Rj, translation Rtᵀ (pj − pt); Ad(tMj) [v; ω] = [R v + p × R ω; R ω]
            r = rt_t @ rj
            p = np.einsum("bij,bj->bi", rt_t, pj - pos_t)
            w = r @ s[3:]
            v = r @ s[:3] + np.cross(p, w)
            jac[:, :3, j], jac[:, 3:, j] = v, w
        return rot_t, pos_t, jac


def _rodrigues(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (b, 3, 3) by ``angle`` (b,) [rad] about the unit ``axis`` (3,)."""
    k = pin.skew(np.asarray(axis, dtype=float))
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)
