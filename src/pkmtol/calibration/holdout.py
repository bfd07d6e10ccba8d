"""Held-out evaluation poses: random task-space targets of P, with their nominal solution and linear maps."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.calibration.hybrid_poses import hybrid_holdout_sweep
from pkmtol.calibration.maps import PoseMaps, pose_maps
from pkmtol.error_model.compensation import AccuracyMaps, mode_maps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep, sweep
from pkmtol.exceptions import InvalidRequestError, KinematicsError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class Holdout:
    """The evaluation poses of a calibration study.

    Attributes:
        maps: Linear maps at the poses (nominal P, joints, commands, twists).
        correction: Shape (m, f, n): Eq. 25's actuator correction per parameter at each pose.
        ideal: The ``ideal`` accuracy maps (Eq. 25) at the poses.
        skipped: Random draws left out because they were unreachable or singular.
    """

    maps: PoseMaps
    correction: np.ndarray
    ideal: AccuracyMaps
    skipped: int


def holdout_poses(
    mechanism: Mechanism,
    pset: ParameterSet,
    count: int,
    rng: np.random.Generator,
    chain: ClosedChain | None = None,
) -> Holdout:
    """``count`` reachable random targets of P, uniform over the task space.

    Raises:
        InvalidRequestError: ``count`` < 1, or not one random draw is reachable.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise InvalidRequestError(f"the number of held-out poses must be an integer ≥ 1, got {count!r}")
    if mechanism.tool is not None:  # a hybrid: random TCP targets × tool axes
        hsw, skipped = hybrid_holdout_sweep(mechanism, pset, count, rng, chain)
        return _holdout(hsw, chain or ClosedChain(mechanism), mechanism, skipped)
    chain = chain or ClosedChain(mechanism)
    grid = mechanism.task_space.grid()
    home = chain.home()
    reference = sweep(mechanism, pset, grid[:1], chain, guesses=home[None, :])
    base_pose = reference.poses[0]
    points, guesses = [], []
    skipped = 0
    for p in mechanism.task_space.sample(rng, count):
        try:
            pose = chain.inverse(p, chain.predict(base_pose, p))
        except KinematicsError:
            try:
                pose = chain.inverse(p, home)
            except KinematicsError:
                skipped += 1
                continue
        points.append(p)
        guesses.append(pose.q_all)
    if not points:
        raise InvalidRequestError("no random task-space target is reachable; check the task space")
    sw = sweep(mechanism, pset, np.array(points), chain, guesses=np.array(guesses))
    return _holdout(sw, chain, mechanism, skipped)


def _holdout(sw: Sweep, chain: ClosedChain, mechanism: Mechanism, skipped: int) -> Holdout:
    return Holdout(
        maps=pose_maps(sw, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection),
        correction=np.array([s.correction for s in sw.separations]),
        ideal=mode_maps(sw, "ideal"),
        skipped=skipped,
    )
