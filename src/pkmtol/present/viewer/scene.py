"""``build_scene``: a design drawn into a ``meshcat.Visualizer``, layer by layer (see the package)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pkmtol.design.job import DesignResult
from pkmtol.present.viewer.backend import require_meshcat
from pkmtol.present.viewer.geometry import (
    Bounds,
    Scene,
    camera_direction,
    framing_distance,
    ground_grid,
    mechanism_points,
    scene_bounds,
    translation,
)
from pkmtol.present.viewer.layers import (
    SpheresLayer,
    VerificationLayer,
    draw_reference,
    draw_robot,
    draw_spheres,
    draw_verification,
)
from pkmtol.present.viewer.legend import draw_legend, legend_lines
from pkmtol.present.viewer.options import ROOT, SceneOptions


@dataclass(frozen=True, eq=False)
class SceneSummary:
    """What :func:`build_scene` drew.

    Attributes:
        root: meshcat path of everything pkmtol drew (``/meshcat/pkmtol``).
        layers: Layer name → its meshcat path relative to ``/meshcat`` (``pkmtol/<layer>``), for
            the layers drawn (``SceneOptions.layers``).
        worst_index: Grid index of the design point (the most error-sensitive pose, at which the
            mechanism is drawn).
        worst_point_m: Shape (3,): the design point P, frame K [m].
        animation_frames: Number of frames of the (paused) animation through the task-space grid
            (0 without the robot layer or with ``animate=False``).
        robot_paths: meshcat path of each limb (``pkmtol/robot/<limb>``, relative to
            ``/meshcat``), in the mechanism's limb order; empty without the robot layer.
        spheres: The error spheres; None without the ``error_spheres`` layer.
        verification: The verification cloud and samples; None without the ``verification``
            layer.
        legend: The legend, one line per entry (drawn in the ``legend`` layer and overlaid on an
            exported page; computed even when that layer is off).
        nodes: Every node path drawn, relative to ``/meshcat``, without duplicates, in drawing
            order.
        bounds: The box around the mechanism (design pose) and the task-space grid that the
            camera frames.
        offset_m: Shape (3,): the translation of the ``pkmtol`` node: everything pkmtol draws is
            shifted by it, so that the box's centre sits at meshcat's origin, which its orbit
            controls always look at (a point ``p`` of K is drawn at ``p + offset_m``).
        camera_m: Shape (3,): the default camera's position relative to the box's centre (K axes).
        ground: ``(z [m], spacing [m])`` of the ground grid in K; None without the ``ground`` layer.
        links_m: Per limb (mechanism order), its link rods at the design pose, joint frame to joint
            frame (shape (k, 2, 3): start and end, frame K [m]; drawn at
            ``pkmtol/robot/<limb>/links/<k>``); empty without the robot layer.

    """

    root: str
    layers: dict[str, str]
    worst_index: int
    worst_point_m: np.ndarray
    animation_frames: int
    robot_paths: tuple[str, ...]
    spheres: SpheresLayer | None
    verification: VerificationLayer | None
    legend: tuple[str, ...]
    nodes: tuple[str, ...]
    bounds: Bounds | None = None
    offset_m: np.ndarray | None = None
    camera_m: np.ndarray | None = None
    ground: tuple[float, float] | None = None
    links_m: tuple[np.ndarray, ...] = ()


def _set_camera(vis: Any, result: DesignResult, bounds: Bounds, margin: float) -> np.ndarray:
    """Frame the mechanism and the task space: the camera as close as sees them all, at the box's centre.

    ``margin``: room for the error spheres around the grid points [m].

    meshcat 0.3's orbit controls always look at meshcat's origin; the ``pkmtol`` node is shifted
    so that the box's centre is there (:func:`build_scene`). Returns the camera position relative
    to the centre (K axes) [m].
    """
    c, _ = camera_direction(result)
    points = np.vstack([mechanism_points(result), result.grid.points_m])
    d = c * framing_distance(points, bounds.centre, c, margin)
    # the camera's position is in meshcat's y-up frame: (x, z_up, -y)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [d[0], d[2], -d[1]])
    return d


def build_scene(result: DesignResult, vis: Any, options: SceneOptions | None = None) -> SceneSummary:
    """Draw a design into ``vis`` (a ``meshcat.Visualizer``); see the module docstring.

    Args:
        result: The design to draw.
        vis: A ``meshcat.Visualizer``; everything is drawn under its ``pkmtol`` path, which is
            cleared first.
        options: What to draw and how (default: :class:`SceneOptions`).

    Returns:
        What was drawn: paths, the error spheres' scale and colours, the verification counts, the
        legend (:class:`SceneSummary`; the layer fields are None for layers not drawn).

    Raises:
        ViewerError: meshcat is missing.

    """
    require_meshcat()
    opt = options or SceneOptions()
    scene = Scene(vis)
    vis[ROOT].delete()
    bounds = scene_bounds(result)
    offset = -bounds.centre
    vis[ROOT].set_transform(translation(offset))
    # meshcat's own grid and axes sit at its origin, now the middle of the scene: the ground grid
    # below the base replaces them
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    ground = ground_grid(scene, f"{ROOT}/ground", bounds) if "ground" in opt.layers else None
    if opt.background_rgb is not None:
        vis["/Background"].set_property("top_color", list(opt.background_rgb))
        vis["/Background"].set_property("bottom_color", list(opt.background_rgb))
    # reference first: the robot's animation keys its nodes
    if "reference" in opt.layers:
        draw_reference(scene, result)
    robot_paths: list[str] = []
    frames = 0
    links: tuple[np.ndarray, ...] = ()
    if "robot" in opt.layers:
        robot_paths, frames, links = draw_robot(scene, result, opt.animate, "reference" in opt.layers)
    spheres = draw_spheres(scene, result, opt) if "error_spheres" in opt.layers else None
    rmax = spheres.max_radius_m if spheres is not None else 0.0
    verification = draw_verification(scene, result, opt, rmax) if "verification" in opt.layers else None
    legend = legend_lines(result, spheres, verification)
    if "legend" in opt.layers:
        draw_legend(scene, result, legend, "error_spheres" in opt.layers, bounds)
    camera = _set_camera(vis, result, bounds, 1.5 * rmax) if opt.camera else None
    return SceneSummary(
        root=f"{vis.path.lower()}/{ROOT}",
        layers={name: f"{ROOT}/{name}" for name in opt.layers},
        worst_index=int(result.worst_index),
        worst_point_m=np.asarray(result.worst_point_m, dtype=float),
        animation_frames=frames,
        robot_paths=tuple(robot_paths),
        spheres=spheres,
        verification=verification,
        legend=tuple(legend),
        nodes=tuple(dict.fromkeys(scene.nodes)),
        bounds=bounds,
        offset_m=offset,
        camera_m=camera,
        ground=ground,
        links_m=links,
    )
