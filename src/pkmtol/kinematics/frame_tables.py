"""A mechanism's limbs as flat joint and frame tables: the compiled forward kinematics' input.

The compiled kernels (:mod:`pkmtol.kinematics.jit_kernels`, the ``fast`` extra) compute the frames
the batched solver needs, pose by pose, without a call into Pinocchio per limb and pose: Pinocchio's
Python API costs about 1.8 µs a call, four calls a limb per Newton evaluation, more than the
arithmetic itself. Every pkmtol joint is a 1-DOF revolute or prismatic joint
(:func:`pkmtol.model.limb.make_limb` checks it), so the tables are small: each joint's parent,
type, axis and placement, in the order of the mechanism's ``q`` (limb after limb), and each frame
of interest's parent joint, placement and supporting joints. The tables are read from the limbs'
Pinocchio models, and the kernel agrees with Pinocchio's ``updateFramePlacement`` and
``getFrameJacobian(…, LOCAL)`` to round-off (``tests/test_jit_kernels.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType

import numpy as np
import pinocchio as pin


@dataclass(frozen=True, eq=False)
class FrameTables:
    """Joint and frame tables of several limb models (``n`` joints in all, ``F`` frames).

    Attributes:
        parent: Shape (n,): each joint's parent joint (−1: the common root K).
        revolute: Shape (n,): True for a revolute joint, False for a prismatic one.
        axis: Shape (n, 3): unit joint axes in the joint frames.
        placements: Shape (1, n, 4, 4): the models' joint placements in their parents.
        f_joint: Shape (F,): each frame's parent joint (−1: the root K).
        f_place: Shape (F, 4, 4): each frame's placement in its parent joint.
        f_start: Shape (F,): the first joint of each frame's limb.
        f_support: Shape (F, w): the joints of its limb that move each frame (``w`` the widest limb).
    """

    parent: np.ndarray
    revolute: np.ndarray
    axis: np.ndarray
    placements: np.ndarray
    f_joint: np.ndarray
    f_place: np.ndarray
    f_start: np.ndarray
    f_support: np.ndarray

    @staticmethod
    def of(models: Sequence[pin.Model], frames: Sequence[tuple[int, int]]) -> FrameTables:
        """The tables of ``models`` (one per limb, ``q`` concatenated in this order) and of frames.

        Args:
            models: The limbs' models; every joint is 1-DOF revolute or prismatic.
            frames: The frames to evaluate, in order: ``(model index, frame id)``.
        """
        offsets = np.concatenate([[0], np.cumsum([int(m.nq) for m in models])]).astype(np.int64)
        n = int(offsets[-1])
        parent = np.full(n, -1, dtype=np.int64)
        revolute = np.zeros(n, dtype=np.bool_)
        axis = np.zeros((n, 3))
        placements = np.zeros((1, n, 4, 4))
        for i, model in enumerate(models):
            for j in range(1, model.njoints):
                g = int(offsets[i]) + j - 1
                data = model.joints[j].createData()
                model.joints[j].calc(data, np.zeros(1))
                s = np.asarray(data.S).reshape(6)
                revolute[g] = bool(np.any(s[3:]))
                axis[g] = s[3:] if revolute[g] else s[:3]
                if model.parents[j] > 0:
                    parent[g] = int(offsets[i]) + model.parents[j] - 1
                placements[0, g] = model.jointPlacements[j].homogeneous
        width = max(int(m.nq) for m in models)
        f_joint, f_place, f_start, f_support = [], [], [], []
        for i, fid in frames:
            model = models[i]
            frame = model.frames[fid]
            support = np.zeros(width, dtype=np.bool_)
            j = int(frame.parentJoint)
            f_joint.append(int(offsets[i]) + j - 1 if j > 0 else -1)
            while j > 0:
                support[j - 1] = True
                j = model.parents[j]
            f_place.append(frame.placement.homogeneous)
            f_start.append(int(offsets[i]))
            f_support.append(support)
        return FrameTables(
            parent=parent,
            revolute=revolute,
            axis=axis,
            placements=placements,
            f_joint=np.array(f_joint, dtype=np.int64),
            f_place=np.array(f_place).reshape(-1, 4, 4),
            f_start=np.array(f_start, dtype=np.int64),
            f_support=np.array(f_support, dtype=np.bool_).reshape(-1, width),
        )

    @property
    def width(self) -> int:
        """Columns of the widest limb's Jacobian."""
        return int(self.f_support.shape[1])

    def perturbed(self, kernels: ModuleType, eps: np.ndarray) -> np.ndarray:
        """Joint placements ``placement_j · exp6(ε_j)`` of ``c`` machines, shape (c, n, 4, 4).

        Args:
            kernels: The compiled kernels.
            eps: Shape (c, n, 6): each machine's joint placement errors ``[v; ω]`` [m, rad].
        """
        eps = np.ascontiguousarray(eps, dtype=float)
        out = np.empty((len(eps), len(self.parent), 4, 4))
        kernels.perturbed_placements(self.placements[0], eps, out)
        return out

    def evaluate(
        self, kernels: ModuleType, q: np.ndarray, rows: np.ndarray, table: np.ndarray, which: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The frames' placements (F, b, 4, 4) and LOCAL Jacobians (F, b, 6, w) for problems ``rows``.

        Args:
            kernels: The compiled kernels.
            q: Shape (B, n): every problem's joint values [rad or m].
            rows: Shape (b,): the problems to evaluate.
            table: Shape (M, n, 4, 4): joint placements per machine (:attr:`placements`, or
                :meth:`perturbed`).
            which: Shape (B,): each problem's row of ``table``.
        """
        b, f = len(rows), len(self.f_joint)
        h = np.empty((f, b, 4, 4))
        jac = np.zeros((f, b, 6, self.width))
        kernels.frames(
            q,
            np.asarray(rows, dtype=np.int64),
            table,
            which,
            self.parent,
            self.revolute,
            self.axis,
            self.f_joint,
            self.f_place,
            self.f_start,
            self.f_support,
            h,
            jac,
        )
        return h, jac
