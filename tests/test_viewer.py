"""The meshcat scene (nodes, spheres, radii), the static page, the server's lifetime and binding."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

meshcat = pytest.importorskip("meshcat")

from process_checks import alive  # noqa: E402

from pkmtol.design.job import DesignOptions, allocate  # noqa: E402
from pkmtol.exceptions import InvalidRequestError, ViewerError  # noqa: E402
from pkmtol.model.loader import load_mechanism  # noqa: E402
from pkmtol.present.viewer.browser import find_chromium, screenshot  # noqa: E402
from pkmtol.present.viewer.export import HtmlExport, export_html, show  # noqa: E402
from pkmtol.present.viewer.options import ROOT, SceneOptions  # noqa: E402
from pkmtol.present.viewer.scene import SceneSummary, build_scene  # noqa: E402
from pkmtol.present.viewer.server import MeshcatServer  # noqa: E402

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


def _server_processes(parent: int | None = None) -> list[int]:
    """Pids of live pkmtol meshcat servers (started by ``parent`` when given)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
            state = (entry / "stat").read_text().split(")")[-1].split()[0]
        except OSError:
            continue
        if b"pkmtol.present.viewer.meshcat_server" not in argv or state == "Z":
            continue
        if parent is not None:
            try:
                i = argv.index(b"--parent-pid")
            except ValueError:
                continue
            if argv[i + 1] != str(parent).encode():
                continue
        pids.append(int(entry.name))
    return pids


@pytest.fixture(scope="module")
def result():
    r = allocate(load_mechanism(ROBOT), DesignOptions(samples=2000, exact_samples=20, verification_poses=200))
    yield r
    # no server started by this test process survives the module
    if Path("/proc").is_dir():
        assert _server_processes(os.getpid()) == []


class RecordingWindow:
    """A meshcat window that records commands instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[dict] = []

    def send(self, command) -> None:
        self.commands.append(command.lower())


@pytest.fixture(scope="module")
def recorded(result):
    window = RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    summary = build_scene(result, vis)
    return summary, window.commands


def _objects(commands, prefix):
    return {
        c["path"]: c["object"] for c in commands if c["type"] == "set_object" and c["path"].startswith(prefix)
    }


def _transforms(commands, prefix):
    out = {}
    for c in commands:
        if c["type"] == "set_transform" and c["path"].startswith(prefix):
            out[c["path"]] = np.array(c["matrix"], dtype=float).reshape(4, 4).T
    return out


def test_layers_each_have_their_own_path(recorded):
    summary, commands = recorded
    assert summary.root == f"/meshcat/{ROOT}"
    assert set(summary.layers) == {"robot", "error_spheres", "verification", "reference", "legend", "ground"}
    paths = {c["path"] for c in commands if c["type"] in ("set_object", "set_transform")}
    for layer in summary.layers.values():
        assert any(p.startswith(f"/meshcat/{layer}/") or p == f"/meshcat/{layer}" for p in paths), layer
    for expected in (
        f"{ROOT}/reference/P",
        f"{ROOT}/reference/platform_frame",
        f"{ROOT}/verification/cloud/target",
        f"{ROOT}/verification/cloud/safe",
        f"{ROOT}/verification/task_space/safe",
        f"{ROOT}/legend",
    ):
        assert expected in summary.nodes, expected
        assert f"/meshcat/{expected}" in paths, expected


def test_one_sphere_per_grid_point_with_radius_proportional_to_sigma(result, recorded):
    summary, commands = recorded
    m = len(result.grid.points_m)
    assert m == 147
    spheres = summary.spheres
    assert spheres is not None and spheres.count == m
    assert spheres.paths == tuple(f"{ROOT}/error_spheres/{k}" for k in range(m))
    assert spheres.colors_rgb.shape == (m, 3) and spheres.sigma_source == "search"
    objs = _objects(commands, f"/meshcat/{ROOT}/error_spheres/")
    assert len(objs) == m
    tfs = _transforms(commands, f"/meshcat/{ROOT}/error_spheres/")
    radii = np.empty(m)
    for k in range(m):
        path = f"/meshcat/{ROOT}/error_spheres/{k}"
        geometry = objs[path]["geometries"][0]
        assert geometry["type"] == "SphereGeometry"
        radii[k] = geometry["radius"]
        np.testing.assert_allclose(tfs[path][:3, 3], result.grid.points_m[k], atol=1e-12)
    sigma = result.search.sigma_analytic_m
    np.testing.assert_allclose(radii, spheres.radius_per_sigma * sigma, rtol=1e-9)
    np.testing.assert_allclose(radii, spheres.radii_m, rtol=1e-9)
    np.testing.assert_allclose(radii / sigma, radii[0] / sigma[0], rtol=1e-9)
    # the largest sphere is the design point, and spheres do not touch
    assert int(np.argmax(radii)) == result.worst_index
    d = np.linalg.norm(result.grid.points_m[:, None] - result.grid.points_m[None], axis=-1)
    d[np.diag_indices(m)] = np.inf
    assert 2 * radii.max() < d.min()
    # colour map: the largest σ is the brightest (viridis yellow), the smallest the darkest
    colours = np.array(
        [objs[f"/meshcat/{ROOT}/error_spheres/{k}"]["materials"][0]["color"] for k in range(m)]
    )
    assert colours[int(np.argmax(sigma))] != colours[int(np.argmin(sigma))]
    assert any("radius =" in line for line in summary.legend)


def test_design_sigma_option(result):
    window = RecordingWindow()
    s = build_scene(
        result,
        meshcat.Visualizer(window=window),
        SceneOptions(sigma="design", layers=("error_spheres",), animate=False),
    )
    assert s.spheres is not None and s.spheres.sigma_source == "design"
    # at the design point the design-β tolerances give σ[Δλ] of the order of Δλ*
    sig = s.spheres.sigma_m
    assert 0.05 * result.target_m < sig[result.worst_index] < result.target_m
    np.testing.assert_allclose(s.spheres.radii_m, s.spheres.radius_per_sigma * sig)
    assert s.robot_paths == () and s.verification is None and s.animation_frames == 0


def test_robot_limbs_are_posed_consistently_at_the_design_point(result, recorded):
    summary, commands = recorded
    pose = result.grid.poses[result.worst_index]
    platform = []
    for limb in result.mechanism.limbs:
        root = f"/meshcat/{ROOT}/robot/{limb.name}/visuals/"
        assert f"{ROOT}/robot/{limb.name}" in summary.robot_paths
        objs = _objects(commands, root)
        assert len(objs) == limb.visual_model.ngeoms
        tfs = _transforms(commands, root)
        g = limb.visual_model.geometryObjects[limb.visual_model.getGeometryId("platform_0")]
        platform.append(tfs[root + "platform_0"])
        # geometry placements are relative to the parent joint; oMp is the platform frame's
        joint_of_platform = limb.model.frames[limb.platform_frame].placement
        expected = pose.oMp * joint_of_platform.inverse() * g.placement
        np.testing.assert_allclose(platform[-1], expected.homogeneous, atol=1e-9)
    for t in platform[1:]:
        np.testing.assert_allclose(t, platform[0], atol=1e-9)
    # reference point and platform frame at the same pose
    ref = _transforms(commands, f"/meshcat/{ROOT}/reference/")
    np.testing.assert_allclose(ref[f"/meshcat/{ROOT}/reference/P"][:3, 3], pose.p_m, atol=1e-12)
    np.testing.assert_allclose(
        ref[f"/meshcat/{ROOT}/reference/platform_frame"], pose.oMp.homogeneous, atol=1e-12
    )


def test_animation_visits_every_grid_point(result, recorded):
    summary, commands = recorded
    anims = [c for c in commands if c["type"] == "set_animation"]
    assert len(anims) == 1
    assert anims[0]["options"]["play"] is False
    assert summary.animation_frames == len(result.grid.points_m)
    tracks = {a["path"] for a in anims[0]["animations"]}
    assert f"/meshcat/{ROOT}/reference/P" in tracks
    assert f"/meshcat/{ROOT}/robot/limb1/visuals/platform_0" in tracks


def test_verification_layer(result, recorded):
    summary, commands = recorded
    v = summary.verification
    assert v is not None and v.distribution == "gaussian" and v.cloud_center_m.shape == (3,)
    ver = result.verification["gaussian"]
    objs = _objects(commands, f"/meshcat/{ROOT}/verification/")
    n_points = 0
    for name in ("safe", "failed"):
        path = f"/meshcat/{ROOT}/verification/task_space/{name}"
        if path in objs:
            packed = objs[path]["geometries"][0]["data"]["attributes"]["position"]
            assert packed["itemSize"] == 3 and packed["type"] == "Float32Array"
            n_points += len(packed["array"].data) // 12
    assert n_points == ver.dlam_linear_m.size == v.task_space_samples
    assert v.task_space_failed == int(np.sum(ver.dlam_linear_m > result.target_m))
    target = objs[f"/meshcat/{ROOT}/verification/cloud/target"]
    assert target["geometries"][0]["radius"] == pytest.approx(v.cloud_target_radius_m)
    assert v.cloud_magnification == pytest.approx(v.cloud_target_radius_m / result.target_m)
    assert 0 < v.cloud_failed < v.cloud_samples


def test_layers_option_draws_only_those(result):
    window = RecordingWindow()
    s = build_scene(result, meshcat.Visualizer(window=window), SceneOptions(layers=("robot",)))
    paths = {c["path"] for c in window.commands if c["type"] == "set_object"}
    assert all(p.startswith(f"/meshcat/{ROOT}/robot/") for p in paths)
    assert s.spheres is None and s.verification is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.spheres = None  # type: ignore[misc]
    assert set(s.layers) == {"robot"} and len(s.robot_paths) == len(result.mechanism.limbs)
    assert not any("Error spheres" in line or "Verification" in line for line in s.legend)


def test_bad_options_are_refused():
    from pkmtol.exceptions import InvalidRequestError

    with pytest.raises(InvalidRequestError):
        SceneOptions(layers=("robots",))
    with pytest.raises(InvalidRequestError):
        SceneOptions(sigma="x")


def test_missing_meshcat_is_actionable(monkeypatch, result):
    monkeypatch.setitem(sys.modules, "meshcat", None)
    with pytest.raises(ViewerError, match="pip install meshcat"):
        build_scene(result, object())


# --- the server ------------------------------------------------------------------------------


def _listening_addresses(pid: int) -> list[str]:
    """Local addresses (hex, as in /proc/net/tcp*) of the sockets ``pid`` listens on."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not Path(table).exists():
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            f = line.split()
            if f[3] == "0A" and f[9] in inodes:  # LISTEN
                out.append(f[1])
    return out


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="needs Linux /proc")
def test_server_listens_on_loopback_only_and_is_reaped():
    with MeshcatServer() as server:
        assert server.zmq_url.startswith("tcp://127.0.0.1:")
        assert server.web_url.startswith("http://127.0.0.1:")
        addresses = []
        for _ in range(50):  # the HTTP port opens just after the URLs are printed
            addresses = _listening_addresses(server.pid)
            if len(addresses) >= 2:
                break
            time.sleep(0.1)
        assert len(addresses) >= 2  # ZeroMQ and HTTP
        assert all(a.split(":")[0] == "0100007F" for a in addresses), addresses
        pid = server.pid
        assert alive(pid)
    assert not alive(pid)
    assert server.proc.returncode is not None


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs Linux /proc")
def test_server_exits_when_its_parent_is_killed():
    code = textwrap.dedent(
        """
        import os, sys
        from pkmtol.present.viewer.server import MeshcatServer
        s = MeshcatServer()
        print(s.pid, flush=True)
        os._exit(0)  # no atexit, no close: as if killed
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    pid = int(out.stdout.split()[0])
    deadline = time.monotonic() + 10
    while alive(pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(pid)


def test_export_html(result, tmp_path):
    path = tmp_path / "scene.html"
    s = export_html(result, path)
    assert isinstance(s, HtmlExport) and isinstance(s.scene, SceneSummary)
    assert s.path == path and path.stat().st_size == s.bytes
    assert s.scene.spheres is not None
    page = path.read_text(encoding="utf-8")
    assert page.count('fetch("data:application/octet-binary;base64,') >= s.scene.spheres.count
    assert 'id="pkmtol-legend"' in page and "Error spheres (147)" in page
    assert "MeshCat.Viewer" in page
    assert not alive(s.server_pid)
    assert [p.name for p in tmp_path.iterdir()] == ["scene.html"]  # no temporary file left
    if Path("/proc").is_dir():
        assert _server_processes(os.getpid()) == []


def test_export_into_missing_folder_writes_nothing(result, tmp_path):
    from pkmtol.exceptions import OutputError

    with pytest.raises(OutputError):
        export_html(result, tmp_path / "nope" / "scene.html")
    assert list(tmp_path.iterdir()) == []


# --- the page in a browser ---------------------------------------------------------------------


def _pixels(png: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(png).convert("RGB"), dtype=float)


def _orange(img: np.ndarray) -> np.ndarray:
    """Pixels of the prismatic legs' orange (URDF rgba 0.8 0.5 0.1), lit or shaded."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 60) & (r > 1.3 * g) & (g > 1.6 * b + 5)


@pytest.mark.skipif(find_chromium() is None, reason="no chromium binary (apt-get install chromium)")
def test_static_page_renders_in_headless_chromium(result, tmp_path):
    shots = {}
    for name, layers in (
        ("full", None),
        ("no_robot", ("error_spheres", "verification", "reference")),
        ("no_spheres", ("robot", "verification", "reference")),
    ):
        opt = SceneOptions() if layers is None else SceneOptions(layers=layers)
        html = export_html(result, tmp_path / f"{name}.html", opt).path
        shots[name] = _pixels(screenshot(html, tmp_path / f"{name}.png", size=(1200, 900)))
    full = shots["full"]
    assert full.shape == (900, 1200, 3)
    # Thresholds: an empty scene (grid, controls bar, legend) measures std 21, 1.2 % of the view
    # not background, 70 orange pixels; this scene 40, 8 %, 3000 (swiftshader, 1200 × 900).
    # not blank: strong pixel variation, and a good part of the view is not the white background
    assert full.std() > 30
    scene = full[30:700]  # below the controls bar, above the legend overlay
    not_background = np.any(np.abs(scene - 255) > 30, axis=-1)
    assert not_background.mean() > 0.05
    # the robot is visible: its orange legs are there, and gone when the robot layer is hidden
    assert _orange(full).sum() > 1500
    assert _orange(shots["no_robot"]).sum() < 0.2 * _orange(full).sum()
    assert np.any(np.abs(full - shots["no_robot"]) > 40, axis=-1).mean() > 0.003
    # the spheres are visible: hiding them changes a large part of the picture
    assert np.any(np.abs(full - shots["no_spheres"]) > 40, axis=-1).mean() > 0.03
    # the camera frames the mechanism: its orange legs lie near the middle of the picture
    ys, xs = np.nonzero(_orange(full))
    assert abs(xs.mean() / 1200 - 0.5) < 0.12 and abs(ys.mean() / 900 - 0.5) < 0.12
    # the mechanism fills at least a third of the view (robot layer alone: every pixel that is
    # not the white background, below the controls bar and apart from the legend's box)
    page = export_html(result, tmp_path / "robot.html", SceneOptions(layers=("robot",))).path
    robot = _pixels(screenshot(page, tmp_path / "robot.png", size=(1200, 900)))
    drawn = np.any(np.abs(robot - 255) > 30, axis=-1)
    drawn[:30] = False  # the controls bar
    drawn[820:, :420] = False  # the legend (2 lines without the error layers)
    ys, xs = np.nonzero(drawn)
    assert max((xs.max() - xs.min()) / 1200, (ys.max() - ys.min()) / 900) >= 1 / 3
    # and the whole mechanism is in view: no orange on the picture's border
    border = _orange(full).copy()
    border[10:-10, 10:-10] = False
    assert border.sum() == 0
    if Path("/proc").is_dir():
        assert _server_processes(os.getpid()) == []


def test_limb_without_visuals_is_drawn_as_a_skeleton(result):
    from pkmtol.present.viewer.geometry import skeleton_geometry

    limbs = tuple(dataclasses.replace(limb, visual_model=None) for limb in result.mechanism.limbs)
    bare = dataclasses.replace(result, mechanism=dataclasses.replace(result.mechanism, limbs=limbs))
    window = RecordingWindow()
    build_scene(bare, meshcat.Visualizer(window=window), SceneOptions(layers=("robot",)))
    for limb in limbs:
        objs = _objects(window.commands, f"/meshcat/{ROOT}/robot/{limb.name}/visuals/")
        expected = skeleton_geometry(limb.model).ngeoms
        assert expected >= limb.nq  # a ball per joint, and rods
        assert len(objs) == expected


def test_show_serves_the_scene_on_loopback(result):
    import urllib.request

    lines: list[str] = []
    server = show(result, block=False, out=lines.append)
    try:
        assert lines[0] == f"meshcat viewer: {server.web_url}"
        assert server.web_url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(server.web_url, timeout=10) as page:
            assert page.status == 200
    finally:
        server.close()
    assert not alive(server.pid)


# --- framing, ground, glyphs, legend (issue 16) ------------------------------------------------


def test_camera_frames_the_mechanism_and_the_task_space(result, recorded):
    from pkmtol.present.viewer.geometry import CAMERA_FOV_DEG, camera_distance, mechanism_points

    summary, commands = recorded
    b = summary.bounds
    pts = np.vstack([mechanism_points(result), result.grid.points_m])
    assert np.all(pts >= b.low) and np.all(pts <= b.high)
    # the pkmtol node is shifted so that the box's centre is meshcat's origin (the orbit target)
    np.testing.assert_allclose(summary.offset_m, -b.centre)
    root = _transforms(commands, f"/meshcat/{ROOT}")[f"/meshcat/{ROOT}"]
    np.testing.assert_allclose(root[:3, 3], -b.centre) and np.testing.assert_allclose(root[:3, :3], np.eye(3))
    cam = [
        c
        for c in commands
        if c["type"] == "set_property" and c["path"] == "/Cameras/default/rotated/<object>"
    ]
    d = summary.camera_m
    assert cam[-1]["value"] == pytest.approx([d[0], d[2], -d[1]])
    # closer than the sphere around the box (the mechanism used to be small beside the spheres)
    assert np.linalg.norm(d) < 0.8 * camera_distance(b.radius)
    # every joint and grid point is in the image: within half the vertical FOV across and up
    f = -d / np.linalg.norm(d)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    rays = pts - (b.centre + d)
    depth = rays @ f
    half = np.tan(np.radians(CAMERA_FOV_DEG / 2))
    assert np.all(depth > 0)
    assert np.max(np.abs(rays @ right) / depth) < half and np.max(np.abs(rays @ up) / depth) < half


def _in_scene(commands, path: str) -> np.ndarray:
    """The transform of ``path`` in meshcat's scene: the product of its own and its ancestors'."""
    every = _transforms(commands, "/meshcat")
    parts = path.split("/")
    out = np.eye(4)
    for k in range(2, len(parts) + 1):
        out = out @ every.get("/".join(parts[:k]), np.eye(4))
    return out


def _rod_ends(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ends of meshcat's unit cylinder (axis y, centred) under ``matrix``."""
    return (matrix @ [0.0, -0.5, 0.0, 1.0])[:3], (matrix @ [0.0, 0.5, 0.0, 1.0])[:3]


def test_every_limb_is_drawn_link_to_link_from_its_base_joint_to_the_platform(result, recorded):
    import pinocchio as pin

    summary, commands = recorded
    offset = _transforms(commands, f"/meshcat/{ROOT}")[f"/meshcat/{ROOT}"][:3, 3]
    pose = result.grid.poses[result.worst_index]
    platform_ends = []
    for i, limb in enumerate(result.mechanism.limbs):
        prefix = f"/meshcat/{ROOT}/robot/{limb.name}/links/"
        rods = _transforms(commands, prefix)
        assert len(rods) == len(summary.links_m[i]) >= 1
        ends = [_rod_ends(_in_scene(commands, f"{prefix}{k}")) for k in range(len(rods))]
        data = limb.model.createData()
        pin.framesForwardKinematics(limb.model, data, np.asarray(pose.q[i], dtype=float))
        base = data.oMi[1].translation + offset
        platform = data.oMf[limb.platform_frame].translation + offset
        # the first rod starts at the base joint, each next one where an earlier one ends, the
        # last ends at the platform frame: no leg stops short of its joints
        np.testing.assert_allclose(ends[0][0], base, atol=1e-9)
        for k in range(1, len(ends)):
            gaps = [np.linalg.norm(ends[k][0] - ends[j][1]) for j in range(k)]
            assert min(gaps) < 1e-9, (limb.name, k)
        np.testing.assert_allclose(ends[-1][1], platform, atol=1e-9)
        np.testing.assert_allclose(np.array(ends), summary.links_m[i] + offset, atol=1e-9)
        platform_ends.append(ends[-1][1])
    # the limbs meet at one platform frame (closed to the solver's tolerance)
    assert np.ptp(np.array(platform_ends), axis=0).max() < 1e-9
    # the platform is drawn once, see-through: the other limbs' copies are hidden
    hidden = {c["path"] for c in commands if c["type"] == "set_property" and c["property"] == "visible"}
    for limb in result.mechanism.limbs[1:]:
        assert any(p.startswith(f"/meshcat/{ROOT}/robot/{limb.name}/visuals/") for p in hidden)


def test_ground_grid_lies_under_the_base(result, recorded):
    from pkmtol.present.viewer.geometry import mechanism_points

    summary, commands = recorded
    z, step = summary.ground
    assert z < mechanism_points(result)[:, 2].min() and step == pytest.approx(0.2)
    grid = _objects(commands, f"/meshcat/{ROOT}/ground")[f"/meshcat/{ROOT}/ground"]
    assert grid["object"]["type"] == "LineSegments"
    pos = grid["geometries"][0]["data"]["attributes"]["position"]["array"]
    xyz = np.frombuffer(pos.data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(xyz[:, 2], z, atol=1e-6)
    b = summary.bounds
    assert xyz[:, 0].min() <= b.low[0] and xyz[:, 0].max() >= b.high[0]
    assert xyz[:, 1].min() <= b.low[1] and xyz[:, 1].max() >= b.high[1]
    hidden = {
        c["path"]: c["value"] for c in commands if c["type"] == "set_property" and c["property"] == "visible"
    }
    assert hidden["/Grid"] is False and hidden["/Axes"] is False


def test_spheres_are_small_and_see_through(result, recorded):
    summary, commands = recorded
    objs = _objects(commands, f"/meshcat/{ROOT}/error_spheres/")
    materials = [o["materials"][0] for o in objs.values()]
    assert all(m["opacity"] == pytest.approx(0.35) and m["transparent"] for m in materials)
    d = np.linalg.norm(result.grid.points_m[:, None] - result.grid.points_m[None], axis=-1)
    d[np.diag_indices(len(d))] = np.inf
    assert summary.spheres.max_radius_m == pytest.approx(0.2 * d.min())


def test_ellipsoid_glyph_is_the_covariance_of_the_error(result):
    window = RecordingWindow()
    s = build_scene(result, meshcat.Visualizer(window=window), SceneOptions(glyph="ellipsoid", animate=False))
    e = s.spheres
    assert e.glyph == "ellipsoid" and e.semi_axes_m.shape == (147, 3) and e.axes.shape == (147, 3, 3)
    L = result.maps.position[:, :, result.uncompensatable]
    cov = L @ np.swapaxes(L, 1, 2)  # η_c ~ N(0, 1): the pose search's quantity
    tfs = _transforms(window.commands, f"/meshcat/{ROOT}/error_spheres/")
    objs = _objects(window.commands, f"/meshcat/{ROOT}/error_spheres/")
    for k in (0, result.worst_index, 100):
        lam = np.sort(np.linalg.eigvalsh(cov[k]))[::-1]
        expected = np.maximum(e.ellipsoid_scale * np.sqrt(np.clip(lam, 0, None)), 0.02 * e.max_radius_m)
        np.testing.assert_allclose(e.semi_axes_m[k], expected, rtol=1e-9)
        V = e.axes[k]
        np.testing.assert_allclose(V.T @ V, np.eye(3), atol=1e-9)
        assert np.linalg.det(V) == pytest.approx(1.0)
        # the covariance's eigenvectors: V diag(λ) Vᵀ = Σ
        np.testing.assert_allclose(V @ np.diag(lam) @ V.T, cov[k], atol=1e-12 * lam[0])
        t = tfs[f"/meshcat/{ROOT}/error_spheres/{k}"]
        np.testing.assert_allclose(t[:3, :3], V * e.semi_axes_m[k][None, :], atol=1e-12)
        np.testing.assert_allclose(t[:3, 3], result.grid.points_m[k], atol=1e-12)
        assert objs[f"/meshcat/{ROOT}/error_spheres/{k}"]["geometries"][0]["radius"] == 1.0
    assert e.semi_axes_m[:, 0].max() == pytest.approx(e.max_radius_m)
    assert any(line.startswith("Error ellipsoids (147)") for line in s.legend)
    with pytest.raises(InvalidRequestError):
        SceneOptions(glyph="cube")
    with pytest.raises(InvalidRequestError):
        SceneOptions(sphere_opacity=0.0)


def test_design_spheres_and_cloud_come_from_the_modes_maps(result):
    """The layers read result.maps (J, L or J_total), not grid.J: doubling the maps doubles σ and Δp."""
    doubled = dataclasses.replace(
        result, maps=dataclasses.replace(result.maps, position=2 * result.maps.position)
    )
    opt = SceneOptions(sigma="design", layers=("error_spheres", "verification"), animate=False)
    one = build_scene(result, meshcat.Visualizer(window=RecordingWindow()), opt)
    two = build_scene(doubled, meshcat.Visualizer(window=RecordingWindow()), opt)
    np.testing.assert_allclose(two.spheres.sigma_m, 2 * one.spheres.sigma_m, rtol=1e-9)
    assert two.verification.cloud_failed > one.verification.cloud_failed


def test_legend_says_which_failure_rate_is_which(result, recorded):
    summary, _ = recorded
    v = summary.verification
    design = [line for line in summary.legend if "AT THE DESIGN POINT" in line]
    whole = [line for line in summary.legend if "OVER THE WHOLE TASK SPACE" in line]
    assert len(design) == 1 and len(whole) == 1
    assert f"{v.cloud_failed} of {v.cloud_samples} beyond Δλ*" in design[0]
    assert f"{v.task_space_failed} beyond Δλ*" in whole[0] and f"{v.task_space_samples} samples" in whole[0]
    assert "TASK SPACE" not in design[0] and "DESIGN POINT" not in whole[0]
