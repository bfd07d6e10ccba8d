"""The claim of a design and its scope: which reliability it promises, where, and whether the check agrees.

Every design ends in one claim (docs/theory.md, "Claims and their scope"): the ``exact`` and
``cost`` designs promise ``R ≥ R*`` at every grid pose (criterion ``every``), at the design pose
(``worst``) or on the grid average (``average``); the one-pose ``fosm`` design promises Φ(β) at the
design point only. Beside the promise, :func:`design_claim` reports the exact Gaussian reliability
of the linear model of the verified tolerances at every grid pose (the minimum, where it is, the
mean), and :func:`verification_misses` names each verification row whose measured reliability
lies below the claim beyond its 95 % interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.design.exact import grid_reliability, noise_covariance
from pkmtol.design.methods import MethodDesign
from pkmtol.design.reliability import reliability_fosm
from pkmtol.design.verification import FailureStats, Verification
from pkmtol.error_model.compensation import AccuracyMaps

#: Where a claim holds, per criterion (``fosm``: at the design point).
SCOPES = {
    "every": "at every grid pose",
    "worst": "at the design point only",
    "average": "on average over the grid",
    "fosm": "at the design point only",
}


@dataclass(frozen=True, eq=False)
class Claim:
    """What a design promises, and its exact reliability over the task-space grid.

    Attributes:
        method: ``fosm``, ``exact`` or ``cost``.
        scope: ``every``, ``worst``, ``average`` (the criterion) or ``fosm`` (the design point).
        claimed: The promised reliability (R* = Φ(design β)).
        design_pose: Grid index of the design pose.
        reliability: Shape (m,): exact reliability of the linear model at each grid pose (Gaussian
            errors at the verified σ_i, tracker noise included; the joint position and tilt
            reliability when the design has an orientation target).
        joint: Whether ``reliability`` is the joint position and tilt reliability.
        toleranced: How many parameters the design tolerances (0: the mode compensates or
            identifies every error; the reliability is then the noise's alone).
    """

    method: str
    scope: str
    claimed: float
    design_pose: int
    reliability: np.ndarray
    joint: bool = False
    toleranced: int = -1

    @property
    def min_reliability(self) -> float:
        """The lowest reliability over the grid."""
        return float(self.reliability.min())

    @property
    def min_pose(self) -> int:
        """Grid index of the lowest reliability (the first, if tied)."""
        return int(np.argmin(self.reliability))

    @property
    def mean_reliability(self) -> float:
        """The grid mean of the reliability."""
        return float(self.reliability.mean())

    @property
    def where(self) -> str:
        """Where the claim holds, in words."""
        return SCOPES[self.scope]


def design_claim(
    maps: AccuracyMaps,
    unc: np.ndarray,
    sigma: np.ndarray,
    target_m: float,
    design_beta: float,
    design_pose: int,
    method: str,
    criterion: str,
    method_design: MethodDesign | None,
) -> Claim:
    """The claim of the verified design ``sigma`` (tolerances of the columns ``unc``).

    The grid reliability is the method design's own (its root finding computed it) or, for
    ``fosm``, the exact Gaussian reliability of the linear model of the FOSM tolerances.
    """
    claimed = float(reliability_fosm(design_beta))
    if method_design is not None:
        return Claim(
            method=method,
            scope=method_design.criterion,
            claimed=method_design.target_reliability,
            design_pose=design_pose,
            reliability=np.asarray(method_design.reliability, dtype=float),
            joint=method_design.joint,
            toleranced=int(np.asarray(unc).size),
        )
    s = np.where(np.isfinite(sigma), sigma, 0.0)
    rel = grid_reliability(maps.position[:, :, unc], s, target_m, noise_covariance(maps))
    return Claim(
        method=method,
        scope="fosm",
        claimed=claimed,
        design_pose=design_pose,
        reliability=rel,
        toleranced=int(np.asarray(unc).size),
    )


@dataclass(frozen=True)
class Miss:
    """A verification row whose reliability lies below the claim beyond its 95 % interval.

    Attributes:
        distribution: The verification's error distribution (``gaussian``).
        model: ``linear`` or ``exact``.
        reliability: Its measured reliability.
        interval: Its 95 % interval of the reliability ``(low, high)``.
        samples: Its sample count.
    """

    distribution: str
    model: str
    reliability: float
    interval: tuple[float, float]
    samples: int


def verification_misses(verification: dict[str, Verification], claimed: float) -> list[Miss]:
    """The Gaussian verification rows (linear, exact) whose interval lies wholly below ``claimed``.

    The verification draws random task-space poses, so it checks the task-space mean; a claim at
    every pose implies that mean, and a claim at the design point only is checked against it too
    (the last lines of ``pkmtol allocate`` then say how far it falls short).
    """
    misses: list[Miss] = []
    v = verification.get("gaussian")
    if v is None:
        return misses
    rows: list[tuple[str, FailureStats | None]] = [("linear", v.linear), ("exact", v.exact)]
    for model, s in rows:
        if s is None:
            continue
        high = 1.0 - s.failure_ci95[0]
        if high < claimed:
            misses.append(Miss("gaussian", model, s.reliability, (1.0 - s.failure_ci95[1], high), s.samples))
    return misses
