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
#: Most random points one call of ``sample`` draws (3·10⁸ floats: 2.4 GB).
MAX_SAMPLES = 100_000_000


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
        values.generator("rng", rng)
        count = values.count("count", count, high=MAX_SAMPLES)
        if self.kind == "points":
            g = self.grid()
            return g[rng.integers(0, len(g), size=count)]
        r = self.radius_m * np.sqrt(rng.random(count))
        a = 2.0 * np.pi * rng.random(count)
        z = rng.uniform(*self.z_range_m, size=count)
        cx, cy = self.center_xy_m
        return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a), z])


@dataclass(frozen=True)
class ToolDirections:
    """The tool orientations of a hybrid machine's task (``task.kind = "tool"``): a cone of axes.

    The tool axis (unit vector in K, from the spindle towards the tool tip) must reach every
    direction within ``half_angle_rad`` of ``axis``. The grid is the cone's axis, then rings of
    ``rings[k]`` directions at the angle ``half_angle_rad·(k+1)/len(rings)`` from it (the spin
    about the tool axis is free, so a direction is a whole orientation of the task).

    Attributes:
        axis: Unit vector (3,) in K: the cone's axis.
        half_angle_rad: The cone's half-angle [rad] (0: one direction).
        rings: Directions per ring, inner to outer (empty: the axis only).
    """

    axis: tuple[float, float, float]
    half_angle_rad: float = 0.0
    rings: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        """Check the fields (InvalidArgumentError naming the first wrong one); normalise the axis."""
        a = values.vector("ToolDirections.axis", self.axis, 3)
        norm = float(np.linalg.norm(a))
        if not norm > 1e-12:
            raise InvalidArgumentError("ToolDirections.axis", self.axis, "expected a non-zero [x, y, z] in K")
        angle = values.number("ToolDirections.half_angle_rad", self.half_angle_rad)
        if not 0.0 <= angle < np.pi / 2:
            raise InvalidArgumentError(
                "ToolDirections.half_angle_rad", angle, "the cone's half-angle must be in [0, 90°)"
            )
        if isinstance(self.rings, str) or not isinstance(self.rings, tuple | list):
            raise InvalidArgumentError(
                "ToolDirections.rings", self.rings, "expected directions per ring, e.g. (6,)"
            )
        for k in self.rings:
            values.count("ToolDirections.rings", k, low=1)
        if self.rings and angle == 0.0:
            raise InvalidArgumentError(
                "ToolDirections.rings", self.rings, "rings need a cone half-angle > 0 (task.cone)"
            )
        object.__setattr__(self, "axis", tuple(float(x) for x in a / norm))
        object.__setattr__(self, "half_angle_rad", float(angle))
        object.__setattr__(self, "rings", tuple(int(k) for k in self.rings))

    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The axis and two unit vectors orthogonal to it (a right-handed frame)."""
        a = np.asarray(self.axis)
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        u = np.cross(a, helper)
        u /= np.linalg.norm(u)
        return a, u, np.cross(a, u)

    def grid(self) -> np.ndarray:
        """Directions (k, 3), unit vectors in K: the axis, then each ring."""
        a, u, v = self._frame()
        out = [a]
        for k, count in enumerate(self.rings):
            t = self.half_angle_rad * (k + 1) / len(self.rings)
            for i in range(count):
                phi = 2.0 * np.pi * i / count
                out.append(np.cos(t) * a + np.sin(t) * (np.cos(phi) * u + np.sin(phi) * v))
        return np.array(out)

    def sample(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """Directions (count, 3) uniformly distributed over the cone's cap of the unit sphere."""
        values.generator("rng", rng)
        count = values.count("count", count, high=MAX_SAMPLES)
        a, u, v = self._frame()
        c = 1.0 - rng.random(count) * (1.0 - np.cos(self.half_angle_rad))
        s = np.sqrt(np.clip(1.0 - c * c, 0.0, None))
        phi = 2.0 * np.pi * rng.random(count)
        return c[:, None] * a + s[:, None] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
