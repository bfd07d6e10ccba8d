"""A machine: the mechanism with given geometric errors, solved by exact kinematics.

The same object plays both roles of a calibration: the **true machine** (its errors are the
manufacturing errors; it is measured and, at the end, it is what moves) and the **controller's
model** (its errors are the identified estimate; the controller solves its inverse kinematics to
command the actuators). Commands are actuator *readings*: the actual joint value is the reading plus
the joint's zero offset (DESIGN.md, "Geometric error parameters").
"""

from __future__ import annotations

import numpy as np

from pkmtol.error_model.parameters import ParameterSet
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.kinematics.solutions import Solutions
from pkmtol.model.mechanism import Mechanism


class Machine:
    """The mechanism perturbed by a parameter vector, with its exact forward and inverse kinematics.

    Args:
        mechanism: The nominal mechanism.
        pset: Its parameter set.
        delta: Shape (n,): the errors of every parameter [m, rad] (zeros: the nominal machine).

    A mechanism with a tool chain gets a
    :class:`~pkmtol.calibration.hybrid_machine.HybridMachine` (the TCP, the whole machine's joints).
    """

    def __new__(cls, mechanism: Mechanism, pset: ParameterSet, delta: np.ndarray) -> Machine:  # noqa: D102
        if mechanism.tool is not None and cls is Machine:  # a hybrid: the module and the tool chain
            from pkmtol.calibration.hybrid_machine import HybridMachine

            return HybridMachine(mechanism, pset, delta)  # type: ignore[return-value]
        return super().__new__(cls)

    def __init__(self, mechanism: Mechanism, pset: ParameterSet, delta: np.ndarray) -> None:
        self.mechanism = mechanism
        self.pset = pset
        self.delta = np.asarray(delta, dtype=float).copy()
        eps, self.offsets = pset.perturbation(self.delta, mechanism)
        self.chain = ClosedChain(mechanism, models=perturbed_limb_models(mechanism, eps), check_limits=False)
        self.actuated_idx = self.chain.actuated_idx
        self._batch: BatchChain | None = None

    @property
    def batch(self) -> BatchChain:
        """The batched solver of this machine (same models and equations as :attr:`chain`)."""
        if self._batch is None:
            self._batch = BatchChain(self.mechanism, chain=self.chain)
        return self._batch

    def forward_many(self, commands: np.ndarray, q0: np.ndarray) -> Solutions:
        """:meth:`forward` of many readings at once: ``commands`` (B, f), guesses (B, Σ nq).

        A problem that cannot be solved has its error in ``Solutions.errors`` (nothing raised).
        """
        commands = np.atleast_2d(np.asarray(commands, dtype=float))
        offsets = np.broadcast_to(self.offsets, (len(commands), self.offsets.size))
        return self.batch.forward(commands, q0, offsets)

    def inverse_many(self, targets_m: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, Solutions]:
        """:meth:`inverse` of many targets (B, 3) at once: ``(readings (B, f), solutions)``.

        Rows of unsolved problems are NaN; their errors are in ``Solutions.errors``.
        """
        sols = self.batch.inverse(np.atleast_2d(np.asarray(targets_m, dtype=float)), q0)
        commands = sols.q[:, self.actuated_idx] - self.offsets[self.actuated_idx]
        return np.where(sols.ok[:, None], commands, np.nan), sols

    def forward(self, commands: np.ndarray, q0: np.ndarray) -> Pose:
        """Platform pose at actuator readings ``commands`` (f,), from the initial guess ``q0`` (Σ nq,).

        Raises:
            pkmtol.exceptions.KinematicsError: Newton does not converge (the machine cannot reach
                these commands near ``q0``).
        """
        return self.chain.forward(np.asarray(commands, dtype=float), q0, self.offsets)

    def inverse(self, target_m: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, Pose]:
        """The readings that put this machine's P at ``target_m`` (3,) [m], and the pose there.

        Returns:
            ``(commands, pose)``: actuator readings (f,) = actual joint values − zero offsets.
        """
        pose = self.chain.inverse(np.asarray(target_m, dtype=float), q0)
        q = pose.q_all
        return q[self.actuated_idx] - self.offsets[self.actuated_idx], pose


def target_positions(pose: Pose, targets_m: np.ndarray) -> np.ndarray:
    """Positions in K of targets fixed at ``targets_m`` (t, 3) in the platform frame, shape (t, 3) [m]."""
    t = np.atleast_2d(np.asarray(targets_m, dtype=float))
    return pose.oMp.translation[None, :] + t @ pose.oMp.rotation.T
