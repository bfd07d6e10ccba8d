"""Task spaces: where the reference point P must reach, as a grid and as a sampling volume."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TaskSpace:
    """A task space of the reference point P, expressed in the base frame K.

    Either a vertical cylinder (axis parallel to z through ``center_xy_m``) gridded as
    ``layers`` z-levels, each with a centre point and rings of ``rings[k]`` points at radius
    ``radius_m·(k+1)/len(rings)`` (the paper's 147 = 3 × (1 + 8 + 16 + 24)); or an explicit list
    of points.

    Attributes:
        kind: ``"cylinder"`` or ``"points"``.
        radius_m: Cylinder radius [m].
        z_range_m: ``(z_min, z_max)`` of the cylinder [m].
        layers: Number of z-levels of the grid.
        rings: Points per ring, inner to outer.
        center_xy_m: Cylinder axis position ``(x, y)`` [m].
        points_m: Explicit points, shape (m, 3) [m] (kind ``"points"``).
    """

    kind: str
    radius_m: float = 0.0
    z_range_m: tuple[float, float] = (0.0, 0.0)
    layers: int = 1
    rings: tuple[int, ...] = ()
    center_xy_m: tuple[float, float] = (0.0, 0.0)
    points_m: np.ndarray | None = None

    def grid(self) -> np.ndarray:
        """Grid points, shape (m, 3) [m] in K: per layer (bottom to top) centre then rings."""
        if self.kind == "points":
            assert self.points_m is not None
            return np.asarray(self.points_m, dtype=float)
        zs = np.linspace(*self.z_range_m, self.layers) if self.layers > 1 else [np.mean(self.z_range_m)]
        cx, cy = self.center_xy_m
        pts = []
        for z in zs:
            pts.append((cx, cy, z))
            for k, count in enumerate(self.rings):
                r = self.radius_m * (k + 1) / len(self.rings)
                for i in range(count):
                    a = 2.0 * np.pi * i / count
                    pts.append((cx + r * np.cos(a), cy + r * np.sin(a), z))
        return np.array(pts, dtype=float)

    def on_rim(self) -> np.ndarray:
        """Boolean mask over :meth:`grid`: points on the outer boundary (outermost ring).

        For an explicit point list, the points farthest from the list's centroid axis.
        """
        g = self.grid()
        if self.kind == "points":
            r = np.linalg.norm(g[:, :2] - g[:, :2].mean(axis=0), axis=1)
        else:
            r = np.linalg.norm(g[:, :2] - np.asarray(self.center_xy_m), axis=1)
        return np.asarray(r >= r.max() - 1e-9)

    def sample(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """Random points uniformly distributed over the task space, shape (count, 3) [m].

        A cylinder is sampled uniformly in volume; an explicit list by drawing its points with
        replacement.
        """
        if self.kind == "points":
            g = self.grid()
            return g[rng.integers(0, len(g), size=count)]
        r = self.radius_m * np.sqrt(rng.random(count))
        a = 2.0 * np.pi * rng.random(count)
        z = rng.uniform(*self.z_range_m, size=count)
        cx, cy = self.center_xy_m
        return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a), z])
