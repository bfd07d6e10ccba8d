"""Drawing helpers of the 3D scene: node registry, transforms, rods, triads, limb skeletons, camera reach."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.design.job import DesignResult
from pkmtol.present.viewer.backend import require_meshcat
from pkmtol.present.viewer.colours import hex_colour

#: Documented API of this module (the other names serve the scene's own modules).
__all__ = ["skeleton_geometry"]


@dataclass
class Scene:
    """Bookkeeping while drawing."""

    vis: Any
    nodes: list[str] = field(default_factory=list)

    def node(self, path: str) -> Any:
        """The meshcat node at ``path``, recorded as drawn."""
        self.nodes.append(path)
        return self.vis[path]


def translation(p: Sequence[float] | np.ndarray) -> np.ndarray:
    """Homogeneous transform (4, 4) of a pure translation ``p`` [m]."""
    t = np.eye(4)
    t[:3, 3] = np.asarray(p, dtype=float)
    return t


def rod_transform(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Transform placing meshcat's unit cylinder (axis y, centred) from ``a`` to ``b``."""
    d = np.asarray(b, float) - np.asarray(a, float)
    length = float(np.linalg.norm(d))
    y = d / length if length > 0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2] = x, y, z
    t[:3, 3] = (np.asarray(a, float) + np.asarray(b, float)) / 2
    return t


def rod(scene: Scene, path: str, a: np.ndarray, b: np.ndarray, radius: float, rgb: Any) -> None:
    """A cylinder of ``radius`` [m] from ``a`` to ``b`` (frame of ``path``'s parent)."""
    g = require_meshcat().geometry
    length = max(float(np.linalg.norm(np.asarray(b) - np.asarray(a))), 1e-9)
    node = scene.node(path)
    node.set_object(g.Cylinder(length, radius), g.MeshLambertMaterial(color=hex_colour(rgb)))
    node.set_transform(rod_transform(a, b))


def triad(scene: Scene, path: str, placement: pin.SE3, length: float, radius: float) -> None:
    """Three rods (x red, y green, z blue) at ``placement``; ``path`` gets the placement."""
    g = require_meshcat().geometry
    scene.node(path).set_transform(placement.homogeneous)
    for axis, rgb in zip("xyz", ((0.9, 0.1, 0.1), (0.1, 0.7, 0.1), (0.1, 0.2, 0.9)), strict=True):
        e = np.zeros(3)
        e["xyz".index(axis)] = length
        node = scene.node(f"{path}/{axis}")
        node.set_object(g.Cylinder(length, radius), g.MeshLambertMaterial(color=hex_colour(rgb)))
        node.set_transform(rod_transform(np.zeros(3), e))


def skeleton_geometry(model: pin.Model, radius: float = 0.02) -> pin.GeometryModel:
    """Build a visual model for a limb without one: a ball per joint, a rod to each joint."""
    import coal

    gm = pin.GeometryModel()
    grey = np.array([0.55, 0.55, 0.6, 1.0])
    for j in range(1, model.njoints):
        ball = pin.GeometryObject(f"joint{j}", j, pin.SE3.Identity(), coal.Sphere(1.5 * radius))
        ball.meshColor = grey
        gm.addGeometryObject(ball)
        offset = model.jointPlacements[j].translation
        length = float(np.linalg.norm(offset))
        if length > 1e-9:
            # rod from the parent joint's origin to this joint's, placed in the parent joint
            rod_t = rod_transform(np.zeros(3), offset)
            # coal's cylinder axis is z; meshcat's is y: rotate y → z
            rot = np.eye(4)
            rot[:3, :3] = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
            placement = pin.SE3(rod_t @ np.linalg.inv(rot))
            rod = pin.GeometryObject(f"rod{j}", model.parents[j], placement, coal.Cylinder(radius, length))
            rod.meshColor = grey
            gm.addGeometryObject(rod)
    return gm


def camera_direction(result: DesignResult) -> tuple[np.ndarray, float]:
    """Return the unit vector from the origin to the default camera, and the scene's reach [m]."""
    pts = np.vstack([result.grid.points_m, np.zeros((1, 3))])
    reach = float(np.max(np.linalg.norm(pts, axis=1)))
    d = np.array([0.8, -1.3, 1.9])
    return d / np.linalg.norm(d), reach
