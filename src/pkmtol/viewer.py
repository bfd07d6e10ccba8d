"""3D inspection of a design in meshcat (the paper's Figs. 7 and 9 in one scene).

:func:`build_scene` draws a :class:`~pkmtol.design.DesignResult` into a ``meshcat.Visualizer``;
:func:`export_html` writes it as one self-contained HTML page; :func:`show` serves it live.
They return what they drew as frozen dataclasses: :class:`SceneSummary` (with a
:class:`SpheresLayer` and a :class:`VerificationLayer` when those layers are drawn) and
:class:`HtmlExport`.
Every layer has its own meshcat path (under ``/meshcat``) so it can be hidden from the viewer's
"Open Controls" panel:

``pkmtol/robot/<limb>``
    Each limb's URDF visuals through Pinocchio's ``MeshcatVisualizer`` (one visualizer per limb,
    all sharing one ``meshcat.Visualizer``), posed at the most error-sensitive pose (the design
    point, ``result.grid.poses[result.worst_index]``). A limb without visuals (built from a bare
    ``pin.Model``) is drawn as a skeleton: a ball at every joint, a rod between joints. A
    key-framed animation (paused; play it from the controls' "Animations" folder) moves the whole
    mechanism through every task-space grid point, starting at the design point.
``pkmtol/error_spheres/<k>``
    One sphere per task-space grid point ``k`` (the paper's Fig. 7), centred at the grid point,
    **radius = scale · σ[Δλ_k]** where σ[Δλ_k] is the standard deviation of the accuracy index at
    that point. By default (``sigma="search"``) it is the paper's sensitive-pose-search quantity:
    every uncompensatable error ``η_c ~ N(0, 1)`` (1 m or 1 rad), so σ is in metres per unit error
    and the largest sphere is the design point; with ``sigma="design"`` the errors are
    ``N(0, σ_i²)`` at the design-β tolerances and σ is in metres. ``scale`` makes the largest
    sphere ``max_sphere_radius_m`` (default: 0.35 × the smallest distance between two grid
    points, so that spheres never touch); it is returned (``SceneSummary.spheres``, a
    :class:`SpheresLayer`: ``radius_per_sigma``), written in the legend and set as the property
    ``pkmtol_radius_per_sigma`` of the layer node. Colour: viridis over [min σ, max σ] (dark
    purple = least, yellow = most sensitive).
``pkmtol/verification/...``
    The Monte Carlo verification (the paper's Fig. 9). ``cloud/safe`` and ``cloud/failed``:
    position-error vectors ``Δp = J η_c`` of P at the design point for ``cloud_samples`` draws of
    η_c from the verification distribution (default Gaussian) at the design-β tolerances,
    magnified by ``cloud_radius_m / Δλ*`` and drawn around the transparent ``cloud/target`` sphere
    of radius ``cloud_radius_m`` (= Δλ*, magnified): a point is green when ``‖Δp‖ ≤ Δλ*`` and
    red otherwise. The cloud is centred just outside the task space, radially out from the
    design point (a thin rod joins the two), so that it does not hide the mechanism.
    ``task_space/safe`` and ``task_space/failed``: every sample of the actual verification run
    (``result.verification[distribution]``, random poses over the task space) at its task-space
    point, red if its Δλ > Δλ* (the green ones are hidden at first: thousands of dots would
    hide the spheres; tick ``visible`` in the controls, or set ``show_safe_samples``).
``pkmtol/reference``
    ``P``: the reference point (magenta ball) at the design pose; ``platform_frame``: a triad
    (x red, y green, z blue) at the platform frame O'; ``offset``: the rod O'→P.
``pkmtol/legend``
    A panel with the scales and the colour bar (also overlaid on the exported HTML page).

The meshcat server started here (:class:`MeshcatServer`) listens on 127.0.0.1 only — meshcat's
own ``meshcat.Visualizer()`` server binds its HTTP port on every interface — and is stopped
(killed and reaped) when the export ends, the ``with`` block exits, or the Python process exits;
it also exits by itself if its parent process dies.
"""

from __future__ import annotations

import atexit
import contextlib
import html as html_lib
import io
import os
import select
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.design import DesignResult
from pkmtol.exceptions import OutputError, PkmtolError
from pkmtol.files import write_atomic
from pkmtol.montecarlo import DISTRIBUTIONS, sample_errors
from pkmtol.reliability import grid_norm_moments

#: Root of everything pkmtol draws, below meshcat's ``/meshcat``.
ROOT = "pkmtol"
#: The layers, each its own meshcat path ``pkmtol/<layer>``.
LAYERS = ("robot", "error_spheres", "verification", "reference", "legend")

# viridis at 9 equally spaced stops (matplotlib's table; no matplotlib needed here)
_VIRIDIS = np.array(
    [
        (0.267, 0.005, 0.329),
        (0.279, 0.175, 0.483),
        (0.230, 0.322, 0.546),
        (0.173, 0.449, 0.558),
        (0.128, 0.567, 0.551),
        (0.158, 0.684, 0.502),
        (0.369, 0.789, 0.383),
        (0.678, 0.864, 0.190),
        (0.993, 0.906, 0.144),
    ]
)
SAFE_RGB = (0.10, 0.65, 0.25)
FAILED_RGB = (0.85, 0.10, 0.10)
P_RGB = (0.85, 0.0, 0.85)
BACKGROUND_RGB = (1.0, 1.0, 1.0)


class ViewerError(PkmtolError):
    """The 3D viewer cannot run: meshcat is missing, or its server did not start."""


def _meshcat() -> Any:
    """Import meshcat or raise :class:`ViewerError` with what to do."""
    try:
        import meshcat
        import meshcat.geometry  # noqa: F401
        import meshcat.transformations  # noqa: F401
    except ImportError as err:  # pragma: no cover - meshcat is a dependency
        raise ViewerError(
            f"the 3D viewer needs meshcat ({err}); install it with `pip install meshcat` "
            "(it is a dependency of pkmtol: `pip install pkmtol` brings it)"
        ) from err
    return meshcat


def viridis(t: np.ndarray) -> np.ndarray:
    """Viridis colours for values ``t`` in [0, 1], shape (..., 3) RGB in [0, 1]."""
    t = np.clip(np.asarray(t, dtype=float), 0.0, 1.0)
    x = np.linspace(0.0, 1.0, len(_VIRIDIS))
    return np.stack([np.interp(t, x, _VIRIDIS[:, c]) for c in range(3)], axis=-1)


def _hex(rgb: Sequence[float]) -> int:
    r, g, b = (int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


@dataclass(frozen=True)
class SceneOptions:
    """What :func:`build_scene` draws and how.

    Attributes:
        sigma: ``"search"`` (η_c ~ N(0, 1), the paper's Fig. 7) or ``"design"`` (η_c at the
            design-β tolerances) for the error spheres.
        max_sphere_radius_m: Radius of the largest error sphere [m] (None: 0.35 × the smallest
            distance between two grid points).
        sphere_opacity: Opacity of the error spheres (1: opaque; below, the mechanism shows
            through).
        distribution: Verification distribution drawn (one of ``montecarlo.DISTRIBUTIONS``).
        cloud_radius_m: Drawn radius of the Δλ* sphere of the verification cloud [m]
            (magnification = ``cloud_radius_m / Δλ*``).
        cloud_samples: Number of error vectors in the verification cloud.
        show_safe_samples: Show the safe task-space verification samples at first (they are
            always drawn; the viewer's controls toggle them).
        animate: Add the (paused) animation through the task-space grid.
        layers: Layers to draw (subset of :data:`LAYERS`).
        camera: Set the default camera to frame the mechanism.
        background_rgb: Background colour (None: meshcat's default gradient).
        seed: Random seed of the verification cloud.

    """

    sigma: str = "search"
    max_sphere_radius_m: float | None = None
    distribution: str = "gaussian"
    sphere_opacity: float = 0.75
    cloud_radius_m: float = 0.15
    cloud_samples: int = 2000
    show_safe_samples: bool = False
    animate: bool = True
    layers: tuple[str, ...] = LAYERS
    camera: bool = True
    background_rgb: tuple[float, float, float] | None = BACKGROUND_RGB
    seed: int = 0

    def __post_init__(self) -> None:
        from pkmtol.exceptions import InvalidRequestError

        if self.sigma not in ("search", "design"):
            raise InvalidRequestError(f"sigma must be 'search' or 'design', got {self.sigma!r}")
        if self.distribution not in DISTRIBUTIONS:
            raise InvalidRequestError(
                f"distribution must be one of {', '.join(DISTRIBUTIONS)}, got {self.distribution!r}"
            )
        unknown = set(self.layers) - set(LAYERS)
        if unknown:
            raise InvalidRequestError(f"unknown layers {sorted(unknown)}; choose from {', '.join(LAYERS)}")
        if self.max_sphere_radius_m is not None and not self.max_sphere_radius_m > 0:
            raise InvalidRequestError("max_sphere_radius_m must be > 0")
        if not self.cloud_radius_m > 0 or self.cloud_samples < 1:
            raise InvalidRequestError("cloud_radius_m must be > 0 and cloud_samples ≥ 1")


@dataclass(frozen=True, eq=False)
class SpheresLayer:
    """The error spheres drawn by :func:`build_scene` (layer ``pkmtol/error_spheres``).

    ``m`` below is the number of task-space grid points (``len(result.grid.points_m)``); sphere
    ``k`` is centred at ``result.grid.points_m[k]`` (frame K).

    Attributes:
        count: Number of spheres ``m`` (one per grid point).
        paths: Shape (m,): meshcat path of each sphere, relative to ``/meshcat``
            (``pkmtol/error_spheres/<k>``).
        radii_m: Shape (m,): drawn radius of each sphere [m] (``radius_per_sigma · sigma_m``).
        sigma_m: Shape (m,): σ[Δλ_k] at each grid point. With ``sigma_source == "search"``
            (η_c ~ N(0, 1)) it is in metres per unit error (m per m or rad); with ``"design"``
            (η_c at the design-β tolerances) in metres.
        colors_rgb: Shape (m, 3): viridis colour of each sphere, RGB in [0, 1].
        radius_per_sigma: The scale: drawn radius [m] per unit of σ (also the layer node's
            property ``pkmtol_radius_per_sigma``); 0 if every σ is 0.
        max_radius_m: Radius of the largest sphere [m] (``SceneOptions.max_sphere_radius_m`` or
            0.35 × the smallest distance between two grid points).
        sigma_source: ``"search"`` or ``"design"`` (:attr:`SceneOptions.sigma`).
        sigma_range_m: ``(min σ, max σ)`` over the grid, the ends of the colour map, in the unit
            of ``sigma_m``.

    """

    count: int
    paths: tuple[str, ...]
    radii_m: np.ndarray
    sigma_m: np.ndarray
    colors_rgb: np.ndarray
    radius_per_sigma: float
    max_radius_m: float
    sigma_source: str
    sigma_range_m: tuple[float, float]


@dataclass(frozen=True, eq=False)
class VerificationLayer:
    """The Monte Carlo verification drawn by :func:`build_scene` (layer ``pkmtol/verification``).

    Attributes:
        distribution: Verification distribution drawn (one of ``montecarlo.DISTRIBUTIONS``).
        cloud_center_m: Shape (3,): where the cloud's Δλ* sphere is drawn, frame K [m] (just
            outside the task space, radially out from the design point).
        cloud_samples: Number of position-error vectors ``Δp = J η_c`` in the cloud.
        cloud_failed: How many of them have ``‖Δp‖ > Δλ*`` (drawn red).
        cloud_target_radius_m: Drawn radius of the Δλ* sphere [m] (``SceneOptions.cloud_radius_m``).
        cloud_magnification: Drawn length per metre of Δp (``cloud_target_radius_m / Δλ*``,
            dimensionless).
        task_space_samples: Number of samples of the verification run
            (``result.verification[distribution]``) drawn at their task-space points.
        task_space_failed: How many of them have Δλ > Δλ* (drawn red).
        safe_visible: Whether the safe (green) task-space samples are shown at first.

    """

    distribution: str
    cloud_center_m: np.ndarray
    cloud_samples: int
    cloud_failed: int
    cloud_target_radius_m: float
    cloud_magnification: float
    task_space_samples: int
    task_space_failed: int
    safe_visible: bool


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


@dataclass(frozen=True)
class HtmlExport:
    """What :func:`export_html` wrote.

    Attributes:
        path: The HTML file written.
        bytes: Its size [bytes] (UTF-8).
        server_pid: Process id of the meshcat server that built the page (stopped and reaped
            before :func:`export_html` returned).
        scene: What was drawn (the :func:`build_scene` summary).

    """

    path: Path
    bytes: int
    server_pid: int
    scene: SceneSummary


@dataclass
class _Scene:
    """Bookkeeping while drawing."""

    vis: Any
    nodes: list[str] = field(default_factory=list)

    def node(self, path: str) -> Any:
        self.nodes.append(path)
        return self.vis[path]


# --- geometry helpers ----------------------------------------------------------------------


def _translation(p: Sequence[float] | np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = np.asarray(p, dtype=float)
    return t


def _rod_transform(a: np.ndarray, b: np.ndarray) -> np.ndarray:
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


def _rod(scene: _Scene, path: str, a: np.ndarray, b: np.ndarray, radius: float, rgb: Any) -> None:
    g = _meshcat().geometry
    length = max(float(np.linalg.norm(np.asarray(b) - np.asarray(a))), 1e-9)
    node = scene.node(path)
    node.set_object(g.Cylinder(length, radius), g.MeshLambertMaterial(color=_hex(rgb)))
    node.set_transform(_rod_transform(a, b))


def _triad(scene: _Scene, path: str, placement: pin.SE3, length: float, radius: float) -> None:
    """Three rods (x red, y green, z blue) at ``placement``; ``path`` gets the placement."""
    g = _meshcat().geometry
    scene.node(path).set_transform(placement.homogeneous)
    for axis, rgb in zip("xyz", ((0.9, 0.1, 0.1), (0.1, 0.7, 0.1), (0.1, 0.2, 0.9)), strict=True):
        e = np.zeros(3)
        e["xyz".index(axis)] = length
        node = scene.node(f"{path}/{axis}")
        node.set_object(g.Cylinder(length, radius), g.MeshLambertMaterial(color=_hex(rgb)))
        node.set_transform(_rod_transform(np.zeros(3), e))


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
            rod_t = _rod_transform(np.zeros(3), offset)
            # coal's cylinder axis is z; meshcat's is y: rotate y → z
            rot = np.eye(4)
            rot[:3, :3] = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
            placement = pin.SE3(rod_t @ np.linalg.inv(rot))
            rod = pin.GeometryObject(f"rod{j}", model.parents[j], placement, coal.Cylinder(radius, length))
            rod.meshColor = grey
            gm.addGeometryObject(rod)
    return gm


# --- the layers ----------------------------------------------------------------------------


def _draw_robot(
    scene: _Scene, result: DesignResult, animate: bool, with_reference: bool
) -> tuple[list[str], int]:
    """Every limb through Pinocchio's MeshcatVisualizer; returns limb paths, animation frames."""
    from pinocchio.visualize import MeshcatVisualizer
    from pinocchio.visualize.meshcat_visualizer import applyScalingOnHomegeneousTransform

    pose = result.grid.poses[result.worst_index]
    paths, vizs = [], []
    for i, limb in enumerate(result.mechanism.limbs):
        visual = limb.visual_model
        if visual is None:
            visual = skeleton_geometry(limb.model)
        viz = MeshcatVisualizer(limb.model, None, visual)
        viz.initViewer(viewer=scene.vis)
        root = f"{ROOT}/robot/{limb.name}"
        viz.loadViewerModel(rootNodeName=root)
        viz.display(np.asarray(pose.q[i], dtype=float))
        paths.append(root)
        scene.nodes.append(root)
        scene.nodes.extend(f"{root}/visuals/{g.name}" for g in visual.geometryObjects)
        vizs.append((viz, visual))
    if not animate:
        return paths, 0
    meshcat = _meshcat()
    order = _tour(result.grid.points_m, result.worst_index)
    anim = meshcat.animation.Animation(default_framerate=4)
    for frame, k in enumerate(order):
        pk = result.grid.poses[k]
        with anim.at_frame(scene.vis, frame) as f:
            for i, (viz, visual) in enumerate(vizs):
                q = np.asarray(pk.q[i], dtype=float)
                pin.forwardKinematics(viz.model, viz.data, q)
                pin.updateGeometryPlacements(viz.model, viz.data, visual, viz.visual_data)
                for gid, g in enumerate(visual.geometryObjects):
                    t = applyScalingOnHomegeneousTransform(viz.visual_data.oMg[gid].homogeneous, g.meshScale)
                    f[f"{paths[i]}/visuals/{g.name}"].set_transform(t)
            if with_reference:
                _reference_frames(f, pk)
    scene.vis.set_animation(anim, play=False)
    return paths, len(order)


def _tour(points: np.ndarray, start: int) -> list[int]:
    """Greedy nearest-neighbour tour through every point, from ``start``."""
    left = set(range(len(points))) - {start}
    order = [start]
    while left:
        cand = np.fromiter(left, dtype=int)
        d = np.linalg.norm(points[cand] - points[order[-1]], axis=1)
        nxt = int(cand[np.argmin(d)])
        order.append(nxt)
        left.remove(nxt)
    return order


def _reference_frames(f: Any, pose: Any) -> None:
    """Animation keys of the reference layer at ``pose``."""
    p = np.asarray(pose.p_m, dtype=float)
    f[f"{ROOT}/reference/P"].set_transform(_translation(p))
    f[f"{ROOT}/reference/platform_frame"].set_transform(pose.oMp.homogeneous)
    f[f"{ROOT}/reference/offset"].set_transform(_rod_transform(pose.oMp.translation, p))


def _sigma(result: DesignResult, which: str) -> np.ndarray:
    if which == "search":
        return np.asarray(result.search.sigma_analytic_m, dtype=float)
    unc = result.uncompensatable
    tol = _design_tolerances(result)
    return grid_norm_moments(result.grid.J[:, :, unc], tol)[:, 1]


def _design_tolerances(result: DesignResult) -> np.ndarray:
    """Design-β tolerances of η_c; a free (+inf) tolerance has no effect: drawn as 0."""
    tol = result.tolerances[result.uncompensatable, result.design_column]
    return np.where(np.isfinite(tol), tol, 0.0)


def _min_spacing(points: np.ndarray) -> float:
    if len(points) < 2:
        return 0.1
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
    d[np.diag_indices_from(d)] = np.inf
    return float(d.min())


def _draw_spheres(scene: _Scene, result: DesignResult, opt: SceneOptions) -> SpheresLayer:
    g = _meshcat().geometry
    sigma = _sigma(result, opt.sigma)
    points = result.grid.points_m
    rmax = opt.max_sphere_radius_m or 0.35 * _min_spacing(points)
    smax, smin = float(sigma.max()), float(sigma.min())
    scale = rmax / smax if smax > 0 else 0.0
    radii = scale * sigma
    t = (sigma - smin) / (smax - smin) if smax > smin else np.ones_like(sigma)
    colours = viridis(t)
    layer = scene.node(f"{ROOT}/error_spheres")
    paths = []
    for k, (p, r, c) in enumerate(zip(points, radii, colours, strict=True)):
        path = f"{ROOT}/error_spheres/{k}"
        node = scene.node(path)
        node.set_object(
            g.Sphere(max(float(r), 1e-6)),
            g.MeshLambertMaterial(color=_hex(c), opacity=opt.sphere_opacity),
        )
        node.set_transform(_translation(p))
        paths.append(path)
    layer.set_property("pkmtol_radius_per_sigma", float(scale))
    return SpheresLayer(
        count=len(paths),
        paths=tuple(paths),
        radii_m=radii,
        sigma_m=sigma,
        colors_rgb=colours,
        radius_per_sigma=float(scale),
        max_radius_m=float(rmax),
        sigma_source=opt.sigma,
        sigma_range_m=(smin, smax),
    )


def _points(position: np.ndarray, rgb: Sequence[float], size: float) -> Any:
    g = _meshcat().geometry
    pos = np.asarray(position, dtype=np.float32).reshape(-1, 3).T
    col = np.tile(np.asarray(rgb, dtype=np.float32)[:, None], (1, pos.shape[1]))
    return g.Points(g.PointsGeometry(pos, col), g.PointsMaterial(size=size))


def _draw_verification(
    scene: _Scene, result: DesignResult, opt: SceneOptions, sphere_rmax: float
) -> VerificationLayer:
    g = _meshcat().geometry
    target = float(result.target_m)
    base = f"{ROOT}/verification"
    scene.node(base)
    # Fig. 9 cloud: Δp = J η at the design point, magnified, around the Δλ* sphere
    rng = np.random.default_rng(opt.seed)
    J = result.grid.J[result.worst_index][:, result.uncompensatable]
    eta = sample_errors(opt.distribution, _design_tolerances(result), opt.cloud_samples, rng)
    dp = eta @ J.T
    dl = np.linalg.norm(dp, axis=1)
    failed = dl > target
    mag = opt.cloud_radius_m / target
    worst = result.worst_point_m
    axis = (
        worst - np.array([*result.mechanism.task_space.center_xy_m, worst[2]])
        if (result.mechanism.task_space.kind == "cylinder")
        else worst - result.grid.points_m.mean(axis=0)
    )
    axis[2] = 0.0
    if np.linalg.norm(axis) < 1e-9:
        axis = np.array([1.0, 0.0, 0.0])
    axis /= np.linalg.norm(axis)
    centre = worst + axis * (sphere_rmax + 1.6 * opt.cloud_radius_m)
    cloud = f"{base}/cloud"
    scene.node(cloud).set_transform(_translation(centre))
    node = scene.node(f"{cloud}/target")
    node.set_object(
        g.Sphere(opt.cloud_radius_m),
        g.MeshLambertMaterial(color=_hex((0.35, 0.55, 0.85)), opacity=0.25, transparent=True),
    )
    size = opt.cloud_radius_m / 25
    if (~failed).any():
        scene.node(f"{cloud}/safe").set_object(_points(dp[~failed] * mag, SAFE_RGB, size))
    if failed.any():
        scene.node(f"{cloud}/failed").set_object(_points(dp[failed] * mag, FAILED_RGB, 1.5 * size))
    _rod(scene, f"{cloud}/link", worst - centre, -axis * opt.cloud_radius_m, 0.002, (0.4, 0.4, 0.4))
    # the actual verification run, sample by sample at its task-space point
    ver = result.verification[opt.distribution]
    bad = ver.dlam_linear_m > target
    ts = f"{base}/task_space"
    scene.node(ts)
    if (~bad).any():
        node = scene.node(f"{ts}/safe")
        node.set_object(_points(ver.points_m[~bad], SAFE_RGB, 0.01))
        # thousands of green dots would hide the spheres: shown from the controls on demand
        node.set_property("visible", bool(opt.show_safe_samples))
    if bad.any():
        scene.node(f"{ts}/failed").set_object(_points(ver.points_m[bad], FAILED_RGB, 0.02))
    return VerificationLayer(
        distribution=opt.distribution,
        cloud_center_m=centre,
        cloud_samples=int(dl.size),
        cloud_failed=int(failed.sum()),
        cloud_target_radius_m=float(opt.cloud_radius_m),
        cloud_magnification=float(mag),
        task_space_samples=int(bad.size),
        task_space_failed=int(bad.sum()),
        safe_visible=bool(opt.show_safe_samples),
    )


def _draw_reference(scene: _Scene, result: DesignResult) -> None:
    g = _meshcat().geometry
    pose = result.grid.poses[result.worst_index]
    scene.node(f"{ROOT}/reference")
    node = scene.node(f"{ROOT}/reference/P")
    node.set_object(g.Sphere(0.018), g.MeshLambertMaterial(color=_hex(P_RGB)))
    node.set_transform(_translation(pose.p_m))
    _triad(scene, f"{ROOT}/reference/platform_frame", pose.oMp, 0.15, 0.006)
    # |O'P| is the same at every pose, so the animation only moves this rod
    _rod(scene, f"{ROOT}/reference/offset", pose.oMp.translation, pose.p_m, 0.006, P_RGB)


def legend_lines(
    result: DesignResult,
    spheres: SpheresLayer | None = None,
    verification: VerificationLayer | None = None,
) -> list[str]:
    """Return the legend of a scene, one line per entry (shown in the scene and the HTML page).

    Args:
        result: The design drawn.
        spheres: The error-sphere layer drawn, if any (adds its scale and colour range).
        verification: The verification layer drawn, if any (adds its counts).

    Returns:
        The lines, as in :attr:`SceneSummary.legend`.

    """
    lines = [
        f"{result.mechanism.name}: design point P = "
        + ", ".join(f"{1e3 * x:.0f}" for x in result.worst_point_m)
        + " mm"
        + f" (grid point {result.worst_index})"
    ]
    if spheres is not None:
        smin, smax = spheres.sigma_range_m
        if spheres.sigma_source == "search":
            what = "σ[Δλ] for η_c ~ N(0,1) (m per unit error)"
            rng = f"{smin:.3g} … {smax:.3g}"
        else:
            what = "σ[Δλ] at the design tolerances"
            rng = f"{1e6 * smin:.3g} … {1e6 * smax:.3g} µm"
        lines.append(f"Error spheres ({spheres.count}): radius = {spheres.radius_per_sigma:.4g} × {what}")
        lines.append(f"  colour viridis over σ = {rng}; largest radius {1e3 * spheres.max_radius_m:.0f} mm")
    v = verification
    if v is not None:
        pct = 100 * v.cloud_failed / v.cloud_samples
        lines.append(
            f"Verification cloud ({v.distribution} errors at the β = {result.design_beta:g} "
            f"tolerances): {v.cloud_samples} position errors Δp at the design point, "
            f"×{v.cloud_magnification:.0f}; blue sphere = Δλ* = {1e3 * result.target_m:g} mm"
        )
        lines.append(f"  green ‖Δp‖ ≤ Δλ*, red beyond: {v.cloud_failed} ({pct:.1f} %)")
        n, k = v.task_space_samples, v.task_space_failed
        lines.append(
            f"Verification run over the task space: {k} of {n} samples failed "
            f"({100 * k / max(n, 1):.2f} %), drawn red at their points"
            + ("; safe ones green" if v.safe_visible else " (safe ones hidden)")
        )
    lines.append("Reference: P magenta, platform frame x/y/z = red/green/blue")
    return lines


_ASCII = str.maketrans(
    {
        "σ": "sigma",
        "Δ": "d",
        "λ": "lambda",
        "η": "eta",
        "β": "beta",
        "µ": "u",
        "×": "x",
        "…": "...",
        "≤": "<=",
        "→": "->",
    }
)


def _font(size: int) -> tuple[Any, bool]:
    """Return a TrueType font with Greek letters (DejaVu Sans) or PIL's default, and which."""
    import importlib.util

    from PIL import ImageFont

    candidates = [Path("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf")]
    spec = importlib.util.find_spec("matplotlib")
    if spec is not None and spec.origin:
        candidates.append(Path(spec.origin).parent / "mpl-data/fonts/ttf/DejaVuSans.ttf")
    for c in candidates:
        if c.is_file():
            with contextlib.suppress(OSError):
                return ImageFont.truetype(str(c), size), True
    return ImageFont.load_default(size=size), False


def _legend_png(lines: list[str], with_bar: bool) -> bytes:
    from PIL import Image, ImageDraw

    font, greek = _font(26)
    small, _ = _font(20)
    if not greek:
        lines = [line.translate(_ASCII) for line in lines]
    w, line_h = 1600, 36
    h = 30 + line_h * len(lines) + (70 if with_bar else 0)
    img = Image.new("RGB", (w, h), (255, 255, 255))
    draw = ImageDraw.Draw(img)
    y = 15
    for line in lines:
        draw.text((20, y), line, fill=(20, 20, 20), font=font)
        y += line_h
    if with_bar:
        cols = (255 * viridis(np.linspace(0, 1, w - 40))).astype(np.uint8)
        for x, c in enumerate(cols):
            draw.line([(20 + x, y + 10), (20 + x, y + 40)], fill=tuple(int(v) for v in c))
        lo, hi = ("min σ", "max σ") if greek else ("min sigma", "max sigma")
        draw.text((20, y + 42), lo, fill=(20, 20, 20), font=small)
        draw.text((w - 20, y + 42), hi, fill=(20, 20, 20), font=small, anchor="ra")
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def _camera_direction(result: DesignResult) -> tuple[np.ndarray, float]:
    """Return the unit vector from the origin to the default camera, and the scene's reach [m]."""
    pts = np.vstack([result.grid.points_m, np.zeros((1, 3))])
    reach = float(np.max(np.linalg.norm(pts, axis=1)))
    d = np.array([0.8, -1.3, 1.9])
    return d / np.linalg.norm(d), reach


def _draw_legend(scene: _Scene, result: DesignResult, lines: list[str], with_bar: bool) -> None:
    """Draw the legend as a textured panel left of the mechanism, facing the default camera."""
    g = _meshcat().geometry
    png = _legend_png(lines, with_bar)
    from PIL import Image

    w, h = Image.open(io.BytesIO(png)).size
    _, reach = _camera_direction(result)
    width = 1.1 * reach
    height = width * h / w
    node = scene.node(f"{ROOT}/legend")
    material = g.MeshBasicMaterial(map=g.ImageTexture(image=g.PngImage(png)))
    node.set_object(g.Box([width, 0.002, height]), material)
    c, _ = _camera_direction(result)
    toward = np.array([c[0], c[1], 0.0]) / np.linalg.norm(c[:2])
    right = np.array([-toward[1], toward[0], 0.0])  # seen from the camera, left to right
    t = np.eye(4)
    # the textured face is the box's -y face: local y points away from the camera
    t[:3, 0], t[:3, 1] = right, -c
    t[:3, 2] = np.cross(right, -c)
    t[:3, 3] = -right * 1.0 * reach + np.array([0.0, 0.0, 0.2 * reach])
    node.set_transform(t)


def _set_camera(vis: Any, result: DesignResult) -> None:
    """Point the default camera at the mechanism.

    meshcat 0.3's orbit controls always look at the world origin (the base of K), so only the
    camera position is set: above and in front of the task space, far enough to see it all.
    """
    c, reach = _camera_direction(result)
    d = c * 2.1 * reach
    # the camera's position is in meshcat's y-up frame: (x, z_up, -y)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [d[0], d[2], -d[1]])


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
    _meshcat()
    opt = options or SceneOptions()
    scene = _Scene(vis)
    vis[ROOT].delete()
    if opt.background_rgb is not None:
        vis["/Background"].set_property("top_color", list(opt.background_rgb))
        vis["/Background"].set_property("bottom_color", list(opt.background_rgb))
    # reference first: the robot's animation keys its nodes
    if "reference" in opt.layers:
        _draw_reference(scene, result)
    robot_paths: list[str] = []
    frames = 0
    if "robot" in opt.layers:
        robot_paths, frames = _draw_robot(scene, result, opt.animate, "reference" in opt.layers)
    spheres = _draw_spheres(scene, result, opt) if "error_spheres" in opt.layers else None
    rmax = spheres.max_radius_m if spheres is not None else 0.0
    verification = _draw_verification(scene, result, opt, rmax) if "verification" in opt.layers else None
    legend = legend_lines(result, spheres, verification)
    if "legend" in opt.layers:
        _draw_legend(scene, result, legend, "error_spheres" in opt.layers)
    if opt.camera:
        _set_camera(vis, result)
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
    )


# --- the server ------------------------------------------------------------------------------


class MeshcatServer:
    """A loopback-only meshcat server subprocess (:mod:`pkmtol.meshcat_server`) and a client.

    Use as a context manager, or call :meth:`close`; the server is also stopped at interpreter
    exit, and exits by itself when this process dies.

    Attributes:
        proc: The server process (``subprocess.Popen``).
        zmq_url: Its ZeroMQ address (``tcp://127.0.0.1:…``).
        web_url: The viewer's address (``http://127.0.0.1:…/static/``).

    """

    def __init__(self, timeout_s: float = 30.0) -> None:
        _meshcat()
        cmd = [sys.executable, "-u", "-m", "pkmtol.meshcat_server"]
        cmd += ["--parent-pid", str(os.getpid())]
        env = dict(os.environ)
        src = str(Path(__file__).resolve().parent.parent)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (env.get("PYTHONPATH"), src) if p)
        try:
            self.proc = subprocess.Popen(
                cmd,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                env=env,
                start_new_session=True,
            )
        except OSError as err:
            raise ViewerError(f"cannot start the meshcat server ({err})") from err
        self._vis: Any = None
        self._closed = False
        atexit.register(self.close)
        try:
            urls = self._read_urls(timeout_s)
        except BaseException:
            self.close()
            raise
        self.zmq_url, self.web_url = urls["zmq_url"], urls["web_url"]

    def _read_urls(self, timeout_s: float) -> dict[str, str]:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        buf = b""
        while buf.count(b"\n") < 2:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ViewerError(f"the meshcat server did not start within {timeout_s:g} s")
            ready, _, _ = select.select([fd], [], [], remaining)
            if ready:
                chunk = os.read(fd, 4096)
                if not chunk:
                    raise ViewerError(
                        f"the meshcat server exited at start (code {self.proc.wait()}); "
                        f"run `{sys.executable} -m pkmtol.meshcat_server` to see why"
                    )
                buf += chunk
        out = {}
        for line in buf.decode("utf-8").splitlines()[:2]:
            key, _, value = line.partition("=")
            out[key.strip()] = value.strip()
        if set(out) != {"zmq_url", "web_url"}:
            raise ViewerError(f"unexpected output from the meshcat server: {buf!r}")
        return out

    @property
    def pid(self) -> int:
        """Process id of the server."""
        return int(self.proc.pid)

    @property
    def visualizer(self) -> Any:
        """A ``meshcat.Visualizer`` connected to this server."""
        if self._closed:
            raise ViewerError("the meshcat server has been stopped")
        if self._vis is None:
            import zmq

            meshcat = _meshcat()
            with contextlib.redirect_stdout(io.StringIO()):  # it prints the URL
                self._vis = meshcat.Visualizer(zmq_url=self.zmq_url)
            sock = self._vis.window.zmq_socket
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.RCVTIMEO, 120_000)
        return self._vis

    def close(self) -> None:
        """Stop the server (terminate, then kill after 5 s) and reap it. Idempotent."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(Exception):
            atexit.unregister(self.close)
        if self._vis is not None:
            with contextlib.suppress(Exception):
                self._vis.window.zmq_socket.close(linger=0)
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --- headless screenshots ------------------------------------------------------------------

#: Chromium binaries looked for, in order.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome binary on PATH, or None."""
    import shutil

    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


def chromium_command(
    chromium: str,
    html: Path,
    png: Path,
    profile: Path,
    size: tuple[int, int] = (1200, 900),
    budget_ms: int = 10_000,
) -> list[str]:
    """Build the headless Chromium command that renders ``html`` (software WebGL) to ``png``."""
    return [
        chromium,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={profile}",
        f"--window-size={size[0]},{size[1]}",
        f"--virtual-time-budget={budget_ms}",
        f"--screenshot={png}",
        Path(html).resolve().as_uri(),
    ]


def screenshot(
    html: Path | str, png: Path | str, size: tuple[int, int] = (1200, 900), timeout_s: float = 120
) -> Path:
    """Render an exported page in headless Chromium (software WebGL) and save a PNG.

    Raises:
        ViewerError: no Chromium found, or it failed or produced no image.

    """
    chromium = find_chromium()
    if chromium is None:
        raise ViewerError(
            "no Chromium found for the screenshot; install it (Debian: `apt-get install chromium`)"
        )
    png = Path(png)
    with tempfile.TemporaryDirectory(prefix="pkmtol-chromium-") as tmp:
        shot = Path(tmp) / "shot.png"
        cmd = chromium_command(chromium, Path(html), shot, Path(tmp) / "profile", size)
        try:
            done = subprocess.run(
                cmd, stdin=subprocess.DEVNULL, capture_output=True, timeout=timeout_s, check=False
            )
        except subprocess.TimeoutExpired as err:
            raise ViewerError(f"Chromium did not finish within {timeout_s:g} s") from err
        if not shot.is_file():
            tail = done.stderr.decode("utf-8", "replace")[-800:]
            raise ViewerError(f"Chromium made no screenshot (exit {done.returncode}): {tail}")
        write_atomic(png, shot.read_bytes())
    return png


# --- entry points ----------------------------------------------------------------------------


def _legend_overlay(lines: list[str], with_bar: bool) -> str:
    rows = "".join(f"<div>{html_lib.escape(line)}</div>" for line in lines)
    stops = ", ".join(
        f"rgb({int(255 * r)},{int(255 * g)},{int(255 * b)}) {100 * i / (len(_VIRIDIS) - 1):.0f}%"
        for i, (r, g, b) in enumerate(_VIRIDIS)
    )
    bar = (
        f'<div style="height:10px;margin-top:4px;background:linear-gradient(to right, {stops})">'
        '</div><div style="display:flex;justify-content:space-between"><span>min σ</span>'
        "<span>max σ</span></div>"
        if with_bar
        else ""
    )
    return (
        '<div id="pkmtol-legend" style="position:fixed;left:8px;bottom:8px;max-width:75vw;'
        "padding:6px 10px;background:rgba(255,255,255,0.85);font:12px sans-serif;color:#222;"
        f'border:1px solid #bbb;border-radius:4px;z-index:10">{rows}{bar}</div>'
    )


def export_html(result: DesignResult, path: Path | str, options: SceneOptions | None = None) -> HtmlExport:
    """Write the scene as one self-contained HTML page (meshcat's ``static_html``), atomically.

    Starts a loopback-only meshcat server, builds the scene, takes the page, stops the server
    (reaped before returning, also on error) and writes ``path`` through a temporary file in the
    same folder renamed over it (nothing is written if anything fails). The legend is overlaid on
    the page (the 3D legend panel is hidden; it can be shown from the viewer's controls).

    Returns:
        The file written, its size, the stopped server's process id and the :func:`build_scene`
        summary (:class:`HtmlExport`).

    Raises:
        ViewerError: meshcat is missing or its server did not start.
        OutputError: the file cannot be written.

    """
    path = Path(path)
    if path.parent and not path.parent.is_dir():
        raise OutputError(path, f"folder {path.parent} does not exist")
    with MeshcatServer() as server:
        vis = server.visualizer
        summary = build_scene(result, vis, options)
        if "legend" in summary.layers:
            # the page has the legend overlaid; the 3D panel stays available in the controls
            vis[f"{ROOT}/legend"].set_property("visible", False)
        page = vis.static_html()
        server_pid = server.pid
    overlay = _legend_overlay(list(summary.legend), summary.spheres is not None)
    page = page.replace("</body>", overlay + "\n</body>", 1)
    data = page.encode("utf-8")
    write_atomic(path, data)
    return HtmlExport(path=path, bytes=len(data), server_pid=server_pid, scene=summary)


def show(
    result: DesignResult,
    options: SceneOptions | None = None,
    *,
    open_browser: bool = False,
    block: bool = True,
    out: Callable[[str], None] = print,
) -> MeshcatServer | None:
    """Serve the scene live on 127.0.0.1 (``pkmtol show``, ``allocate --view``).

    Prints the viewer's URL and the legend through ``out``. With ``block`` (default) it waits
    until Ctrl-C (or SIGTERM), stops the server and returns None; otherwise it returns the running
    :class:`MeshcatServer`, which the caller must close.
    """
    server = MeshcatServer()
    try:
        summary = build_scene(result, server.visualizer, options)
        out(f"meshcat viewer: {server.web_url}")
        for line in summary.legend:
            out(line)
        if open_browser:
            import webbrowser

            webbrowser.open(server.web_url, new=2)
        if not block:
            return server
        out("press Ctrl-C to stop the viewer")
        import signal

        def _stop(signum: int, frame: Any) -> None:
            raise KeyboardInterrupt

        previous = signal.signal(signal.SIGTERM, _stop)
        try:
            while server.proc.poll() is None:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)
    except BaseException:
        server.close()
        raise
    server.close()
    return None
