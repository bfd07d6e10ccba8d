"""The error model over many poses: inverse kinematics along a point list, separation at each."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

import pkmtol.values as values
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.separation import Separation, separate
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.model.mechanism import Mechanism

#: Relative size of a projection below which it counts as zero (classification).
ZERO_TOLERANCE = 1e-9

CLASSES = ("absorbed", "compensatable", "uncompensatable")


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


def sweep(
    mechanism: Mechanism,
    pset: ParameterSet,
    points_m: np.ndarray,
    chain: ClosedChain | None = None,
    guesses: np.ndarray | None = None,
    progress: bool = False,
) -> Sweep:
    """Solve the inverse kinematics at every point and separate the errors there.

    Args:
        mechanism: The mechanism.
        pset: The error-parameter set.
        points_m: Shape (m, 3): positions of P in K [m].
        chain: Solver workspace (created if None).
        guesses: Shape (m, Σ nq): initial guesses; default: a tangent step from the previous
            point's solution (the first point starts from the refined home).
        progress: Show a progress bar.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism")
    values.instance("pset", pset, ParameterSet, "a ParameterSet (pkmtol.parameter_set)")
    points_m = values.array_of_shape("points_m", points_m, (None, 3))
    chain = chain or ClosedChain(mechanism)
    poses: list[Pose] = []
    seps = []
    it = tqdm(points_m, desc="poses", unit="pose", disable=not progress, leave=False)
    for k, p in enumerate(it):
        if guesses is not None:
            q0 = guesses[k]
        elif poses:
            q0 = chain.predict(poses[-1], p)  # tangent step from the previous point
        else:
            q0 = chain.home()
        pose = chain.inverse(p, q0)
        poses.append(pose)
        seps.append(separate(mechanism, pset, chain, pose))
    return Sweep(
        points_m=np.asarray(points_m, dtype=float),
        poses=tuple(poses),
        separations=tuple(seps),
        J=np.array([s.J for s in seps]),
        J_total=np.array([s.J_total for s in seps]),
        W_condition=np.array([s.W_condition for s in seps]),
    )
