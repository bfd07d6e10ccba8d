"""The solutions of a batch of closed-chain problems (:class:`~pkmtol.kinematics.batch.BatchChain`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import KinematicsError
from pkmtol.kinematics.closed_chain import Pose


@dataclass(frozen=True, eq=False)
class Solutions:
    """Solutions of ``B`` closed-chain problems (``N = Σ nq_i`` joints, frame K, SI units).

    Rows of a failed problem hold its last iterate; ``errors[k]`` says why it failed.

    Attributes:
        q: Shape (B, N): all joint values (actual values: offsets included) [rad or m].
        rotation: Shape (B, 3, 3): platform orientation in K (limb 0's platform frame).
        translation: Shape (B, 3): position of the platform point O' in K [m].
        p_m: Shape (B, 3): position of the reference point P in K [m].
        residual: Shape (B,): norm of the closure (+ task) residual [m, rad].
        condition: Shape (B,): upper bound ``κ_F`` of the Jacobian's 2-norm condition number.
        jacobians: Per limb, shape (B, 6, nq_i): platform-frame (local) Jacobian at the solution.
        system: Shape (B, rows, free): the closure (+ task) Jacobian at the solution.
        system_inverse: Shape (B, free, rows): its inverse (pseudo-inverse if over-determined).
        errors: Per problem, None or the :class:`KinematicsError` the per-pose solver raises.
        limb_offsets: Where each limb's joints start in ``q`` (len(limbs) + 1 entries).
        task: Whether these are inverse problems (their last three rows are the task of P).
    """

    q: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    p_m: np.ndarray
    residual: np.ndarray
    condition: np.ndarray
    jacobians: tuple[np.ndarray, ...]
    system: np.ndarray
    system_inverse: np.ndarray
    errors: tuple[KinematicsError | None, ...]
    limb_offsets: tuple[int, ...]
    task: bool = False

    def __len__(self) -> int:
        return len(self.errors)

    @property
    def ok(self) -> np.ndarray:
        """Shape (B,): True where the problem was solved."""
        return np.array([e is None for e in self.errors], dtype=bool)

    def take(self, index: np.ndarray) -> Solutions:
        """The problems ``index`` (in that order) as a batch of their own."""
        index = np.asarray(index, dtype=int)
        return Solutions(
            q=self.q[index],
            rotation=self.rotation[index],
            translation=self.translation[index],
            p_m=self.p_m[index],
            residual=self.residual[index],
            condition=self.condition[index],
            jacobians=tuple(j[index] for j in self.jacobians),
            system=self.system[index],
            system_inverse=self.system_inverse[index],
            errors=tuple(self.errors[int(k)] for k in index),
            limb_offsets=self.limb_offsets,
            task=self.task,
        )

    def with_rows(self, index: np.ndarray, other: Solutions) -> Solutions:
        """These solutions with problems ``index`` replaced by ``other``'s (in that order)."""
        index = np.asarray(index, dtype=int)

        def put(mine: np.ndarray, theirs: np.ndarray) -> np.ndarray:
            out = mine.copy()
            out[index] = theirs
            return out

        errors = list(self.errors)
        for pos, k in enumerate(index):
            errors[int(k)] = other.errors[pos]
        return Solutions(
            q=put(self.q, other.q),
            rotation=put(self.rotation, other.rotation),
            translation=put(self.translation, other.translation),
            p_m=put(self.p_m, other.p_m),
            residual=put(self.residual, other.residual),
            condition=put(self.condition, other.condition),
            jacobians=tuple(put(a, b) for a, b in zip(self.jacobians, other.jacobians, strict=True)),
            system=put(self.system, other.system),
            system_inverse=put(self.system_inverse, other.system_inverse),
            errors=tuple(errors),
            limb_offsets=self.limb_offsets,
            task=self.task,
        )

    @staticmethod
    def concatenate(parts: Sequence[Solutions]) -> Solutions:
        """One batch of the problems of ``parts``, in order."""
        return Solutions(
            q=np.concatenate([p.q for p in parts]),
            rotation=np.concatenate([p.rotation for p in parts]),
            translation=np.concatenate([p.translation for p in parts]),
            p_m=np.concatenate([p.p_m for p in parts]),
            residual=np.concatenate([p.residual for p in parts]),
            condition=np.concatenate([p.condition for p in parts]),
            jacobians=tuple(np.concatenate(js) for js in zip(*(p.jacobians for p in parts), strict=True)),
            system=np.concatenate([p.system for p in parts]),
            system_inverse=np.concatenate([p.system_inverse for p in parts]),
            errors=tuple(e for p in parts for e in p.errors),
            limb_offsets=parts[0].limb_offsets,
            task=parts[0].task,
        )

    def first_error(self) -> KinematicsError | None:
        """The error of the first failed problem (in problem order), or None."""
        return next((e for e in self.errors if e is not None), None)

    def pose(self, k: int) -> Pose:
        """Problem ``k`` as a :class:`Pose` (``q`` split per limb); raises its error if it failed."""
        err = self.errors[k]
        if err is not None:
            raise err
        q, o = self.q[k], self.limb_offsets
        return Pose(
            q=tuple(q[a:b].copy() for a, b in zip(o[:-1], o[1:], strict=True)),
            oMp=pin.SE3(self.rotation[k].copy(), self.translation[k].copy()),
            p_m=self.p_m[k].copy(),
            residual=float(self.residual[k]),
            condition=float(self.condition[k]),
            tangent=self.system_inverse[k][:, -3:].copy() if self.task else None,
        )
