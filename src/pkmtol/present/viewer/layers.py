"""The layers of the 3D scene: robot, error spheres (Fig. 7), verification (Fig. 9), reference point."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.design.job import DesignResult
from pkmtol.design.signoff import result_maps, verified_sigma
from pkmtol.design.verification import sample_errors
from pkmtol.error_model.accuracy import norm_moments
from pkmtol.model.limb import Limb
from pkmtol.present.viewer.backend import require_meshcat
from pkmtol.present.viewer.colours import FAILED_RGB, LINK_RGB, P_RGB, SAFE_RGB, hex_colour, viridis
from pkmtol.present.viewer.geometry import (
    Scene,
    rod,
    rod_transform,
    scene_size,
    skeleton_geometry,
    translation,
    triad,
)
from pkmtol.present.viewer.options import GLYPH_SPACING, ROOT, SceneOptions
from pkmtol.present.viewer.tool_layer import draw_tool, place_tool

#: Documented API of this module (the other names serve the scene's own modules).
__all__ = ["SpheresLayer", "VerificationLayer", "link_segments"]

#: Radius of a link rod, relative to the size of the mechanism (:func:`scene_size`).
LINK_RADIUS_FRACTION = 0.008
#: A joint-to-joint distance below this is no link (coincident axes of a U or S joint) [m].
MIN_LINK_M = 1e-9
#: Opacity of the platform's visuals (the joints under it show through).
PLATFORM_OPACITY = 0.35


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
        glyph: ``"sphere"`` or ``"ellipsoid"`` (:attr:`SceneOptions.glyph`).
        semi_axes_m: Shape (m, 3): an ellipsoid's drawn semi-axes [m], largest first
            (``scale_ellipsoid · √λ`` of the covariance; each at least 2 % of the largest); None
            for spheres.
        axes: Shape (m, 3, 3): the ellipsoids' axes (columns, frame K, right-handed), in the
            order of ``semi_axes_m``; None for spheres.
        ellipsoid_scale: Drawn length [m] per unit of ``√λ`` (the unit of ``sigma_m``); 0 for
            spheres.

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
    glyph: str = "sphere"
    semi_axes_m: np.ndarray | None = None
    axes: np.ndarray | None = None
    ellipsoid_scale: float = 0.0


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


def draw_robot(
    scene: Scene, result: DesignResult, animate: bool, with_reference: bool
) -> tuple[list[str], int, tuple[np.ndarray, ...]]:
    """Every limb: its URDF visuals (Pinocchio's MeshcatVisualizer) and its links, joint to joint.

    The URDF visuals of a limb are drawn as its file gives them (a leg's cylinder has the length
    written there, whatever the stroke); the links layer draws, at each pose, a rod from every joint
    frame to the next and from the last to the platform frame, so each limb is drawn whole from its
    base joint to the platform. The platform's visuals are drawn once, see-through, so that the
    joints under it stay visible.

    Returns:
        The limb paths, the animation frames, and per limb its link segments at the design pose
        (shape (k, 2, 3): start and end of each rod, frame K [m]).
    """
    from pinocchio.visualize import MeshcatVisualizer
    from pinocchio.visualize.meshcat_visualizer import applyScalingOnHomegeneousTransform

    pose = result.grid.poses[result.worst_index]
    radius = LINK_RADIUS_FRACTION * scene_size(result)
    paths, vizs, links = [], [], []
    for i, limb in enumerate(result.mechanism.limbs):
        visual = limb.visual_model
        if visual is None:
            visual = skeleton_geometry(limb.model)
        plate = _platform_visuals(limb, visual)
        saved = {gid: visual.geometryObjects[gid].meshColor.copy() for gid in plate}
        for gid in plate:  # see-through: the joints under the platform stay visible
            visual.geometryObjects[gid].meshColor = np.r_[saved[gid][:3], PLATFORM_OPACITY]
        viz = MeshcatVisualizer(limb.model, None, visual)
        viz.initViewer(viewer=scene.vis)
        root = f"{ROOT}/robot/{limb.name}"
        try:
            viz.loadViewerModel(rootNodeName=root)
        finally:
            for gid, colour in saved.items():
                visual.geometryObjects[gid].meshColor = colour
        if i:  # the platform once (limb 0's), not one copy per limb
            for gid in plate:
                scene.vis[f"{root}/visuals/{visual.geometryObjects[gid].name}"].set_property("visible", False)
        viz.display(np.asarray(pose.q[i], dtype=float))
        paths.append(root)
        scene.nodes.append(root)
        scene.nodes.extend(f"{root}/visuals/{g.name}" for g in visual.geometryObjects)
        segments = link_segments(limb, np.asarray(pose.q[i], dtype=float))
        links.append(segments)
        for k, (a, b) in enumerate(segments):
            node = scene.node(f"{root}/links/{k}")
            node.set_object(require_meshcat().geometry.Cylinder(1.0, radius), _link_material())
            node.set_transform(_unit_rod(a, b))
        vizs.append((viz, visual))
    tool = draw_tool(scene, result, int(result.worst_index))  # a hybrid: the wrist and the spindle
    if tool is not None:
        paths.append(tool[0])
    if not animate:
        return paths, 0, tuple(links)
    meshcat = require_meshcat()
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
                for j, (a, b) in enumerate(link_segments(result.mechanism.limbs[i], q)):
                    f[f"{paths[i]}/links/{j}"].set_transform(_unit_rod(a, b))
            if tool is not None:
                place_tool(f, tool[0], tool[1], tool[2], result.grid, k)
            if with_reference:
                _reference_frames(f, pk)
    scene.vis.set_animation(anim, play=False)
    return paths, len(order), tuple(links)


def link_segments(limb: Limb, q: np.ndarray) -> np.ndarray:
    """Shape (k, 2, 3): the rods of ``limb`` at ``q``, joint frame to joint frame, frame K [m].

    One rod from each joint's origin to each of its children's (coincident origins, such as a
    universal or spherical joint's, give none), and one from the platform frame's joint to the
    platform frame; the base joint's origin is where the first rod starts.
    """
    model = limb.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    origin = [data.oMi[j].translation.copy() for j in range(model.njoints)]
    out = []
    for j in range(2, model.njoints):
        a, b = origin[model.parents[j]], origin[j]
        if model.parents[j] > 0 and np.linalg.norm(b - a) > MIN_LINK_M:
            out.append((a, b))
    end = data.oMf[limb.platform_frame].translation.copy()
    last = origin[model.frames[limb.platform_frame].parentJoint]
    if np.linalg.norm(end - last) > MIN_LINK_M:
        out.append((last, end))
    return np.array(out, dtype=float).reshape(-1, 2, 3)


def _platform_visuals(limb: Limb, visual: Any) -> list[int]:
    """Ids of the geometry objects of ``visual`` on the platform link."""
    name = limb.model.frames[limb.platform_frame].name
    frames = limb.model.frames
    on = [gid for gid, g in enumerate(visual.geometryObjects) if g.parentFrame < len(frames)]  # set
    return [gid for gid in on if frames[visual.geometryObjects[gid].parentFrame].name == name]


def _unit_rod(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Transform of meshcat's unit-length cylinder (axis y) onto the segment ``a``–``b``."""
    t = rod_transform(a, b)
    t[:3, 1] *= max(float(np.linalg.norm(np.asarray(b) - np.asarray(a))), 1e-12)
    return t


def _link_material() -> Any:
    return require_meshcat().geometry.MeshLambertMaterial(color=hex_colour(LINK_RGB))


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
    f[f"{ROOT}/reference/P"].set_transform(translation(p))
    f[f"{ROOT}/reference/platform_frame"].set_transform(pose.oMp.homogeneous)
    f[f"{ROOT}/reference/offset"].set_transform(rod_transform(pose.oMp.translation, p))


def error_covariance(result: DesignResult, which: str) -> np.ndarray:
    """Covariance of P's error at every grid point from the mode's maps, (m, 3, 3).

    ``which = "search"``: every toleranced error ``N(0, 1)`` (m² per unit error², no noise; the
    pose search's quantity); ``"design"``: the verified design's σ_i and, after a calibration, the
    tracker noise [m²].
    """
    maps = result_maps(result)
    if which == "search":
        L = maps.position[:, :, result.uncompensatable]
        return L @ np.swapaxes(L, 1, 2)
    return maps.position_covariance(verified_sigma(result))


def _sigma(result: DesignResult, which: str, cov: np.ndarray) -> np.ndarray:
    if which == "search":
        return np.asarray(result.search.sigma_analytic_m, dtype=float)
    return np.array([norm_moments(np.clip(np.linalg.eigvalsh(c)[::-1], 0.0, None))[1] for c in cov])


def design_tolerances(result: DesignResult) -> np.ndarray:
    """The verified design's σ of the toleranced errors; a free (+inf) tolerance is drawn as 0."""
    return verified_sigma(result)[result.uncompensatable]


def _min_spacing(points: np.ndarray) -> float:
    if len(points) < 2:
        return 0.1
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
    d[np.diag_indices_from(d)] = np.inf
    return float(d.min())


def draw_spheres(scene: Scene, result: DesignResult, opt: SceneOptions) -> SpheresLayer:
    """Layer ``pkmtol/error_spheres``: one sphere per grid point, radius ∝ σ[Δλ] (Fig. 7)."""
    g = require_meshcat().geometry
    cov = error_covariance(result, opt.sigma)
    sigma = _sigma(result, opt.sigma, cov)
    points = result.grid.points_m
    rmax = opt.max_sphere_radius_m or GLYPH_SPACING * _min_spacing(points)
    smax, smin = float(sigma.max()), float(sigma.min())
    scale = rmax / smax if smax > 0 else 0.0
    radii = scale * sigma
    t = (sigma - smin) / (smax - smin) if smax > smin else np.ones_like(sigma)
    colours = viridis(t)
    layer = scene.node(f"{ROOT}/error_spheres")
    paths = []
    semi, axes, e_scale = None, None, 0.0
    if opt.glyph == "ellipsoid":
        semi, axes, e_scale = _ellipsoids(cov, rmax)
        radii = semi[:, 0]
    for k, (p, r, c) in enumerate(zip(points, radii, colours, strict=True)):
        path = f"{ROOT}/error_spheres/{k}"
        node = scene.node(path)
        material = g.MeshLambertMaterial(color=hex_colour(c), opacity=opt.sphere_opacity)
        if semi is not None and axes is not None:
            node.set_object(g.Sphere(1.0), material)  # the unit sphere, stretched by the transform
            t = translation(p)
            t[:3, :3] = axes[k] * semi[k][None, :]
            node.set_transform(t)
        else:
            node.set_object(g.Sphere(max(float(r), 1e-6)), material)
            node.set_transform(translation(p))
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
        glyph=opt.glyph,
        semi_axes_m=semi,
        axes=axes,
        ellipsoid_scale=e_scale,
    )


def _ellipsoids(cov: np.ndarray, rmax: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Semi-axes (m, 3, largest first), right-handed axes (m, 3, 3) and scale of the 1σ ellipsoids."""
    lam, vec = np.linalg.eigh(cov)  # ascending
    lam, vec = lam[:, ::-1], vec[:, :, ::-1]
    root = np.sqrt(np.clip(lam, 0.0, None))
    top = float(root.max(initial=0.0))
    scale = rmax / top if top > 0 else 0.0
    semi = np.maximum(scale * root, 0.02 * rmax)
    flip = np.linalg.det(vec) < 0
    vec[flip, :, 2] *= -1.0
    return semi, vec, float(scale)


def _points(position: np.ndarray, rgb: Sequence[float], size: float) -> Any:
    g = require_meshcat().geometry
    pos = np.asarray(position, dtype=np.float32).reshape(-1, 3).T
    col = np.tile(np.asarray(rgb, dtype=np.float32)[:, None], (1, pos.shape[1]))
    return g.Points(g.PointsGeometry(pos, col), g.PointsMaterial(size=size))


def draw_verification(
    scene: Scene, result: DesignResult, opt: SceneOptions, sphere_rmax: float
) -> VerificationLayer:
    """Layer ``pkmtol/verification``: the design-point cloud (Fig. 9) and the task-space samples."""
    g = require_meshcat().geometry
    target = float(result.target_m)
    base = f"{ROOT}/verification"
    scene.node(base)
    # Fig. 9 cloud: Δp = J η at the design point, magnified, around the Δλ* sphere
    rng = np.random.default_rng(opt.seed)
    maps = result_maps(result)
    J = maps.position[result.worst_index][:, result.uncompensatable]
    eta = sample_errors(opt.distribution, design_tolerances(result), opt.cloud_samples, rng)
    dp = eta @ J.T
    N = maps.position_noise[result.worst_index]
    if N.shape[1] and maps.noise_m > 0:  # the tracker noise a calibration leaves, Gaussian
        dp = dp + maps.noise_m * rng.standard_normal((opt.cloud_samples, N.shape[1])) @ N.T
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
    scene.node(cloud).set_transform(translation(centre))
    node = scene.node(f"{cloud}/target")
    node.set_object(
        g.Sphere(opt.cloud_radius_m),
        g.MeshLambertMaterial(color=hex_colour((0.35, 0.55, 0.85)), opacity=0.25, transparent=True),
    )
    size = opt.cloud_radius_m / 25
    if (~failed).any():
        scene.node(f"{cloud}/safe").set_object(_points(dp[~failed] * mag, SAFE_RGB, size))
    if failed.any():
        scene.node(f"{cloud}/failed").set_object(_points(dp[failed] * mag, FAILED_RGB, 1.5 * size))
    rod(scene, f"{cloud}/link", worst - centre, -axis * opt.cloud_radius_m, 0.002, (0.4, 0.4, 0.4))
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


def draw_reference(scene: Scene, result: DesignResult) -> None:
    """Layer ``pkmtol/reference``: P, the platform frame O' and the rod O'→P at the design pose."""
    g = require_meshcat().geometry
    pose = result.grid.poses[result.worst_index]
    scene.node(f"{ROOT}/reference")
    node = scene.node(f"{ROOT}/reference/P")
    node.set_object(g.Sphere(0.018), g.MeshLambertMaterial(color=hex_colour(P_RGB)))
    node.set_transform(translation(pose.p_m))
    triad(scene, f"{ROOT}/reference/platform_frame", pose.oMp, 0.15, 0.006)
    # |O'P| is the same at every pose, so the animation only moves this rod
    rod(scene, f"{ROOT}/reference/offset", pose.oMp.translation, pose.p_m, 0.006, P_RGB)
