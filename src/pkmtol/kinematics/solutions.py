"""The solutions of a batch of closed-chain problems (:class:`~pkmtol.kinematics.batch.BatchChain`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import KinematicsError
from pkmtol.kinematics.closed_chain import Pose

#: One array field of :class:`Solutions`, as a function of the solutions.
_Field = Callable[["Solutions"], np.ndarray]


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
        return self._built(lambda f: f(self)[index], [self.errors[int(k)] for k in index])

    def with_rows(self, index: np.ndarray, other: Solutions) -> Solutions:
        """These solutions with problems ``index`` replaced by ``other``'s (in that order)."""
        index = np.asarray(index, dtype=int)

        def put(f: _Field) -> np.ndarray:
            out = f(self).copy()
            out[index] = f(other)
            return out

        errors = list(self.errors)
        for pos, k in enumerate(index):
            errors[int(k)] = other.errors[pos]
        return self._built(put, errors)

    @staticmethod
    def scatter(parts: Sequence[Solutions], index: Sequence[np.ndarray], count: int) -> Solutions:
        """One batch of ``count`` problems: ``parts[p]``'s problems at positions ``index[p]``.

        Together the ``index`` arrays hold every position once (``concatenate(parts)`` taken in the
        inverse order of ``concatenate(index)``, with one copy instead of two).
        """
        where = [np.asarray(i, dtype=int) for i in index]

        def gather(f: _Field) -> np.ndarray:
            out = np.empty((count,) + f(parts[0]).shape[1:])
            for part, at in zip(parts, where, strict=True):
                out[at] = f(part)
            return out

        errors: list[KinematicsError | None] = [None] * count
        for part, at in zip(parts, where, strict=True):
            for pos, k in enumerate(at):
                errors[int(k)] = part.errors[pos]
        return parts[0]._built(gather, errors)

    @staticmethod
    def concatenate(parts: Sequence[Solutions]) -> Solutions:
        """One batch of the problems of ``parts``, in order."""
        return parts[0]._built(
            lambda f: np.concatenate([f(p) for p in parts]), [e for p in parts for e in p.errors]
        )

    def _built(
        self, arrays: Callable[[_Field], np.ndarray], errors: Sequence[KinematicsError | None]
    ) -> Solutions:
        """Solutions whose every array is ``arrays(field)``, with ``errors`` and these offsets and task."""
        return Solutions(
            q=arrays(lambda s: s.q),
            rotation=arrays(lambda s: s.rotation),
            translation=arrays(lambda s: s.translation),
            p_m=arrays(lambda s: s.p_m),
            residual=arrays(lambda s: s.residual),
            condition=arrays(lambda s: s.condition),
            jacobians=tuple(arrays(_jacobian(i)) for i in range(len(self.jacobians))),
            system=arrays(lambda s: s.system),
            system_inverse=arrays(lambda s: s.system_inverse),
            errors=tuple(errors),
            limb_offsets=self.limb_offsets,
            task=self.task,
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


def _jacobian(i: int) -> _Field:
    """Limb ``i``'s Jacobians of :class:`Solutions`, as a field."""
    return lambda s: s.jacobians[i]
