"""``tracker-6d``: a tracker with a 6D probe on the platform, measuring P's position and the orientation.

The probe (Leica T-Mac, API i-Probe class) reports the position of the tool point P and the
orientation of the platform, both in the tracker frame T (:mod:`.frame`):
``y = T⁻¹ (o + R p)`` and ``R_y = R_Tᵀ R`` (the probe's axes are taken parallel to the platform
frame; its mounting rotation, if any, is folded into the data). The orientation is written as a
rotation vector ``log3(R_y)``; the residual of an orientation is ``log3(R_meas R_modelᵀ)``, the
spatial rotation (tracker frame) that takes the model to the measurement. Per unit platform twist
``$ = (v, ω)``: ``dy = R_Tᵀ [I, −[R p]×] $`` and ``dθ = R_Tᵀ ω``.

Noise: σ per position coordinate (default 10 µm, as the tracker) and σ per rotation component
(default 0.1 mrad: a T-Mac's orientation accuracy is about ±0.01° = 175 µrad).

CSV: ``pose,<actuated joints>…,x [mm],y [mm],z [mm],rx [mrad],ry [mrad],rz [mrad]`` (rotation
vector, any angle unit), one row per pose (:mod:`pkmtol.calibration.instrument_files`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pkmtol.calibration.instruments.base import Instrument, lever_rows
from pkmtol.calibration.instruments.frame import FRAME_NAMES, FRAME_UNITS, TrackerFrame
from pkmtol.calibration.instruments.tracker import FRAME_DRAW


class Tracker6D(Instrument):
    """P's position and the platform orientation from a 6D probe.

    Args:
        point_m: Shape (3,): the probe's measured point in the platform frame (P) [m].
        noise_m: σ per position coordinate [m].
        noise_rad: σ per rotation component [rad].
        frame: The tracker frame (registered, or identified as 6 nuisance parameters).
    """

    name = "tracker-6d"
    value_names = ("x", "y", "z", "rx", "ry", "rz")
    value_units = ("m", "m", "m", "rad", "rad", "rad")

    def __init__(
        self, point_m: np.ndarray, noise_m: float, noise_rad: float, frame: TrackerFrame | None = None
    ) -> None:
        self.point_m = np.asarray(point_m, dtype=float).reshape(3)
        self.frame = frame or TrackerFrame()
        self.noise = np.array([noise_m] * 3 + [noise_rad] * 3, dtype=float)
        self.nuisance_names = FRAME_NAMES if self.frame.identify else ()
        self.nuisance_units = FRAME_UNITS if self.frame.identify else ()
        self.nuisance_scale = np.full(self.frame.count, 1e-3)
        self.refresh_rows = self.frame.identify  # the rows turn with the registered frame

    def measure(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``[T⁻¹ P, log3(R_Tᵀ R)]`` per pose, (N, 6) [m, rad]."""
        p = origin + np.einsum("kab,b->ka", rotation, self.point_m)
        y = self.frame.to_tracker(p, nuisance)
        Ry = self.frame.rotation_to_tracker(rotation, nuisance)
        return np.column_stack([y, np.array([pin.log3(r) for r in Ry]).reshape(-1, 3)])

    def residual(self, measured: np.ndarray, model: np.ndarray) -> np.ndarray:
        """Position difference, and the rotation ``log3(exp3(θ_meas) exp3(θ_model)ᵀ)``."""
        measured, model = np.atleast_2d(measured), np.atleast_2d(model)
        rot = [
            pin.log3(pin.exp3(a) @ pin.exp3(b).T) for a, b in zip(measured[:, 3:], model[:, 3:], strict=True)
        ]
        return np.column_stack([measured[:, :3] - model[:, :3], np.array(rot).reshape(-1, 3)])

    def perturb(self, values: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """Positions plus noise; orientations turned by the noise rotation (spatial, tracker frame)."""
        values, noise = np.atleast_2d(values), np.atleast_2d(noise)
        rot = [pin.log3(pin.exp3(e) @ pin.exp3(v)) for e, v in zip(noise[:, 3:], values[:, 3:], strict=True)]
        return np.column_stack([values[:, :3] + noise[:, :3], np.array(rot).reshape(-1, 3)])

    def twist_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``[R_Tᵀ [I, −[R p]×]; 0, R_Tᵀ]`` per pose, (N, 6, 6)."""
        RT = self.frame.transform(nuisance).rotation
        out = np.zeros((len(origin), 6, 6))
        out[:, :3] = np.einsum("ba,kbc->kac", RT, lever_rows(rotation, self.point_m))
        out[:, 3:, 3:] = RT.T
        return out

    def nuisance_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """Per unit frame parameter (N, 6, 6), or (N, 6, 0) when the frame is registered."""
        N = len(origin)
        if not self.frame.identify:
            return np.zeros((N, 6, 0))
        y = self.measure(origin, rotation, stations, nuisance)[:, :3]
        return np.concatenate(
            [self.frame.point_rows(y, nuisance), self.frame.rotation_rows(N, nuisance)], axis=1
        )

    def start(
        self, measured: np.ndarray, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray
    ) -> tuple[Instrument, np.ndarray]:
        """With the frame identified: register it by the rigid fit of the measured to the nominal P."""
        if not self.frame.identify:
            return self, np.zeros(0)
        p = origin + np.einsum("kab,b->ka", rotation, self.point_m)
        frame = self.frame.registered(p, np.asarray(measured, dtype=float)[:, :3])
        return Tracker6D(self.point_m, float(self.noise[0]), float(self.noise[3]), frame), np.zeros(6)

    def draw_nuisance(self, rng: np.random.Generator) -> np.ndarray:
        """A random tracker placement (as :class:`TrackerPoints`)."""
        if not self.frame.identify:
            return np.zeros(0)
        v = rng.standard_normal(3) * FRAME_DRAW[0]
        w = rng.standard_normal(3) * FRAME_DRAW[1]
        angle = np.linalg.norm(w)
        if angle > 0.95 * np.pi:
            w *= 0.95 * np.pi / angle
        return np.concatenate([v, w])
