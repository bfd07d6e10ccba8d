"""The distance from a platform point to a station's centre: the ballbar's and the sphere probe's model.

Station ``s`` has a centre ``c_s + π_s`` in K: its nominal position and a 3-vector of nuisance
parameters (the table ball of a ballbar set-up, the centre of a probed sphere), identified with the
machine. The value at a pose is ``d = ‖o + R b − c_s − π_s‖`` for the platform point ``b``
(platform frame; the tool point P). With ``u = (o + R b − c)/d``: per unit platform twist
``dd = uᵀ [I, −[R b]×] $``, per unit nuisance of its own station ``dd = −uᵀ dπ_s``.
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
        label: Nuisance names' prefix (``ball``, ``sphere``).

    Raises:
        InvalidRequestError: no station, or a centre that is not finite.
    """

    value_names = ("d",)
    value_units = ("m",)

    def __init__(
        self,
        point_m: np.ndarray,
        centres_m: np.ndarray,
        noise_m: float,
        centre_sigma_m: float,
        label: str,
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
        self.nuisance_names = tuple(f"{label}{s}.{a}" for s in range(S) for a in "xyz")
        self.nuisance_units = ("m",) * (3 * S)
        self.nuisance_scale = np.full(3 * S, float(centre_sigma_m))

    def _offsets(self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray):
        st = np.asarray(stations, dtype=int)
        if st.size and (st.min() < 0 or st.max() >= len(self.centres_m)):
            raise InvalidRequestError(
                f"station {int(st.max())} of {self.name} data does not exist: {len(self.centres_m)} "
                "station(s) are set up ([calibration] stations_m)"
            )
        centres = self.centres_m + np.asarray(nuisance, dtype=float).reshape(-1, 3)
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
        """``−uᵀ`` in the columns of each pose's station, (N, 1, 3·S)."""
        r, st = self._offsets(origin, rotation, stations, nuisance)
        u = r / np.linalg.norm(r, axis=1)[:, None]
        out = np.zeros((len(origin), 1, 3 * len(self.centres_m)))
        for a in range(3):
            out[np.arange(len(origin)), 0, 3 * st + a] = -u[:, a]
        return out
