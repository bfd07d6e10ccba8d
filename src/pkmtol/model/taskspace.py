"""Task spaces: where the reference point P must reach, as a grid and as a sampling volume."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError

#: Task-space kinds.
KINDS = ("cylinder", "points")
#: Most grid points a task space may have (each costs an inverse kinematics and a separation).
MAX_GRID_POINTS = 1_000_000


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

    def __post_init__(self) -> None:
        """Check every field (raises InvalidArgumentError naming it); store tuples and arrays."""
        values.choice("TaskSpace.kind", self.kind, KINDS)
        if self.kind == "points":
            if self.points_m is None:
                raise InvalidArgumentError(
                    "TaskSpace.points_m", None, "kind 'points' needs points_m, an array of shape (m, 3) [m]"
                )
            pts = values.array("TaskSpace.points_m", self.points_m, ndim=2)
            values.within_length("TaskSpace.points_m", pts)
            if pts.shape[1:] != (3,) or len(pts) == 0:
                raise InvalidArgumentError(
                    "TaskSpace.points_m", self.points_m, f"need [x, y, z] points, got shape {pts.shape}"
                )
            if len(pts) > MAX_GRID_POINTS:
                raise InvalidArgumentError(
                    "TaskSpace.points_m", f"{len(pts)} points", f"at most {MAX_GRID_POINTS} are allowed"
                )
            object.__setattr__(self, "points_m", pts)
            return
        if self.points_m is not None:
            raise InvalidArgumentError(
                "TaskSpace.points_m", "an array", "only kind 'points' takes points; use kind='points'"
            )
        values.within_length(
            "TaskSpace.radius_m", values.number("TaskSpace.radius_m", self.radius_m, positive=True)
        )
        z = values.within_length(
            "TaskSpace.z_range_m", values.vector("TaskSpace.z_range_m", self.z_range_m, 2)
        )
        if z[1] < z[0]:
            raise InvalidArgumentError("TaskSpace.z_range_m", self.z_range_m, "write it as (z_min, z_max)")
        values.count("TaskSpace.layers", self.layers, low=1)
        rings = self.rings
        if isinstance(rings, str) or not isinstance(rings, tuple | list) or not rings:
            raise InvalidArgumentError("TaskSpace.rings", rings, "expected points per ring, e.g. (8, 16, 24)")
        for k in rings:
            values.count("TaskSpace.rings", k, low=1)
        center = values.within_length(
            "TaskSpace.center_xy_m", values.vector("TaskSpace.center_xy_m", self.center_xy_m, 2)
        )
        n = int(self.layers) * (1 + sum(int(k) for k in rings))
        if n > MAX_GRID_POINTS:
            raise InvalidArgumentError("TaskSpace.rings", rings, f"{n} grid points (max {MAX_GRID_POINTS})")
        object.__setattr__(self, "radius_m", float(self.radius_m))
        object.__setattr__(self, "z_range_m", (float(z[0]), float(z[1])))
        object.__setattr__(self, "rings", tuple(int(k) for k in rings))
        object.__setattr__(self, "center_xy_m", (float(center[0]), float(center[1])))

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
