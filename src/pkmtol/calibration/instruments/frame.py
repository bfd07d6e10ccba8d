"""The tracker-to-base transform: registered (known) or identified with the machine (6 nuisance parameters).

A tracker reports coordinates in its own frame T. A point ``p`` of K is read as
``y = T⁻¹ p = R_Tᵀ (p − t_T)``. When the frame is *identified*, ``T = T_ref · exp6(τ)`` with the
6 nuisance parameters ``τ = (v, ω)`` (Pinocchio's ``[v; ω]`` order, in the frame T): the
identification first registers ``T_ref`` in closed form (the rigid fit of the measured points to
the nominal model's, Kabsch/Umeyama by SVD), then refines ``τ`` with the machine. A global rigid
motion of the whole machine cannot be told from a moved tracker, so identifying the frame leaves
(up to) six more combinations of the machine's parameters unidentified; the plan names them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.calibration.instruments.base import skew
from pkmtol.exceptions import InvalidRequestError

#: How a tracker's frame is known.
FRAMES = ("registered", "identify")
#: Names of the six frame parameters (translation then rotation, in the tracker frame).
FRAME_NAMES = ("frame.dx", "frame.dy", "frame.dz", "frame.rx", "frame.ry", "frame.rz")
FRAME_UNITS = ("m", "m", "m", "rad", "rad", "rad")


@dataclass(frozen=True, eq=False)
class TrackerFrame:
    """Where the tracker's frame is, and whether it is identified.

    Attributes:
        identify: Identify ``τ`` with the machine (6 nuisance parameters); else the frame is
            ``reference`` exactly (registered to the base).
        reference: ``T_ref``: tracker frame → K (identity: measurements in K).
    """

    identify: bool = False
    reference: pin.SE3 = pin.SE3.Identity()

    @property
    def count(self) -> int:
        """Nuisance parameters of the frame (6 or 0)."""
        return 6 if self.identify else 0

    def transform(self, tau: np.ndarray) -> pin.SE3:
        """``T = T_ref · exp6(τ)`` (``τ`` ignored when the frame is registered)."""
        if not self.identify:
            return self.reference
        return self.reference * pin.exp6(pin.Motion(np.asarray(tau, dtype=float)[:6]))

    def to_tracker(self, points_m: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``T⁻¹ p`` of points (…, 3) of K [m]."""
        T = self.transform(tau)
        return (np.asarray(points_m, dtype=float) - T.translation) @ T.rotation

    def rotation_to_tracker(self, rotation: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``R_Tᵀ R`` of rotations (…, 3, 3) of K."""
        return np.einsum("ba,...bc->...ac", self.transform(tau).rotation, rotation)

    def point_rows(self, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Change of tracker coordinates ``y`` (N, 3) per unit ``τ``, shape (N, 3, 6)."""
        out = np.zeros((len(y), 3, 6))
        out[:, :, :3] = -np.eye(3)
        out[:, :, 3:] = skew(y)
        return out @ self._right_jacobian(tau)

    def rotation_rows(self, count: int, tau: np.ndarray) -> np.ndarray:
        """Change of a measured orientation (spatial, tracker frame) per unit ``τ``, (count, 3, 6)."""
        out = np.zeros((count, 3, 6))
        out[:, :, 3:] = -np.eye(3)
        return out @ self._right_jacobian(tau)

    def _right_jacobian(self, tau: np.ndarray) -> np.ndarray:
        return np.asarray(pin.Jexp6(pin.Motion(np.asarray(tau, dtype=float)[:6])))

    def registered(self, model_points_m: np.ndarray, measured: np.ndarray) -> TrackerFrame:
        """This frame re-referenced at the rigid fit of ``measured`` (tracker, (M, 3)) to ``model`` (K).

        Raises:
            InvalidRequestError: the points cannot fix a frame (fewer than 3, or all on a line).
        """
        return TrackerFrame(identify=self.identify, reference=rigid_fit(measured, model_points_m))


def rigid_fit(source: np.ndarray, target: np.ndarray) -> pin.SE3:
    """The rigid transform T minimising ``Σ ‖T s_i − t_i‖²`` (Kabsch by SVD), source/target (M, 3).

    Raises:
        InvalidRequestError: fewer than 3 points, or all on a line (the rotation is not fixed).
    """
    s = np.asarray(source, dtype=float).reshape(-1, 3)
    t = np.asarray(target, dtype=float).reshape(-1, 3)
    if len(s) < 3:
        raise InvalidRequestError(f"{len(s)} measured point(s) cannot register the tracker frame; need ≥ 3")
    cs, ct = s.mean(axis=0), t.mean(axis=0)
    u, sv, vt = np.linalg.svd((s - cs).T @ (t - ct))
    if sv[1] <= 1e-12 * max(sv[0], 1e-300):
        raise InvalidRequestError(
            "the measured points lie on a line: they cannot register the tracker frame; measure "
            "poses spread over the task space, or give the registered frame"
        )
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return pin.SE3(R, ct - R @ cs)
