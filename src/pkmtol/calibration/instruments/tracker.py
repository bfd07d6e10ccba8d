"""``tracker`` and ``tracker-multi``: a laser tracker measuring the positions of reflectors on the platform.

``tracker`` reads one reflector at the tool point P (the classic set-up); ``tracker-multi`` reads
``K ≥ 3`` reflectors at given platform positions ``t_j``, which fixes the platform's pose too.
Each reflector's position ``y_j = T⁻¹ (o + R t_j)`` is read in the tracker frame T
(:mod:`.frame`), with independent Gaussian noise σ per coordinate (default 10 µm: the maximum
permissible error of an AT960/Vantage-class tracker is about ±(15 µm + 6 µm/m), σ ≈ 10 µm at the
1–2 m of a machining PKM). Per unit platform twist, ``dy_j = R_Tᵀ [I, −[R t_j]×] $``.

CSV: ``pose,<actuated joints [mm|deg]>…,target,x [mm],y [mm],z [mm]``, one row per reflector
(:mod:`pkmtol.calibration.measurement_files`).
"""

from __future__ import annotations

import numpy as np

from pkmtol.calibration.instruments.base import Instrument, lever_rows
from pkmtol.calibration.instruments.frame import FRAME_NAMES, FRAME_UNITS, TrackerFrame
from pkmtol.exceptions import InvalidRequestError

#: σ of a simulated frame offset when the frame is identified: translation [m], rotation [rad]
#: (a tracker set up a metre or so from the machine, turned at random).
FRAME_DRAW = (1.0, np.pi / 2)


class TrackerPoints(Instrument):
    """Reflectors at ``targets_m`` (t, 3) in the platform frame, read by a tracker.

    Args:
        targets_m: Shape (t, 3): reflector positions in the platform frame [m].
        noise_m: σ per coordinate [m].
        frame: The tracker frame (registered, or identified as 6 nuisance parameters).
        name: ``tracker`` or ``tracker-multi``.

    Raises:
        InvalidRequestError: ``tracker-multi`` with fewer than 3 reflectors or all on a line.
    """

    def __init__(
        self,
        targets_m: np.ndarray,
        noise_m: float,
        frame: TrackerFrame | None = None,
        name: str = "tracker",
    ) -> None:
        self.targets_m = np.atleast_2d(np.asarray(targets_m, dtype=float))
        self.frame = frame or TrackerFrame()
        self.name = name
        t = self.targets_m.shape[0]
        if name == "tracker-multi":
            spread = np.linalg.svd(self.targets_m - self.targets_m.mean(axis=0), compute_uv=False)
            if t < 3 or spread[1] <= 1e-9:
                raise InvalidRequestError(
                    f"tracker-multi needs ≥ 3 reflectors not on one line (got {t}); give "
                    "[calibration] targets_m = [[x, y, z], …] in the platform frame [m]"
                )
        self.value_names = tuple(f"{a}{j}" for j in range(t) for a in "xyz")
        self.value_units = ("m",) * (3 * t)
        self.noise = np.full(3 * t, float(noise_m))
        self.nuisance_names = FRAME_NAMES if self.frame.identify else ()
        self.nuisance_units = FRAME_UNITS if self.frame.identify else ()
        self.nuisance_scale = np.array([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3][: self.frame.count])
        self.refresh_rows = self.frame.identify  # the rows turn with the registered frame

    def _points(self, origin: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        return origin[:, None, :] + np.einsum("kab,tb->kta", rotation, self.targets_m)

    def measure(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """Reflector coordinates in the tracker frame, (N, 3·t) [m]."""
        y = self.frame.to_tracker(self._points(origin, rotation), nuisance)
        return y.reshape(len(origin), -1)

    def twist_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``R_Tᵀ [I, −[R t_j]×]`` per pose and reflector, (N, 3·t, 6)."""
        RT = self.frame.transform(nuisance).rotation
        rows = np.stack([lever_rows(rotation, t) for t in self.targets_m], axis=1)  # (N, t, 3, 6)
        return np.einsum("ba,ktbc->ktac", RT, rows).reshape(len(origin), -1, 6)

    def nuisance_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """Per unit frame parameter (N, 3·t, 6), or (N, 3·t, 0) when the frame is registered."""
        N, t = len(origin), self.targets_m.shape[0]
        if not self.frame.identify:
            return np.zeros((N, 3 * t, 0))
        y = self.frame.to_tracker(self._points(origin, rotation), nuisance).reshape(-1, 3)
        return self.frame.point_rows(y, nuisance).reshape(N, 3 * t, 6)

    def start(
        self, measured: np.ndarray, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray
    ) -> tuple[Instrument, np.ndarray]:
        """With the frame identified: register it by the rigid fit of the data to the nominal model."""
        if not self.frame.identify:
            return self, np.zeros(0)
        model = self._points(origin, rotation).reshape(-1, 3)
        frame = self.frame.registered(model, np.asarray(measured, dtype=float).reshape(-1, 3))
        return TrackerPoints(self.targets_m, float(self.noise[0]), frame, self.name), np.zeros(6)

    def draw_nuisance(self, rng: np.random.Generator) -> np.ndarray:
        """A random tracker placement: translation σ 1 m, rotation σ π/2 per axis (|θ| < π)."""
        if not self.frame.identify:
            return np.zeros(0)
        v = rng.standard_normal(3) * FRAME_DRAW[0]
        w = rng.standard_normal(3) * FRAME_DRAW[1]
        angle = np.linalg.norm(w)
        if angle > 0.95 * np.pi:
            w *= 0.95 * np.pi / angle
        return np.concatenate([v, w])
