"""``ballbar``: a double ballbar (ISO 230-4) between a ball at the tool point and a ball on the table.

The table ball of each set-up (a *station*: one circle) sits at a nominal centre ``c_s``; its true
position in the circle's plane is identified with the machine (2 nuisance parameters per circle;
its height above the plane changes every reading by ``h²/2R`` only, 0.13 µm at 0.2 mm on a 150 mm
bar, so no data can see it: it is taken as set up). The
machine moves P on a circle of radius ``R`` (the bar's length) about ``c_s`` in one of the planes
xy, yz or zx, and the ballbar reads the distance ``‖P − c_s − π_s‖`` (:mod:`.distance`), with
independent Gaussian noise σ per reading (default 1 µm: a Renishaw QC20-W's accuracy is
±(0.7 + 0.3 %·Δ) µm, plus set-up and thermal drift).

The plan chooses whole circles (:class:`~.base.Candidates` groups) from candidate circles: every
centre of ``stations_m`` (default: the task space's centre and four points at half its radius, at
mid-height) in every plane of ``circle_planes``, ``circle_points`` readings per circle (points the
mechanism cannot reach are left out: the circle becomes an arc).

CSV: ``pose,<actuated joints>…,station,d [mm]``, one row per reading; ``station`` is the circle's
index in the plan (:mod:`pkmtol.calibration.instrument_files`).
"""

from __future__ import annotations

import numpy as np

from pkmtol.calibration.instruments.base import Candidates
from pkmtol.calibration.instruments.distance import StationDistance
from pkmtol.exceptions import InvalidRequestError

PLANES = {"xy": (0, 1), "yz": (1, 2), "zx": (2, 0)}


class Ballbar(StationDistance):
    """A ballbar of length ``radius_m`` on circles about the given centres.

    Args:
        point_m: Shape (3,): the spindle ball in the platform frame (P) [m].
        circles: ``((centre (3,), plane), …)``: each circle's nominal table-ball position [m] and plane.
        radius_m: The bar's length = the circles' radius [m].
        points_per_circle: Readings per circle.
        noise_m: σ per reading [m].
        centre_sigma_m: Expected offset of a table ball from its nominal centre [m].

    Raises:
        InvalidRequestError: an unknown plane, a radius ≤ 0, or fewer than 4 points per circle.
    """

    name = "ballbar"

    def __init__(
        self,
        point_m: np.ndarray,
        circles: tuple[tuple[np.ndarray, str], ...],
        radius_m: float,
        points_per_circle: int,
        noise_m: float,
        centre_sigma_m: float = 2e-4,
    ) -> None:
        for _, plane in circles:
            if plane not in PLANES:
                raise InvalidRequestError(f"unknown circle plane {plane!r}; use one of {', '.join(PLANES)}")
        if not radius_m > 0 or not np.isfinite(radius_m):
            raise InvalidRequestError(f"the ballbar length must be > 0, got {radius_m!r} m")
        if points_per_circle < 4:
            raise InvalidRequestError(f"a circle needs ≥ 4 readings, got {points_per_circle}")
        self.planes = tuple(p for _, p in circles)
        self.radius_m = float(radius_m)
        self.points_per_circle = int(points_per_circle)
        axes = np.array([np.eye(3)[list(PLANES[p])] for p in self.planes])
        super().__init__(point_m, np.array([c for c, _ in circles]), noise_m, centre_sigma_m, "ball", axes)

    def candidates(self, task_points: np.ndarray, rng: np.random.Generator) -> Candidates:
        """Every circle's readings: P at ``c_s + R (cos θ e₁ + sin θ e₂)``, θ every 360°/points."""
        pts, st = [], []
        theta = 2 * np.pi * np.arange(self.points_per_circle) / self.points_per_circle
        for s, (c, plane) in enumerate(zip(self.centres_m, self.planes, strict=True)):
            a, b = PLANES[plane]
            p = np.repeat(c[None, :], theta.size, axis=0)
            p[:, a] += self.radius_m * np.cos(theta)
            p[:, b] += self.radius_m * np.sin(theta)
            pts.append(p)
            st += [s] * theta.size
        stations = np.array(st, dtype=int)
        return Candidates(points_m=np.concatenate(pts), stations=stations, groups=stations.copy())
