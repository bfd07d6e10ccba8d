"""Compensation by the controller's model, and the error the true machine is left with (exact).

The controller solves the inverse kinematics of its model (the mechanism perturbed by the
identified parameters) for a target of P, and sends the readings it finds; the true machine (its
real errors) moves to the pose its exact forward kinematics gives for those readings. What is left
is measured against the *nominal* pose at that target: the position error of P and the platform's
rotation (DESIGN.md's pose error ``X_actual = X_nominal · exp6(δ)``, rotation part in K).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.calibration.machine import Machine


@dataclass(frozen=True, eq=False)
class PoseErrors:
    """Errors of a machine at ``m`` targets of P (frame K, SI units).

    Attributes:
        position_m: Shape (m, 3): P_actual − P_target [m].
        rotation_rad: Shape (m, 3): rotation vector of the platform relative to its nominal
            orientation at the target, in K [rad].
        solved: Shape (m,): False where the model or the machine could not be solved (then the
            rows above are NaN).
    """

    position_m: np.ndarray
    rotation_rad: np.ndarray
    solved: np.ndarray

    @property
    def dlambda_m(self) -> np.ndarray:
        """Accuracy index Δλ = ‖P error‖ per target [m] (NaN where unsolved)."""
        return np.linalg.norm(self.position_m, axis=1)

    @property
    def angle_rad(self) -> np.ndarray:
        """Full orientation error angle per target [rad]."""
        return np.linalg.norm(self.rotation_rad, axis=1)

    def tilt_rad(self, axis: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """Tilt of the tool axis ``axis`` (platform frame) per target [rad]; ``rotations`` (m, 3, 3) nominal.

        The angle between the nominal and the actual axis: ``atan2(‖a × a'‖, a · a')``, exact.
        """
        a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        nominal = np.einsum("kij,j->ki", rotations, a)
        actual = _rotate(self.rotation_rad, nominal)
        cross = np.linalg.norm(np.cross(nominal, actual), axis=1)
        return np.arctan2(cross, np.einsum("ki,ki->k", nominal, actual))


def _rotate(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``exp3(θ_k) v_k`` for rotation vectors θ (m, 3) and vectors v (m, 3) (Rodrigues; NaN rows stay NaN)."""
    angle = np.linalg.norm(theta, axis=1)
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    k = theta / safe[:, None]
    kxv = np.cross(k, v)
    kv = np.einsum("ka,ka->k", k, v)
    c, s = np.cos(angle), np.sin(angle)
    out = v * c[:, None] + kxv * s[:, None] + k * (kv * (1.0 - c))[:, None]
    # below 1e-8 rad: the first order, exact to 1e-16
    return np.where(small[:, None], v + np.cross(theta, v), out)


def pose_errors(
    machine: Machine,
    commands: np.ndarray,
    q0: np.ndarray,
    targets_m: np.ndarray,
    rotations: np.ndarray,
) -> PoseErrors:
    """Errors of ``machine`` at readings ``commands`` (m, f) against targets (m, 3) with nominal rotations.

    ``q0`` (m, Σ nq) are the initial guesses (e.g. the nominal joint values at the targets).
    """
    m = len(commands)
    pos = np.full((m, 3), np.nan)
    rot = np.full((m, 3), np.nan)
    good = np.all(np.isfinite(commands), axis=1)
    ok = np.zeros(m, dtype=bool)
    if good.any():
        idx = np.flatnonzero(good)
        sols = machine.forward_many(commands[idx], q0[idx])
        for j, k in enumerate(idx):
            if sols.errors[j] is not None:
                continue
            pos[k] = machine.mechanism.task_error(sols.p_m[j] - targets_m[k])
            rk = rotations[k]
            task_rot = getattr(sols, "task_rotation", sols.rotation)  # a hybrid: the TCP frame's
            rot[k] = rk @ pin.log3(rk.T @ task_rot[j])
            ok[k] = True
    return PoseErrors(position_m=pos, rotation_rad=rot, solved=ok)


def controller_commands(
    model: Machine, targets_m: np.ndarray, q0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Readings the controller sends for each target (m, 3): its model's exact inverse kinematics.

    Returns:
        ``(commands (m, f), solved (m,))``; unsolved rows are NaN.
    """
    commands, sols = model.inverse_many(targets_m, q0)
    return commands, sols.ok
