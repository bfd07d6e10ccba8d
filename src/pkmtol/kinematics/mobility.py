"""Mobility and actuation of a mechanism, counted before its home pose is solved with the actuators held.

The home solve holds the actuated joints and solves the passive ones; with too few actuators (or
badly placed ones) it has more unknowns than independent equations, and it fails with a
misleading message (the platform frames "cannot coincide", a "singular configuration").
:func:`count_mobility` (``ClosedChain.mobility``) counts instead, on the closure equations alone:

1. the configuration is closed near ``home`` with *every* joint free (least-norm Gauss–Newton;
   no joint is held, so a wrong actuation cannot stop it);
2. the mobility is ``f = n − rank C`` with ``C`` the closure Jacobian there (shape
   ``(6(L−1) + loop rows, n)``); ranks are numerical (singular values above
   :data:`RANK_TOLERANCE` times the largest), as in ``pkmtol check``;
3. the actuators determine the pose when they are ``f`` joints and, with them held, the passive
   columns of ``C`` keep its rank (no passive motion is left).

The rank at a closed configuration counts over-constrained mechanisms right (the seed robot:
21 joints, rank 18, f = 3); a random open configuration would not.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

#: A singular value counts towards a rank above this fraction of the largest one.
RANK_TOLERANCE = 1e-9
#: Closure residual [m or rad] at which the configuration counts as closed.
CLOSURE_TOLERANCE = 1e-11
#: Gauss–Newton iterations allowed for the closure near home.
MAX_ITERATIONS = 30
#: Joints named as candidates to actuate, at most.
MAX_CANDIDATES = 6


@dataclass(frozen=True)
class Mobility:
    """The mobility of a mechanism and what its actuators leave free, near ``home``.

    Attributes:
        n_joints: Joints of all limbs.
        closure_rank: Rank of the closure Jacobian at the closed configuration.
        actuated: Actuated joints as ``<limb>.<joint>``, in limb order.
        free_motions: Passive motions left with the actuators held (``passive − rank`` of the
            closure Jacobian's passive columns).
        candidates: Passive joints (``<limb>.<joint>``) of limbs without an actuator whose
            actuation would remove a free motion.
        task_dof: Degrees of freedom of the task (3 for the position of P, 2 planar; None for a
            hybrid's tool task, whose wrist adds its own).
        closed: Whether the closure converged near home (if not, nothing is claimed: the home
            check names the gap).
        closure_residual: Largest closure residual reached [m or rad].
    """

    n_joints: int
    closure_rank: int
    actuated: tuple[str, ...]
    free_motions: int
    candidates: tuple[str, ...]
    task_dof: int | None
    closed: bool
    closure_residual: float

    @property
    def mobility(self) -> int:
        """Mobility ``f = n − rank C`` (0 when the closure did not converge)."""
        return self.n_joints - self.closure_rank if self.closed else 0

    @property
    def n_actuators(self) -> int:
        """Number of actuated joints."""
        return len(self.actuated)

    @property
    def problems(self) -> tuple[str, ...]:
        """What stops the actuators from determining the pose (empty when all is well or not closed)."""
        if not self.closed:
            return ()
        f, n_act = self.mobility, self.n_actuators
        out = []
        if self.task_dof is not None and f < self.task_dof:
            out.append(
                f"the mechanism has mobility {f} ({self.n_joints} joints − rank {self.closure_rank} of "
                f"the closure Jacobian), fewer than the task's {self.task_dof} degrees of freedom: it "
                "cannot move P over the task space; check the joint types and axes of the limbs"
            )
        given = f"{n_act} given ({', '.join(self.actuated) or 'none'})"
        if n_act < f:
            out.append(
                f"too few actuators: mobility {f} ({self.n_joints} joints − rank {self.closure_rank} "
                f"of the closure Jacobian) needs {f} actuated joints, {given}; actuate "
                f"{f - n_act} more joint{'s' if f - n_act > 1 else ''} ('actuated' of a limb in "
                "mechanism.toml)" + self._suggest()
            )
        elif n_act > f:
            out.append(
                f"too many actuators: mobility {f} ({self.n_joints} joints − rank {self.closure_rank} "
                f"of the closure Jacobian) needs {f} actuated joints, {given}: they fight each other; "
                f"make {n_act - f} of them passive"
            )
        elif self.free_motions:
            out.append(
                f"the {n_act} actuators do not determine the pose: with them held, the passive joints "
                f"still move ({self.free_motions} free motion{'s' if self.free_motions > 1 else ''}); "
                "actuate other joints" + self._suggest()
            )
        return tuple(out)

    def _suggest(self) -> str:
        if not self.candidates:
            return ""
        more = ", …" if len(self.candidates) == MAX_CANDIDATES else ""
        return f", e.g. one of {', '.join(self.candidates)}{more}"


def count_mobility(
    evaluate: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    q_home: np.ndarray,
    names: Sequence[str],
    actuated: Sequence[int],
    task_dof: int | None,
) -> Mobility:
    """Count the mobility of a closed chain and what its actuators leave free, near ``q_home``.

    Cheap (a few Jacobians of the closure equations); it holds no joint, so it runs where the
    home solve with the actuators held cannot. ``ClosedChain.mobility`` calls it for a mechanism.

    Args:
        evaluate: ``q ↦ (residual, Jacobian)`` of the closure equations, shapes (m,), (m, n).
        q_home: The home joint values (n,) [rad or m].
        names: ``<limb>.<joint>`` per joint (n).
        actuated: Indices of the actuated joints into q.
        task_dof: The task's degrees of freedom (None: not compared).

    Returns:
        The counts; :attr:`Mobility.problems` says what is wrong, in words.
    """
    q = np.array(q_home, dtype=float)
    residual = np.inf
    for _ in range(MAX_ITERATIONS):
        res, jac = evaluate(q)
        if not (np.isfinite(res).all() and np.isfinite(jac).all()):
            break
        residual = float(np.max(np.abs(res))) if res.size else 0.0
        if residual < CLOSURE_TOLERANCE:
            break
        step = np.linalg.lstsq(jac, res, rcond=None)[0]  # least norm: every joint free
        q = q - step / max(1.0, float(np.max(np.abs(step))) / 0.5)
    closed = residual < CLOSURE_TOLERANCE
    jac = np.array(evaluate(q)[1]) if closed else np.zeros((0, q.size))
    act = [int(k) for k in actuated]
    passive = [k for k in range(q.size) if k not in act]
    passive_rank = _rank(jac[:, passive]) if closed else len(passive)
    driven = {n.split(".", 1)[0] for n in (names[k] for k in act)}  # a limb takes one actuator
    candidates: list[str] = []
    if closed and len(passive) > passive_rank:
        for k in passive:
            if names[k].split(".", 1)[0] in driven:
                continue
            rest = [p for p in passive if p != k]
            if _rank(jac[:, rest]) == passive_rank:  # actuating k removes a free motion
                candidates.append(names[k])
                if len(candidates) == MAX_CANDIDATES:
                    break
    return Mobility(
        n_joints=q.size,
        closure_rank=_rank(jac),
        actuated=tuple(names[k] for k in act),
        free_motions=len(passive) - passive_rank,
        candidates=tuple(candidates),
        task_dof=task_dof,
        closed=closed,
        closure_residual=residual,
    )


def _rank(matrix: np.ndarray) -> int:
    if matrix.size == 0:
        return 0
    s = np.linalg.svd(matrix, compute_uv=False)
    return int(np.sum(s > RANK_TOLERANCE * s[0])) if s[0] > 0 else 0
