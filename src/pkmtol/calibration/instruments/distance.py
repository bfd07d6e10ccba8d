"""The distance from a platform point to a station's centre: the ballbar's and the sphere probe's model.

Station ``s`` has a centre ``c_s + E_s π_s`` in K: its nominal position, moved along the station's
``k`` nuisance axes ``E_s`` (3 × k, orthonormal columns) by its nuisance parameters ``π_s`` (a
ballbar's table ball, in its circle's plane), identified with the machine. The value at a pose is
``d = ‖o + R b − c_s − E_s π_s‖`` for the platform point ``b`` (platform frame; the tool point P).
With ``u = (o + R b − c)/d``: per unit platform twist ``dd = uᵀ [I, −[R b]×] $``, per unit
nuisance of its own station ``dd = −uᵀ E_s dπ_s``.
"""

from __future__ import annotations

import numpy as np

from pkmtol.calibration.instruments.base import Instrument, lever_rows
from pkmtol.exceptions import InvalidRequestError


class StationDistance(Instrument):
    """Distances from a platform point to station centres (abstract: a ballbar or a sphere probe).

    Args:
        point_m: Shape (3,): the platform point (ball or stylus tip) in the platform frame [m].
        centres_m: Shape (S, 3): the stations' nominal centres in K [m].
        noise_m: σ per distance [m].
        centre_sigma_m: Expected size of each centre's offset from nominal [m] (scaling, draws).
        label: Nuisance names' prefix (``ball``).
        axes: Shape (S, k, 3): each station's nuisance axes (rows; default the x, y, z axes).

    Raises:
        InvalidRequestError: no station, or a centre that is not finite.
    """

    value_names = ("d",)
    value_units = ("m",)
    refresh_rows = True

    def __init__(
        self,
        point_m: np.ndarray,
        centres_m: np.ndarray,
        noise_m: float,
        centre_sigma_m: float,
        label: str,
        axes: np.ndarray | None = None,
    ) -> None:
        self.point_m = np.asarray(point_m, dtype=float).reshape(3)
        self.centres_m = np.asarray(centres_m, dtype=float).reshape(-1, 3)
        if not len(self.centres_m) or not np.all(np.isfinite(self.centres_m)):
            raise InvalidRequestError(
                f"the {self.name} needs at least one station centre [x, y, z] in metres; give "
                "[calibration] stations_m"
            )
        self.noise = np.array([float(noise_m)])
        S = len(self.centres_m)
        self.axes = np.tile(np.eye(3), (S, 1, 1)) if axes is None else np.asarray(axes, dtype=float)
        k = self.axes.shape[1]
        self.nuisance_names = tuple(
            f"{label}{s}.{'xyz'[int(np.argmax(np.abs(e)))]}" for s in range(S) for e in self.axes[s]
        )
        self.nuisance_units = ("m",) * (k * S)
        self.nuisance_scale = np.full(k * S, float(centre_sigma_m))

    def _offsets(self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray):
        st = np.asarray(stations, dtype=int)
        if st.size and (st.min() < 0 or st.max() >= len(self.centres_m)):
            raise InvalidRequestError(
                f"station {int(st.max())} of {self.name} data does not exist: {len(self.centres_m)} "
                "station(s) are set up ([calibration] stations_m)"
            )
        pi = np.asarray(nuisance, dtype=float).reshape(len(self.centres_m), -1)
        centres = self.centres_m + np.einsum("sk,ska->sa", pi, self.axes)
        point = origin + np.einsum("kab,b->ka", rotation, self.point_m)
        return point - centres[st], st

    def measure(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``‖o + R b − c_s − π_s‖`` per pose, (N, 1) [m]."""
        r, _ = self._offsets(origin, rotation, stations, nuisance)
        return np.linalg.norm(r, axis=1)[:, None]

    def twist_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``uᵀ [I, −[R b]×]`` per pose, (N, 1, 6)."""
        r, _ = self._offsets(origin, rotation, stations, nuisance)
        u = r / np.linalg.norm(r, axis=1)[:, None]
        return np.einsum("ka,kab->kb", u, lever_rows(rotation, self.point_m))[:, None, :]

    def nuisance_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``−uᵀ E_s`` in the columns of each pose's station, (N, 1, k·S)."""
        r, st = self._offsets(origin, rotation, stations, nuisance)
        u = r / np.linalg.norm(r, axis=1)[:, None]
        k = self.axes.shape[1]
        out = np.zeros((len(origin), 1, k * len(self.centres_m)))
        proj = -np.einsum("na,nka->nk", u, self.axes[st])
        for a in range(k):
            out[np.arange(len(origin)), 0, k * st + a] = proj[:, a]
        return out
