"""One self-contained HTML page a designer signs off: every table, the figures as inline SVG, the 3D scene.

The page (``pkmtol allocate --report FILE.html``, :func:`write_report`) holds:

* "at a glance": the requirement, the verified design's reliability, Cpk, PPM, worst case;
* every section of the text report (:func:`pkmtol.present.tables.summary_text`, converted from its
  Markdown form), each figure inline as SVG after the section it belongs to (the Pareto figure
  after the contributions, the Δλ histogram after the verification, …);
* the 3D scene (meshcat's ``static_html``, :func:`pkmtol.present.viewer.export.render_html`) in an
  ``<iframe srcdoc>``;
* the provenance: pkmtol's version and git commit, the input files' SHA-256, the seed and the
  command line (:mod:`pkmtol.present.provenance`).

Nothing is fetched when it is opened: scripts, styles, images and the scene's geometry are inline
(``data:`` URLs at most), and a Content-Security-Policy (:data:`CSP`) forbids any network request
from the page and its frame. Sections are wrapped in classes ``pkmtol-tables``,
``pkmtol-figure`` and ``pkmtol-scene``, with anchors ``#scene``, ``#figure-<stem>`` and
``#section-<k>``.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pkmtol.values as values
from pkmtol.design.job import DesignResult
from pkmtol.design.signoff import sign_off
from pkmtol.exceptions import FiguresError, OutputError
from pkmtol.files import write_atomic
from pkmtol.present.headline import claim_line
from pkmtol.present.provenance import Provenance, provenance
from pkmtol.present.tables import summary_text

#: The page's Content-Security-Policy: inline code and ``data:``/``blob:`` only, no network.
CSP = (
    "default-src 'none'; script-src 'unsafe-inline' 'unsafe-eval'; style-src 'unsafe-inline'; "
    "img-src data: blob:; connect-src data: blob:; font-src data:; media-src data: blob:; "
    "worker-src blob:; frame-src data: blob: about:"
)
#: Where each figure goes: after the first section whose heading starts with this.
FIGURE_PLACES = {
    "sensitivity": "Tolerances",
    "tolerances": "Tolerances",
    "contributions": "Contributions to E[Δλ²]",
    "dlambda_histogram": "Verification of",
}
#: Height of the 3D scene's frame [CSS px].
SCENE_HEIGHT_PX = 680

_STYLE = """
body{font:14px/1.4 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d1d1f;margin:0 auto;
max-width:1400px;padding:0 24px 48px}
h1{font-size:24px;margin:24px 0 4px}h2{font-size:18px;margin:28px 0 6px;border-bottom:1px solid #ccc}
p{margin:4px 0}table{border-collapse:collapse;margin:8px 0;font-size:12.5px}
td,th{border:1px solid #d0d0d0;padding:2px 7px;text-align:left;vertical-align:top}th{background:#f0f2f5}
td.num{text-align:right;font-variant-numeric:tabular-nums}tr:nth-child(even) td{background:#fafafa}
figure{margin:12px 0}figure svg{max-width:100%;height:auto}figcaption{color:#555;font-size:12px}
iframe.pkmtol-scene-frame{width:100%;border:1px solid #bbb}.meta{color:#555;font-size:12px}
table.glance td:first-child{font-weight:600}
"""


@dataclass(frozen=True)
class RenderedReport:
    """A report rendered in memory (:func:`render_report`), not yet written.

    Attributes:
        data: The page (UTF-8).
        sections: The headings of the report's sections, in order.
        figures: The figure stems embedded (empty without matplotlib).
        figures_missing: Why figures are missing (None when they are there).
        scene: The 3D scene's :class:`~pkmtol.present.viewer.scene.SceneSummary` (None without).
    """

    data: bytes
    sections: tuple[str, ...]
    figures: tuple[str, ...]
    figures_missing: str | None
    scene: Any


def svg_inline(svg: str, prefix: str) -> str:
    """A matplotlib SVG document made fit to inline: no XML prolog or metadata, ids prefixed.

    Several SVGs in one HTML page share one id space; every ``id`` and reference to it
    (``href="#…"``, ``url(#…)``) gets ``prefix-`` so that clip paths and glyphs do not collide.
    """
    start = svg.find("<svg")
    body = svg[start:] if start >= 0 else svg
    body = re.sub(r"<metadata>.*?</metadata>", "", body, flags=re.S)
    body = re.sub(r'\s+xmlns(:xlink)?="[^"]*"', "", body, count=2)
    body = re.sub(r'\bid="([^"]+)"', rf'id="{prefix}-\1"', body)
    body = re.sub(r'(href)="#([^"]+)"', rf'\1="#{prefix}-\2"', body)
    return re.sub(r"url\(#([^)]+)\)", rf"url(#{prefix}-\1)", body)


def figure_svgs(result: DesignResult) -> dict[str, str]:
    """Every figure as an inline-ready SVG string, by stem (:data:`pkmtol.present.figures.FIGURES`).

    Raises:
        FiguresError: matplotlib is missing.
    """
    from pkmtol.present.figures import make_figures
    from pkmtol.present.plotting import render, require_matplotlib

    require_matplotlib()
    import matplotlib

    out = {}
    for stem, fig in make_figures(result).items():
        with matplotlib.rc_context({"svg.hashsalt": stem, "svg.fonttype": "path"}):
            out[stem] = svg_inline(render(fig, "svg", 100).decode("utf-8"), stem)
    return out


def _cell(text: str) -> str:
    numeric = re.fullmatch(r"[±+\-−<>]?\s*[\d.]+(e[-+]?\d+)?\s*(\(.*\))?|[\d.]+–[\d.]+|-|\+inf", text.strip())
    cls = ' class="num"' if numeric else ""
    return f"<td{cls}>{html.escape(text)}</td>"


def markdown_sections(md: str) -> list[tuple[str, str]]:
    """The text report's Markdown (as ``summary_text(markdown=True)`` writes it) as ``(heading, html)``.

    Handles exactly what that writer produces: ``#``/``##`` headings, pipe tables (header row,
    ``|---|`` rule) and paragraphs; everything is HTML-escaped.
    """
    sections: list[tuple[str, list[str]]] = [("", [])]
    lines = md.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("## ") or line.startswith("# "):
            sections.append((line.lstrip("#").strip(), []))
        elif line.startswith("|"):
            block = []
            while i < len(lines) and lines[i].startswith("|"):
                block.append([c.strip() for c in lines[i].strip()[1:-1].split(" | ")])
                i += 1
            rows = [b for b in block if not all(set(c) <= {"-", "|", ""} for c in b)]
            head = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
            body = "".join("<tr>" + "".join(_cell(c) for c in row) + "</tr>" for row in rows[1:])
            sections[-1][1].append(f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
            continue
        elif line.strip():
            sections[-1][1].append(f"<p>{html.escape(line)}</p>")
        i += 1
    return [(h, "\n".join(parts)) for h, parts in sections if h or parts]


def _glance(r: DesignResult) -> str:
    so = sign_off(r)
    cap, st, w = so.capability, so.stackup, so.design_index
    gauss = r.verification.get("gaussian")
    p = ", ".join(f"{1e3 * x:.1f}" for x in r.worst_point_m)
    rows = [
        ("mechanism", f"{r.mechanism.name} — {r.mechanism.description}".rstrip(" —")),
        (
            "requirement",
            f"Δλ* = {1e3 * r.target_m:g} mm at P, β = {r.design_beta:g} (R* = Φ(β) = "
            f"{100 * so.reliability_target:.2f} %), compensation '{r.compensation}'",
        ),
        *([] if r.claim is None else [("claim", claim_line(r.claim, r.compensation == "calibrated"))]),
        (
            "design",
            ("FOSM (Eq. 20)" if r.method_design is None else f"'{r.method_design.method}'")
            + f", {len(so.columns)} toleranced errors, drawing convention {so.drawing.short_label}",
        ),
        ("design point", f"P = ({p}) mm, grid pose {w}"),
        ("exact R at the design point", f"{100 - cap.ppm[w] / 1e4:.3f} % ({cap.ppm[w]:.0f} PPM out of spec)"),
        (
            "worst grid pose",
            f"{cap.ppm.max():.0f} PPM at pose {cap.worst_ppm_index}; mean over the grid "
            f"{cap.ppm.mean():.0f} PPM",
        ),
        (
            "Cpk",
            f"{cap.cpk[w]:.3f} at the design point, {cap.cpk.min():.3f} lowest (pose {cap.worst_cpk_index})",
        ),
        (
            "stack-up of ±t",
            f"worst case {1e6 * st.worst_case_m[w]:.1f} µm, RSS {1e6 * st.rss_m[w]:.1f} µm, "
            f"exact {100 * so.reliability_target:.2f} % quantile {1e6 * cap.quantile[w]:.1f} µm",
        ),
    ]
    if gauss is not None:
        f = gauss.linear
        rows.append(
            (
                "verification (Gaussian, linear)",
                f"{100 * f.failure_fraction:.2f} % of {f.samples} "
                f"random task-space samples beyond Δλ* (95 % CI {100 * f.failure_ci95[0]:.2f}–"
                f"{100 * f.failure_ci95[1]:.2f} %)",
            )
        )
    body = "".join(f"<tr><td>{html.escape(a)}</td><td>{html.escape(b)}</td></tr>" for a, b in rows)
    return f'<table class="glance"><tbody>{body}</tbody></table>'


def _provenance_html(prov: Provenance) -> str:
    body = "".join(
        f"<tr><td>{html.escape(a)}</td><td><code>{html.escape(b)}</code></td></tr>" for a, b in prov.rows()
    )
    return f"<table><tbody>{body}</tbody></table>"


def report_html(
    result: DesignResult,
    prov: Provenance,
    figures: dict[str, str] | None = None,
    scene_page: str | None = None,
    note: str | None = None,
) -> tuple[str, list[str]]:
    """The page's HTML text and its section headings (nothing drawn or written here).

    Args:
        result: The design.
        prov: Its provenance.
        figures: Inline SVG by stem (:func:`figure_svgs`); None or empty: none.
        scene_page: The 3D scene's standalone page (meshcat's ``static_html``); None: none.
        note: A line shown at the top (e.g. why the figures are missing).
    """
    figures = dict(figures or {})
    title = f"pkmtol report — {result.mechanism.name}"
    parts = [
        f"<h1>{html.escape(title)}</h1>",
        f'<p class="meta">pkmtol {html.escape(prov.version)}, commit {html.escape(prov.commit or "none")}; '
        f"{html.escape(prov.command_line or 'Python API')}</p>",
    ]
    if note:
        parts.append(f'<p class="meta">{html.escape(note)}</p>')
    parts += ['<section id="glance"><h2>At a glance</h2>', _glance(result), "</section>"]
    if scene_page is not None:
        parts += [
            '<section id="scene" class="pkmtol-scene"><h2>3D scene</h2>',
            "<p>The mechanism at the design point, an error glyph at every task-space grid point and "
            "the verification samples (legend in the frame; drag to orbit, scroll to zoom, "
            "“Open Controls” to hide layers).</p>",
            f'<iframe class="pkmtol-scene-frame" title="3D scene" style="height:{SCENE_HEIGHT_PX}px" '
            f'srcdoc="{html.escape(scene_page, quote=True)}"></iframe>',
            "</section>",
        ]
    headings = []
    for k, (heading, body) in enumerate(markdown_sections(summary_text(result, markdown=True))):
        if heading.startswith("pkmtol allocation"):
            heading = "Summary"
        headings.append(heading)
        parts += [
            f'<section id="section-{k}" class="pkmtol-tables">',
            f"<h2>{html.escape(heading)}</h2>",
            body,
        ]
        for stem in [s for s, place in FIGURE_PLACES.items() if heading.startswith(place) and s in figures]:
            parts.append(_figure(stem, figures.pop(stem)))
        parts.append("</section>")
    if figures:
        parts += ['<section id="figures"><h2>Figures</h2>', *(_figure(s, svg) for s, svg in figures.items())]
        parts.append("</section>")
    parts += ['<section id="provenance"><h2>Provenance</h2>', _provenance_html(prov), "</section>"]
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>\n"
        + "\n".join(parts)
        + "\n</body></html>\n"
    )
    return page, headings


def _figure(stem: str, svg: str) -> str:
    return (
        f'<figure id="figure-{stem}" class="pkmtol-figure">{svg}'
        f"<figcaption>{html.escape(stem.replace('_', ' '))} (pkmtol figure “{stem}”)</figcaption></figure>"
    )


def render_report(
    result: DesignResult,
    prov: Provenance | None = None,
    scene_options: Any = None,
    scene: bool = True,
    figures: bool = True,
) -> RenderedReport:
    """Render the report in memory: figures (if matplotlib is there), the 3D scene, the page.

    Raises:
        ViewerError: meshcat is missing or its server did not start (with ``scene``).
    """
    prov = prov or provenance(result.mechanism)
    svgs: dict[str, str] = {}
    missing = None
    if figures:
        try:
            svgs = figure_svgs(result)
        except FiguresError as err:
            missing = f"no figures: {err}"
    page_scene, summary = None, None
    if scene:
        from pkmtol.present.viewer.export import render_html

        rendered = render_html(result, Path("scene.html"), scene_options)
        page_scene, summary = rendered.data.decode("utf-8"), rendered.export.scene
    page, headings = report_html(result, prov, svgs, page_scene, missing)
    return RenderedReport(
        data=page.encode("utf-8"),
        sections=tuple(headings),
        figures=tuple(svgs),
        figures_missing=missing,
        scene=summary,
    )


def write_report(
    result: DesignResult, path: Path | str, prov: Provenance | None = None, scene_options: Any = None
) -> RenderedReport:
    """Render the report and write it to ``path`` whole or not at all (:func:`render_report`).

    Raises:
        OutputError: the folder does not exist or the file cannot be written.
        ViewerError: meshcat is missing or its server did not start.
    """
    values.instance("result", result, DesignResult, "a pkmtol.DesignResult (pkmtol.allocate)")
    path = values.path("path", path, "a file path for the HTML report (str or pathlib.Path)")
    values.optional(values.instance, "prov", prov, Provenance, "a Provenance (present.provenance) or None")
    if scene_options is not None:
        from pkmtol.present.viewer.options import SceneOptions

        values.instance("scene_options", scene_options, SceneOptions, "a SceneOptions or None")
    if not (path.parent if str(path.parent) else Path(".")).is_dir():
        raise OutputError(path, f"folder {path.parent} does not exist; create it or choose another --report")
    report = render_report(result, prov, scene_options)
    write_atomic(path, report.data)
    return report
