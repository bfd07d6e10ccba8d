"""The hybrid in the 3D scene: the wrist and the spindle on the platform, error spheres at the TCP."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

meshcat = pytest.importorskip("meshcat")

from pkmtol.cli.common import apply_tool_options  # noqa: E402
from pkmtol.design.job import DesignOptions, allocate  # noqa: E402
from pkmtol.model.loader import load_mechanism  # noqa: E402
from pkmtol.present.viewer.options import ROOT  # noqa: E402
from pkmtol.present.viewer.scene import build_scene  # noqa: E402

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups_wrist"


class _Args:
    tool_length, compensate_with, lock_wrist = None, "module", None


class RecordingWindow:
    """A meshcat window that records commands instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[dict] = []

    def send(self, command) -> None:
        self.commands.append(command.lower())


@pytest.fixture(scope="module")
def scene():
    mech = apply_tool_options(load_mechanism(ROBOT), _Args())
    r = allocate(mech, DesignOptions(samples=1000, exact_samples=10, verification_poses=50))
    window = RecordingWindow()
    summary = build_scene(r, meshcat.Visualizer(window=window))
    return r, summary, window.commands


def _transforms(commands, prefix):
    out = {}
    for c in commands:
        if c["type"] == "set_transform" and c["path"].startswith(prefix):
            out[c["path"]] = np.array(c["matrix"], dtype=float).reshape(4, 4).T
    return out


def test_the_tool_chain_is_drawn_on_the_platform_at_the_design_pose(scene):
    r, summary, commands = scene
    root = f"{ROOT}/robot/tool"
    assert root in summary.robot_paths
    h = r.grid.hybrid_poses[r.worst_index]
    tfs = _transforms(commands, f"/meshcat/{root}")
    np.testing.assert_allclose(tfs[f"/meshcat/{root}"], h.module.oMp.homogeneous, atol=1e-12)
    tool = r.mechanism.tool
    data = tool.model.createData()
    pin.framesForwardKinematics(tool.model, data, h.q_tool)
    visual = tool.visual_model
    nose = next(
        g for g in visual.geometryObjects if g.parentFrame == tool.nose_frame or g.name.startswith("spindle")
    )
    placed = tfs[f"/meshcat/{root}/visuals/{nose.name}"]
    # the geometry's pose in K (the tool node's placement composed with its own) is Pinocchio's
    expected = h.module.oMp * data.oMi[nose.parentJoint] * nose.placement
    np.testing.assert_allclose(h.module.oMp.homogeneous @ placed, expected.homogeneous, atol=1e-9)


def test_reference_point_and_error_spheres_sit_at_the_tcp(scene):
    r, summary, commands = scene
    ref = _transforms(commands, f"/meshcat/{ROOT}/reference/")
    np.testing.assert_allclose(
        ref[f"/meshcat/{ROOT}/reference/P"][:3, 3], r.grid.points_m[r.worst_index], atol=1e-12
    )
    np.testing.assert_allclose(
        r.grid.points_m[r.worst_index], r.grid.hybrid_poses[r.worst_index].tcp_m, atol=1e-11
    )
    spheres = [
        c
        for c in commands
        if c["type"] == "set_object" and c["path"].startswith(f"/meshcat/{ROOT}/error_spheres/")
    ]
    assert len(spheres) >= len(r.grid.points_m)
    anims = [c for c in commands if c["type"] == "set_animation"]
    tracks = {a["path"] for a in anims[0]["animations"]}
    assert f"/meshcat/{ROOT}/robot/tool" in tracks
