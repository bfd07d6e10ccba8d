"""Drawing helpers of the 3D scene: node registry, transforms, rods, triads, skeletons, framing, ground."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.design.job import DesignResult
from pkmtol.present.viewer.backend import require_meshcat
from pkmtol.present.viewer.colours import GROUND_RGB, hex_colour

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


#: Direction from the scene's centre to the default camera (frame K, before normalising): in front
#: of the mechanism, to the right, and above.
CAMERA_DIRECTION = np.array([0.8, -1.3, 1.9])
#: Vertical field of view of meshcat's default camera [deg] (three.js PerspectiveCamera(75, …)).
CAMERA_FOV_DEG = 75.0


@dataclass(frozen=True)
class Bounds:
    """The axis-aligned bounding box of what the camera must frame (frame K) [m].

    Attributes:
        low: Shape (3,): its lower corner.
        high: Shape (3,): its upper corner.
        base_z_m: The lowest joint of the mechanism (where the ground grid goes below).
    """

    low: np.ndarray
    high: np.ndarray
    base_z_m: float

    @property
    def centre(self) -> np.ndarray:
        """Shape (3,): the box's centre."""
        return (self.low + self.high) / 2

    @property
    def radius(self) -> float:
        """Half the box's diagonal (the radius of a sphere around it)."""
        return float(np.linalg.norm(self.high - self.low) / 2)


def mechanism_points(result: DesignResult) -> np.ndarray:
    """Shape (k, 3): every joint, platform frame and P of the mechanism at the design pose (K) [m]."""
    pose = result.grid.poses[result.worst_index]
    pts = [np.asarray(pose.p_m, dtype=float), pose.oMp.translation]
    for limb, q in zip(result.mechanism.limbs, pose.q, strict=True):
        data = limb.model.createData()
        pin.forwardKinematics(limb.model, data, np.asarray(q, dtype=float))
        pts.extend(data.oMi[j].translation for j in range(1, limb.model.njoints))
    return np.array(pts)


def scene_size(result: DesignResult) -> float:
    """The size of the mechanism at the design pose: the diagonal of the box around its joints [m]."""
    pts = mechanism_points(result)
    return max(float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))), 1e-3)


def scene_bounds(result: DesignResult) -> Bounds:
    """The box around the mechanism at the design pose and the task-space grid (the camera frames it)."""
    mech = mechanism_points(result)
    pts = np.vstack([mech, result.grid.points_m])
    low, high = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * max(float(np.linalg.norm(high - low)), 1e-3)
    return Bounds(low=low - pad, high=high + pad, base_z_m=float(mech[:, 2].min()))


def camera_direction(result: DesignResult) -> tuple[np.ndarray, float]:
    """Return the unit vector from the scene's centre to the default camera, and the scene's radius [m]."""
    d = CAMERA_DIRECTION / np.linalg.norm(CAMERA_DIRECTION)
    return d, scene_bounds(result).radius


def camera_distance(radius: float) -> float:
    """Distance from the centre at which a sphere of ``radius`` fills the vertical field of view."""
    return 1.05 * radius / float(np.sin(np.radians(CAMERA_FOV_DEG / 2)))


#: The box's corners stay within this fraction of the half field of view (a margin at the edge).
FRAME_FILL = 0.92


def framing_distance(points: np.ndarray, centre: np.ndarray, direction: np.ndarray, margin: float) -> float:
    """The closest camera distance along ``direction`` (from ``centre``) at which every point is in view.

    The camera looks at ``centre`` with z up. A point ``c`` (relative to the centre) is at depth
    ``t − c·d`` and at ``(c·r, c·u)`` across the image (``r``, ``u``: the image's right and up
    axes); it is in view when both ``|c·r| + margin`` and ``|c·u| + margin`` are at most
    ``FRAME_FILL · tan(FOV/2)`` times its depth (the vertical field of view in both directions: a
    square window at worst). Framing the points themselves, not the sphere around their box
    (:func:`camera_distance`), lets the mechanism fill more of the view.

    Args:
        points: Shape (n, 3): what must be seen (frame K) [m].
        centre: Shape (3,): where the camera looks (frame K) [m].
        direction: Shape (3,): from the centre towards the camera (normalised here).
        margin: Added to each point's distance across the image (a glyph's radius) [m].
    """
    d = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    right = np.cross(-d, np.array([0.0, 0.0, 1.0]))
    right /= np.linalg.norm(right)
    up = np.cross(right, -d)
    rel = np.asarray(points, dtype=float) - np.asarray(centre, dtype=float)
    reach = FRAME_FILL * float(np.tan(np.radians(CAMERA_FOV_DEG / 2)))
    across = np.maximum(np.abs(rel @ right), np.abs(rel @ up)) + margin
    return float(np.max(rel @ d + across / reach))


def nice_step(length: float, lines: int = 10) -> float:
    """A round grid spacing (1, 2 or 5 × 10ᵏ) giving about ``lines`` lines over ``length``.

    >>> nice_step(1.7), nice_step(0.04)
    (0.2, 0.005)
    """
    raw = max(length, 1e-9) / lines
    k = np.floor(np.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10**k >= raw:
            return float(round(m * 10**k, 12))
    raise AssertionError  # unreachable


def ground_grid(scene: Scene, path: str, bounds: Bounds) -> tuple[float, float]:
    """Line grid in the plane just below the base, over the box's footprint; returns (z, spacing) [m]."""
    g = require_meshcat().geometry
    size = bounds.high - bounds.low
    step = nice_step(float(max(size[0], size[1])))
    z = bounds.base_z_m - 0.02 * bounds.radius
    lo = np.floor(bounds.low[:2] / step) * step - step
    hi = np.ceil(bounds.high[:2] / step) * step + step
    xs = np.arange(lo[0], hi[0] + step / 2, step)
    ys = np.arange(lo[1], hi[1] + step / 2, step)
    seg = [((x, lo[1], z), (x, hi[1], z)) for x in xs] + [((lo[0], y, z), (hi[0], y, z)) for y in ys]
    pos = np.asarray(seg, dtype=np.float32).reshape(-1, 3).T
    node = scene.node(path)
    node.set_object(g.LineSegments(g.PointsGeometry(pos), g.LineBasicMaterial(color=hex_colour(GROUND_RGB))))
    return float(z), step
