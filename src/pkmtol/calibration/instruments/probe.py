"""``probe``: a touch probe at the tool point touching a sphere artifact of known size.

The artifact is a sphere whose *effective* radius ``R`` (sphere radius + stylus-tip radius) is known
from its certificate; it is set up at one or more stations, each of unknown true centre
``c_s + π_s`` (3 nuisance parameters per station, identified with the machine). At a touch the
probe triggers where the tip centre P lies on the sphere of radius R about the centre: the machine's
actuator readings at the trigger satisfy ``‖P(u) − c_s − π_s‖ = R`` (:mod:`.distance`); the
residual is ``R − ‖P(u) − c_s − π_s‖``. Noise: σ per touch along the surface normal (default 1 µm: a
touch-trigger probe's unidirectional repeatability is 0.25–1 µm 2σ, plus the machine's trigger lag).

The plan chooses touches among approach directions: ``approach_directions`` directions spread over
the upper hemisphere of every station (the stylus comes from above or the side), P at
``c_s + R n``. In a simulation the probe reads the distance at the planned commands; data from a
real probe gives the trigger readings and the known radius.

CSV: ``pose,<actuated joints>…,station`` (the readings at the trigger), one row per touch
(:mod:`pkmtol.calibration.instrument_files`).
"""

from __future__ import annotations

import numpy as np

from pkmtol.calibration.instruments.base import Candidates
from pkmtol.calibration.instruments.distance import StationDistance
from pkmtol.exceptions import InvalidRequestError


def hemisphere(count: int, min_elevation_rad: float = 0.0) -> np.ndarray:
    """``count`` unit vectors spread over the upper hemisphere (Fibonacci spiral), shape (count, 3)."""
    i = np.arange(count) + 0.5
    z_low = np.sin(min_elevation_rad)
    z = 1.0 - i / count * (1.0 - z_low)
    r = np.sqrt(np.clip(1.0 - z**2, 0.0, None))
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


class SphereProbe(StationDistance):
    """Touches on a sphere artifact of effective radius ``radius_m`` at the given stations.

    Args:
        point_m: Shape (3,): the stylus tip centre in the platform frame (P) [m].
        centres_m: Shape (S, 3): the artifact's nominal centre at each station, in K [m].
        radius_m: Effective radius (sphere + stylus tip) [m].
        directions: Candidate approach directions per station.
        noise_m: σ per touch [m].
        centre_sigma_m: Expected offset of a station from its nominal centre [m].

    Raises:
        InvalidRequestError: a radius ≤ 0 or fewer than 4 directions.
    """

    name = "probe"

    def __init__(
        self,
        point_m: np.ndarray,
        centres_m: np.ndarray,
        radius_m: float,
        directions: int,
        noise_m: float,
        centre_sigma_m: float = 5e-4,
    ) -> None:
        if not radius_m > 0 or not np.isfinite(radius_m):
            raise InvalidRequestError(f"the artifact's radius must be > 0, got {radius_m!r} m")
        if directions < 4:
            raise InvalidRequestError(f"a sphere needs ≥ 4 approach directions, got {directions}")
        self.radius_m = float(radius_m)
        self.directions = hemisphere(int(directions), np.deg2rad(10.0))
        super().__init__(point_m, centres_m, noise_m, centre_sigma_m, "sphere")

    def candidates(self, task_points: np.ndarray, rng: np.random.Generator) -> Candidates:
        """Every station's touches: P at ``c_s + R n`` for each approach direction ``n``."""
        S, D = len(self.centres_m), len(self.directions)
        pts = (self.centres_m[:, None, :] + self.radius_m * self.directions[None, :, :]).reshape(-1, 3)
        stations = np.repeat(np.arange(S), D)
        return Candidates(points_m=pts, stations=stations, groups=np.arange(S * D))
