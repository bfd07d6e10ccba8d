"""The scene's legend: its lines, the textured 3D panel and the HTML overlay of an exported page."""

from __future__ import annotations

import contextlib
import html as html_lib
import io
from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.design.job import DesignResult
from pkmtol.present.viewer.backend import require_meshcat
from pkmtol.present.viewer.colours import VIRIDIS, viridis
from pkmtol.present.viewer.geometry import Bounds, Scene, camera_direction
from pkmtol.present.viewer.layers import SpheresLayer, VerificationLayer
from pkmtol.present.viewer.options import ROOT

#: Documented API of this module (the other names serve the scene's own modules).
__all__ = ["legend_lines"]


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
        + ", ".join(f"{round(1e3 * x) + 0.0:.0f}" for x in result.worst_point_m)
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
        if spheres.glyph == "ellipsoid":
            lines.append(
                f"Error ellipsoids ({spheres.count}): the 1σ ellipsoid of P's error, semi-axes = "
                f"{spheres.ellipsoid_scale:.4g} × √λ of its covariance"
                + (" (η_c ~ N(0,1))" if spheres.sigma_source == "search" else " (design tolerances)")
            )
        else:
            lines.append(f"Error spheres ({spheres.count}): radius = {spheres.radius_per_sigma:.4g} × {what}")
        lines.append(f"  colour viridis over σ = {rng}; largest {1e3 * spheres.max_radius_m:.0f} mm")
    v = verification
    if v is not None:
        pct = 100 * v.cloud_failed / v.cloud_samples
        design = "β = " + f"{result.design_beta:g}" if result.method_design is None else "verified"
        lines.append(
            f"Cloud at the design point only (grid point {result.worst_index}): {v.cloud_samples} "
            f"position errors Δp ({v.distribution} errors at the {design} tolerances), "
            f"×{v.cloud_magnification:.0f} around the blue Δλ* = {1e3 * result.target_m:g} mm sphere"
        )
        lines.append(
            f"  failure rate AT THE DESIGN POINT: {v.cloud_failed} of {v.cloud_samples} beyond Δλ* "
            f"({pct:.1f} %; green ‖Δp‖ ≤ Δλ*, red beyond)"
        )
        n, k = v.task_space_samples, v.task_space_failed
        lines.append(
            f"Failure rate OVER THE WHOLE TASK SPACE (the verification run, {n} samples at random "
            f"poses): {k} beyond Δλ* ({100 * k / max(n, 1):.2f} %), red dots at their poses"
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


def draw_legend(scene: Scene, result: DesignResult, lines: list[str], with_bar: bool, bounds: Bounds) -> None:
    """Draw the legend as a textured panel left of the mechanism, facing the default camera."""
    g = require_meshcat().geometry
    png = _legend_png(lines, with_bar)
    from PIL import Image

    w, h = Image.open(io.BytesIO(png)).size
    reach = bounds.radius
    width = 1.1 * reach
    height = width * h / w
    node = scene.node(f"{ROOT}/legend")
    material = g.MeshBasicMaterial(map=g.ImageTexture(image=g.PngImage(png)))
    node.set_object(g.Box([width, 0.002, height]), material)
    c, _ = camera_direction(result)
    toward = np.array([c[0], c[1], 0.0]) / np.linalg.norm(c[:2])
    right = np.array([-toward[1], toward[0], 0.0])  # seen from the camera, left to right
    t = np.eye(4)
    # the textured face is the box's -y face: local y points away from the camera
    t[:3, 0], t[:3, 1] = right, -c
    t[:3, 2] = np.cross(right, -c)
    t[:3, 3] = bounds.centre - right * 1.0 * reach + np.array([0.0, 0.0, 0.2 * reach])
    node.set_transform(t)


def legend_overlay(lines: list[str], with_bar: bool) -> str:
    """The legend as an HTML ``<div>`` overlaid on an exported page (with the colour bar)."""
    rows = "".join(f"<div>{html_lib.escape(line)}</div>" for line in lines)
    stops = ", ".join(
        f"rgb({int(255 * r)},{int(255 * g)},{int(255 * b)}) {100 * i / (len(VIRIDIS) - 1):.0f}%"
        for i, (r, g, b) in enumerate(VIRIDIS)
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
