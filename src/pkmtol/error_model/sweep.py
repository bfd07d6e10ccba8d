"""The error model over many poses: inverse kinematics along a point list, separation at each."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

import pkmtol.values as values
from pkmtol.error_model.parameters import ParameterSet, check_set
from pkmtol.error_model.separation import Separation, separate_many
from pkmtol.exceptions import InvalidArgumentError, KinematicsError
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.kinematics.continuation import continuation
from pkmtol.model.mechanism import Mechanism

#: Relative size of a projection below which it counts as zero (classification).
ZERO_TOLERANCE = 1e-9

CLASSES = ("absorbed", "compensatable", "uncompensatable")
#: Poses solved together (bounds the solver's working memory).
CHUNK = 512


@dataclass(frozen=True, eq=False)
class Sweep:
    """Separations at a list of points of P.

    Attributes:
        points_m: Shape (m, 3): positions of P in K [m].
        poses: The closed-chain poses.
        separations: The separation at each pose.
        J: Shape (m, 3, n): compensated map to P's position error at each point.
        J_total: Shape (m, 3, n): uncompensated map to P's position error at each point.
        W_condition: Shape (m,): condition number of W at each point.
    """

    points_m: np.ndarray
    poses: tuple[Pose, ...]
    separations: tuple[Separation, ...]
    J: np.ndarray
    J_total: np.ndarray
    W_condition: np.ndarray

    @property
    def redundancy(self) -> int:
        """Largest number of linearly dependent wrenches over the points (0: not over-constrained)."""
        return max((s.redundancy for s in self.separations), default=0)

    def incompatible(self) -> np.ndarray:
        """Per parameter: whether it has an incompatible part (an assembly error) at some point.

        Only over-constrained mechanisms have one: the part of the parameter's wrench rows that no
        rigid platform motion satisfies (``Separation.incompatible_map``), relative as in
        :meth:`classify`.
        """
        return self._max_relative(lambda s: s.incompatible_map if s.redundancy else None) > ZERO_TOLERANCE

    def classify(self) -> list[str]:
        """Class of each parameter: ``absorbed``, ``compensatable`` or ``uncompensatable``.

        Uncompensatable: a constraint wrench of its limb sees it (``G_c`` column ≠ 0) at some
        point. Compensatable: otherwise, an actuation wrench sees it (``G_a`` or ``Λ_a``).
        Absorbed: neither, at every point — its error twist lies in its limb's passive-joint span.
        """
        ya = self._max_relative(lambda s: s.Y_a)
        yc = self._max_relative(lambda s: s.Y_c)
        return [
            "uncompensatable" if c > ZERO_TOLERANCE else "compensatable" if a > ZERO_TOLERANCE else "absorbed"
            for a, c in zip(ya, yc, strict=True)
        ]

    def _max_relative(self, rows: Callable[[Separation], np.ndarray | None]) -> np.ndarray:
        """Per parameter, the largest ``|row entry| / max(1, ‖error column‖)`` over the points."""
        out = np.zeros(self.J.shape[2])
        for s in self.separations:
            m = rows(s)
            if m is None or not m.size:
                continue
            scale = np.maximum(1.0, np.linalg.norm(s.error_columns, axis=0))
            out = np.maximum(out, np.abs(m).max(axis=0) / scale)
        return out


def check_chain(chain: object, mechanism: Mechanism) -> None:
    """InvalidArgumentError unless ``chain`` is None or a ClosedChain of ``mechanism``'s limbs."""
    if chain is None:
        return
    values.instance("chain", chain, ClosedChain, "a ClosedChain of the mechanism, or None")
    assert isinstance(chain, ClosedChain)
    if [m.nq for m in chain.models] != [lb.nq for lb in mechanism.limbs]:
        raise InvalidArgumentError(
            "chain", chain.mechanism.name, f"solves another mechanism than '{mechanism.name}'"
        )


def sweep(
    mechanism: Mechanism,
    pset: ParameterSet,
    points_m: np.ndarray,
    chain: ClosedChain | None = None,
    guesses: np.ndarray | None = None,
    progress: bool = False,
) -> Sweep:
    """Solve the inverse kinematics at every point and separate the errors there.

    The points are solved in batches (:class:`pkmtol.kinematics.batch.BatchChain`,
    :func:`pkmtol.error_model.separation.separate_many`). Without ``guesses``, they are reached by
    continuation from the refined home (:func:`pkmtol.kinematics.continuation.continuation`).

    Args:
        mechanism: The mechanism.
        pset: The error-parameter set.
        points_m: Shape (m, 3): positions of P in K [m].
        chain: Solver workspace (created if None); its models and limit check are used.
        guesses: Shape (m, Σ nq): initial guesses; default: continuation as above.
        progress: Show a progress bar.

    Raises:
        KinematicsError: the error of the first point (in point order) that cannot be solved or
            separated — unreachable, outside a joint limit, or singular.
    """
    check_set(pset, mechanism)
    points_m = values.points("points_m", points_m)
    check_chain(chain, mechanism)
    if guesses is not None:
        guesses = values.array_of_shape("guesses", guesses, (len(points_m), mechanism.n_joints))
    values.flag("progress", progress)
    chain = chain or ClosedChain(mechanism)
    batch = BatchChain(mechanism, chain=chain)
    points = np.asarray(points_m, dtype=float).reshape(-1, 3)
    m = len(points)
    bar = tqdm(total=m, desc="poses", unit="pose", disable=not progress, leave=False)
    results: list[Separation | KinematicsError | None] = [None] * m
    if guesses is not None:
        q0 = np.asarray(guesses, dtype=float).reshape(m, -1)
        for start in range(0, m, CHUNK):
            part = slice(start, min(start + CHUNK, m))
            sols = batch.inverse(points[part], q0[part])
            results[part] = separate_many(mechanism, pset, batch, sols)
            bar.update(part.stop - part.start)
    else:
        solved = continuation(batch, points, chain.home(), progress=bar.update)
        for start in range(0, m, CHUNK):
            part = slice(start, min(start + CHUNK, m))
            results[part] = separate_many(
                mechanism, pset, batch, solved.take(np.arange(part.start, part.stop))
            )
    bar.close()
    failed = next((r for r in results if not isinstance(r, Separation)), None)
    if failed is not None:
        raise failed if isinstance(failed, KinematicsError) else AssertionError("a point was not solved")
    seps = [r for r in results if isinstance(r, Separation)]
    return Sweep(
        points_m=points,
        poses=tuple(s.pose for s in seps),
        separations=tuple(seps),
        J=np.array([s.J for s in seps]).reshape(m, 3, len(pset)),
        J_total=np.array([s.J_total for s in seps]).reshape(m, 3, len(pset)),
        W_condition=np.array([s.W_condition for s in seps]),
    )


def guesses_near(grid: Sweep, points_m: np.ndarray) -> np.ndarray:
    """Initial guesses (m, Σ nq) for ``points_m`` (m, 3): a tangent step off the nearest grid pose.

    ``q_k + (∂q/∂P)_k (p − p_k)`` with ``k`` the nearest point of ``grid`` (its plain joint values
    when the pose has no tangent).
    """
    points = np.asarray(points_m, dtype=float).reshape(-1, 3)
    nearest = np.argmin(((points[:, None, :] - grid.points_m[None]) ** 2).sum(-1), axis=1)
    out = np.empty((len(points), grid.poses[0].q_all.size))
    for i, k in enumerate(nearest):
        pose = grid.poses[k]
        out[i] = pose.q_all
        if pose.tangent is not None:
            out[i] += pose.tangent @ (points[i] - pose.p_m)
    return out
