"""Regenerate the README's images: docs/img/scene.png and scene_ellipsoids.png (the meshcat scene in
headless Chromium, error spheres and error ellipsoids) and
docs/img/{sensitivity,dlambda_histogram,tolerances,contributions}.png (the report's figures).

Usage: python scripts/make_doc_images.py [ROBOT] [--out DIR]
Needs matplotlib and a Chromium binary (Debian: apt-get install chromium).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from pkmtol.design.job import DesignOptions, allocate
from pkmtol.model.loader import load_mechanism
from pkmtol.present.figures import write_figures
from pkmtol.present.viewer.browser import screenshot
from pkmtol.present.viewer.export import export_html
from pkmtol.present.viewer.options import SceneOptions

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("robot", nargs="?", default=str(ROOT / "robots" / "r2rps_ups"))
    parser.add_argument("--out", default=str(ROOT / "docs" / "img"))
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    # the default sample counts, with a smaller exact-kinematics subsample (the figures use the
    # linear-model samples; the exact subsample only adds a line to the histogram's legend)
    result = allocate(load_mechanism(args.robot), DesignOptions(exact_samples=100))
    print(f"design computed in {time.perf_counter() - t0:.1f} s")
    for path in write_figures(result, out, formats=("png",)):
        print(f"wrote {path}")
    with tempfile.TemporaryDirectory() as tmp:
        html = export_html(result, Path(tmp) / "scene.html").path
        print(f"wrote {screenshot(html, out / 'scene.png', size=(1200, 900))}")
        html = export_html(result, Path(tmp) / "ellipsoids.html", SceneOptions(glyph="ellipsoid")).path
        print(f"wrote {screenshot(html, out / 'scene_ellipsoids.png', size=(1200, 900))}")


if __name__ == "__main__":
    main()
