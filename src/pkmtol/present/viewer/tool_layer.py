"""A hybrid machine's tool chain in the scene: the wrist and the spindle on the platform, at each pose.

The chain's visuals (its URDF's, or a skeleton) go through Pinocchio's MeshcatVisualizer under
``pkmtol/robot/tool``, whose node carries the platform placement of the pose (the chain's root is
the platform frame), so the wrist's joints move it as the module's move the limbs. The TCP itself
is the reference point of the reference layer, and the error spheres sit on the TCP points.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.error_model.tool_sweep import ToolSweep
from pkmtol.present.viewer.geometry import Scene, skeleton_geometry
from pkmtol.present.viewer.options import ROOT


def draw_tool(scene: Scene, result: Any, k: int) -> tuple[str, Any, Any] | None:
    """Draw the tool chain at grid pose ``k``; returns ``(path, visualizer, visuals)`` or None.

    None for a parallel module (no tool chain).
    """
    from pinocchio.visualize import MeshcatVisualizer

    grid, tool = result.grid, result.mechanism.tool
    if tool is None or not isinstance(grid, ToolSweep):
        return None
    visual = tool.visual_model if tool.visual_model is not None else skeleton_geometry(tool.model)
    viz = MeshcatVisualizer(tool.model, None, visual)
    viz.initViewer(viewer=scene.vis)
    root = f"{ROOT}/robot/tool"
    viz.loadViewerModel(rootNodeName=root)
    place_tool(scene.vis, root, viz, visual, grid, k)
    scene.nodes.append(root)
    scene.nodes.extend(f"{root}/visuals/{g.name}" for g in visual.geometryObjects)
    return root, viz, visual


def place_tool(target: Any, root: str, viz: Any, visual: Any, grid: Any, k: int) -> None:
    """Put the chain at pose ``k``: its node at the platform placement, its links at the wrist's joints.

    ``target`` is the visualizer, or an animation frame (the same item access).
    """
    from pinocchio.visualize.meshcat_visualizer import applyScalingOnHomegeneousTransform

    h = grid.hybrid_poses[k]
    target[root].set_transform(np.asarray(h.module.oMp.homogeneous))
    pin.forwardKinematics(viz.model, viz.data, np.asarray(h.q_tool, dtype=float))
    pin.updateGeometryPlacements(viz.model, viz.data, visual, viz.visual_data)
    for gid, g in enumerate(visual.geometryObjects):
        t = applyScalingOnHomegeneousTransform(viz.visual_data.oMg[gid].homogeneous, g.meshScale)
        target[f"{root}/visuals/{g.name}"].set_transform(t)
