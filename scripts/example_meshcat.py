"""Allocation results drawn in YOUR OWN Pinocchio ``MeshcatVisualizer``, saved as a static page.

You already show your machine with ``pinocchio.visualize.MeshcatVisualizer``; pkmtol draws its
layers (error spheres over the task space, the verification cloud, P and the platform frame, the
legend) into the same ``meshcat.Visualizer`` with :func:`pkmtol.present.viewer.scene.build_scene`, leaving the
robot to you. Here "your" visualizers show the seed robot's limb URDFs, loaded the ordinary way
(``pin.buildModelsFromUrdf``) under ``/meshcat/my_robot/<limb>``, posed at the design point.

The meshcat server is pkmtol's loopback-only one (:class:`pkmtol.present.viewer.server.MeshcatServer`); it is
stopped (and reaped) when the ``with`` block ends, so the script saves the scene as one
self-contained HTML file and exits instead of blocking. Open the file in a browser.

Usage:
    python scripts/example_meshcat.py --out out/my_scene.html
    python scripts/example_meshcat.py --out scene.html --samples 500   # quicker
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pinocchio as pin
from pinocchio.visualize import MeshcatVisualizer

from pkmtol import DesignOptions, allocate, load_mechanism
from pkmtol.files import write_atomic
from pkmtol.present.viewer.options import SceneOptions
from pkmtol.present.viewer.scene import build_scene
from pkmtol.present.viewer.server import MeshcatServer

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/my_scene.html"), help="HTML file to write")
    ap.add_argument("--samples", type=int, default=10_000, help="Monte Carlo samples (default 10000)")
    args = ap.parse_args(argv)

    mech = load_mechanism(ROBOT)
    result = allocate(
        mech,
        DesignOptions(samples=args.samples, verification_poses=min(args.samples, 2_000), exact_samples=20),
    )
    pose = result.grid.poses[result.worst_index]  # the design point: most error-sensitive pose

    with MeshcatServer() as server:  # loopback only; stopped and reaped when the block ends
        vis = server.visualizer  # a meshcat.Visualizer
        # your own robot display: one Pinocchio MeshcatVisualizer per limb URDF
        for limb, q in zip(mech.limbs, pose.q, strict=True):
            assert limb.urdf_path is not None
            model, _, visual = pin.buildModelsFromUrdf(str(limb.urdf_path), str(limb.urdf_path.parent))
            viz = MeshcatVisualizer(model, visual, visual)
            viz.initViewer(viewer=vis)
            viz.loadViewerModel(rootNodeName=f"my_robot/{limb.name}")
            viz.display(np.asarray(q, dtype=float))
        # pkmtol's layers into the same viewer, without its own robot layer
        options = SceneOptions(layers=("error_spheres", "verification", "reference", "legend"), animate=False)
        summary = build_scene(result, vis, options)  # a pkmtol.present.viewer.scene.SceneSummary
        page = vis.static_html()
        pid = server.pid
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(args.out, page.encode("utf-8"))

    spheres = summary.spheres  # a pkmtol.present.viewer.layers.SpheresLayer (None had the layer been off)
    assert spheres is not None
    p = result.worst_point_m * 1e3
    print(
        f"design point P = ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm; "
        f"{spheres.count} error spheres, largest radius "
        f"{spheres.max_radius_m * 1e3:.1f} mm"
    )
    print(f"wrote {args.out} ({len(page)} characters); meshcat server {pid} stopped")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
