"""The report's figures (matplotlib, optional extra ``pkmtol[plots]``).

* :func:`sensitivity_figure` — the sensitivities ``ω_i`` of the uncompensatable errors η_c at the
  design point (the paper's Fig. 8), one bar per η_c, lengths and angles told apart;
* :func:`histogram_figure` — the verification's Δλ samples (Gaussian errors at the design-β
  tolerances, linear model; the paper's Fig. 10) with the Δλ* line; the failure fraction (and
  its 95 % interval, the FOSM prediction ``1 − Φ(β)`` and the exact-kinematics subsample's
  fraction when run) in the legend;
* :func:`tolerance_figure` — traditional (all errors, no compensation) vs new tolerances of η_c
  at the design β on a log scale (the paper's Fig. 11);
* :func:`pareto_figure` — the percent contribution of each toleranced error to E[Δλ²] (Pareto:
  largest first, cumulative line) at the design point, its worst share over the task space as
  a marker, and the same for the tilt Δα when it is reported.

:func:`write_figures` writes all four as PNG and SVG. Figures are drawn on matplotlib's Agg
canvas through the object API (``matplotlib.figure.Figure``): pyplot and the global backend are
left alone, so this works headless and inside notebooks alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.design.contributions import NOISE
from pkmtol.design.job import DesignResult
from pkmtol.design.signoff import sign_off
from pkmtol.exceptions import FiguresError, InvalidRequestError, OutputError
from pkmtol.files import write_atomic
from pkmtol.present.plotting import new_figure, render, require_matplotlib

#: Number of bins of the Δλ histogram.
HISTOGRAM_BINS = 40
#: File stem of each figure.
FIGURES = ("sensitivity", "dlambda_histogram", "tolerances", "contributions")
FORMATS = ("png", "svg")

LENGTH_COLOUR = "#3b6fb6"
ANGLE_COLOUR = "#e08a1e"
SAFE_COLOUR = "#2e9e4f"
FAILED_COLOUR = "#d62728"
NOISE_COLOUR = "#8c8c8c"

_SUBSCRIPT = str.maketrans("0123456789ae", "₀₁₂₃₄₅₆₇₈₉ₐₑ")
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def label_name(name: str) -> str:
    """A parameter name as an axis label: a D–H symbol's indices as Unicode subscripts (``δθ₁,₄``).

    Plain text instead of mathtext: the labels of the figures cost a third of their drawing
    time as mathtext. A ``$`` in a name is escaped, so that it is never read as math.

    >>> label_name("δθ_{e,4}"), label_name("limb1.limb1_u1.dx")
    ('δθₑ,₄', 'limb1.limb1_u1.dx')
    """
    name = name.replace("$", r"\$")
    if "_{" not in name or not name.endswith("}"):
        return name
    head, sub = name[:-1].split("_{", 1)
    return head + sub.translate(_SUBSCRIPT)


def decade_label(value: float, _pos: object = None) -> str:
    """A log axis's tick label in plain text: a power of ten as ``10³``, any other value as ``%g``.

    matplotlib's default log labels are mathtext (``$10^{3}$``), whose typesetting is most of the
    cost of drawing a log axis.

    >>> decade_label(1000.0), decade_label(0.01), decade_label(20.0)
    ('10³', '10⁻²', '20')
    """
    if value > 0:
        exponent = round(math.log10(value))
        if math.isclose(value, 10.0**exponent, rel_tol=1e-9):
            return "10" + str(exponent).translate(_SUPERSCRIPT)
    return f"{value:g}"


def _plain_log_axis(axis: Any) -> None:
    """Plain-text labels on a log axis: decades as ``10³``; the others only within one decade."""
    from matplotlib.ticker import FuncFormatter

    def minor(value: float, pos: object) -> str:
        low, high = sorted(axis.get_view_interval())
        return "" if low <= 0 or high / low >= 10.0 else decade_label(value, pos)

    axis.set_major_formatter(FuncFormatter(decade_label))
    axis.set_minor_formatter(FuncFormatter(minor))


def _unit_colour(unit: str) -> str:
    return LENGTH_COLOUR if unit == "m" else ANGLE_COLOUR


def sensitivity_figure(result: DesignResult) -> Any:
    """Bars of the sensitivities ``ω_i = ‖J[:, i]‖`` of η_c at the design point (Fig. 8)."""
    require_matplotlib()
    from matplotlib.patches import Patch

    unc = np.asarray(result.uncompensatable, dtype=int)
    params = [result.pset.parameters[i] for i in unc]
    values = np.asarray(result.sensitivity, dtype=float)[unc]
    fig = new_figure((max(6.0, 0.45 * len(unc) + 2.0), 4.0))
    ax = fig.add_subplot()
    x = np.arange(len(unc))
    colours = [_unit_colour(p.unit) for p in params]
    ax.bar(x, values, color=colours, edgecolor="black", linewidth=0.5)
    ax.set_xticks(x, [label_name(p.name) for p in params], rotation=60, ha="right")
    ax.set_xlim(-0.7, len(unc) - 0.3)
    ax.set_ylabel("sensitivity ω_i  [µm/µm or µm/µrad]")
    p = np.round(result.worst_point_m * 1e3) + 0.0  # no "-0"
    ax.set_title(
        f"{result.mechanism.name}: sensitivities of the {len(unc)} uncompensatable errors\n"
        f"at the design point P = ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm",
        fontsize=10,
    )
    ax.legend(
        handles=[
            Patch(facecolor=LENGTH_COLOUR, edgecolor="black", label="length error (µm/µm)"),
            Patch(facecolor=ANGLE_COLOUR, edgecolor="black", label="angle error (µm/µrad)"),
        ],
        fontsize=8,
    )
    ax.grid(axis="y", alpha=0.3)
    return fig


def histogram_figure(result: DesignResult, distribution: str = "gaussian", bins: int = HISTOGRAM_BINS) -> Any:
    """Histogram of the verification's Δλ with the Δλ* line and the failure fraction (Fig. 10)."""
    require_matplotlib()
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    if distribution not in result.verification:
        raise InvalidRequestError(
            f"no verification with distribution {distribution!r} (have: {', '.join(result.verification)})"
        )
    if bins < 1:
        raise InvalidRequestError(f"bins must be ≥ 1, got {bins}")
    ver = result.verification[distribution]
    dl = np.asarray(ver.dlam_linear_m, dtype=float) * 1e6
    target = result.target_m * 1e6
    hi = max(float(dl.max()), target) * 1.02
    edges = np.linspace(0.0, hi, bins + 1)
    counts, _ = np.histogram(dl, edges)
    centres = (edges[:-1] + edges[1:]) / 2
    fig = new_figure((7.0, 4.2))
    ax = fig.add_subplot()
    colours = [FAILED_COLOUR if c > target else SAFE_COLOUR for c in centres]
    ax.bar(centres, counts, width=np.diff(edges), color=colours, edgecolor="black", linewidth=0.3)
    ax.axvline(target, color="black", linestyle="--", linewidth=1.5)
    st = ver.linear
    n_safe = st.samples - round(st.failure_fraction * st.samples)
    lo, up = st.failure_ci95
    handles = [
        Line2D([], [], color="black", linestyle="--", label=f"Δλ* = {target:g} µm"),
        Patch(color=SAFE_COLOUR, label=f"safe: {n_safe} of {st.samples}"),
        Patch(
            color=FAILED_COLOUR,
            label=f"failed (Δλ > Δλ*): {100 * st.failure_fraction:.2f} % "
            f"[{100 * lo:.2f}, {100 * up:.2f}] of {st.samples}",
        ),
        Line2D(
            [],
            [],
            color="none",
            label=f"FOSM prediction 1 − Φ(β={result.design_beta:g}): "
            f"{100 * (1 - float(_phi(result.design_beta))):.2f} %",
        ),
    ]
    if ver.exact is not None:
        handles.append(
            Line2D(
                [],
                [],
                color="none",
                label=f"exact kinematics, {ver.exact.samples} samples: "
                f"{100 * ver.exact.failure_fraction:.2f} % failed",
            )
        )
    ax.legend(handles=handles, fontsize=8, loc="upper right")
    ax.set_xlabel("Δλ  [µm]  (linear model, random task-space poses)")
    ax.set_ylabel("samples")
    ax.set_xlim(0.0, hi)
    ax.set_title(
        f"{result.mechanism.name}: verification, {distribution.replace('_', ' ')} errors at the "
        f"β = {result.design_beta:g} tolerances",
        fontsize=10,
    )
    ax.grid(axis="y", alpha=0.3)
    return fig


def _phi(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def tolerance_figure(result: DesignResult) -> Any:
    """Traditional vs new tolerances of η_c at the design β, log scale (Fig. 11)."""
    unc = np.asarray(result.uncompensatable, dtype=int)
    params = [result.pset.parameters[i] for i in unc]
    new = np.asarray(result.tolerances[unc, result.design_column], dtype=float) * 1e6
    trad_of = dict(
        zip(result.traditional.columns.tolist(), result.traditional.tolerance.tolist(), strict=True)
    )
    trad = np.array([trad_of.get(int(i), math.nan) for i in unc], dtype=float) * 1e6
    fig = new_figure((max(6.5, 0.5 * len(unc) + 2.5), 4.4))
    ax = fig.add_subplot()
    x = np.arange(len(unc))
    w = 0.4
    finite = np.concatenate([v[np.isfinite(v)] for v in (new, trad)])
    top = float(finite.max()) * 3 if finite.size else 1.0
    ax.bar(
        x - w / 2,
        np.where(np.isfinite(trad), trad, np.nan),
        w,
        color="#9a9a9a",
        edgecolor="black",
        linewidth=0.5,
        label="traditional (all errors, no compensation)",
    )
    ax.bar(
        x + w / 2,
        np.where(np.isfinite(new), new, np.nan),
        w,
        color=LENGTH_COLOUR,
        edgecolor="black",
        linewidth=0.5,
        label="new (η_c only, compensation applied)",
    )
    for k, (a, b) in enumerate(zip(trad, new, strict=True)):
        for value, dx in ((a, -w / 2), (b, w / 2)):
            if not np.isfinite(value):
                ax.text(k + dx, top / 3, "∞", ha="center", va="bottom", fontsize=9)
    ax.set_yscale("log")
    _plain_log_axis(ax.yaxis)
    ax.set_ylim(top=top)
    ax.set_xticks(
        x,
        [label_name(p.name) + (" (µrad)" if p.unit == "rad" else "") for p in params],
        rotation=60,
        ha="right",
    )
    ax.set_xlim(-0.7, len(unc) - 0.3)
    ax.set_ylabel("tolerance σ_i  [µm or µrad]")
    n_comp = sum(1 for c in result.classes if c == "compensatable")
    with np.errstate(invalid="ignore", divide="ignore"):  # free (inf) tolerances give no ratio
        ratio = new / trad
    ok = np.isfinite(ratio)
    gain = f"; new/traditional: median ×{np.median(ratio[ok]):.2f}" if ok.any() else ""
    ax.set_title(
        f"{result.mechanism.name}: tolerances at β = {result.design_beta:g}, "
        f"Δλ* = {result.target_m * 1e3:g} mm{gain}\n"
        f"({n_comp} compensatable errors need no tolerance in the new method)",
        fontsize=10,
    )
    ax.legend(fontsize=8)
    ax.grid(axis="y", which="both", alpha=0.3)
    return fig


def pareto_figure(result: DesignResult) -> Any:
    """Percent contributions to E[Δλ²] (and E[Δα²]) of the verified design: bars, worst share, cumulative."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    so = sign_off(result)
    panels = [("Δλ", so.contributions, so.design_index)]
    if so.tilt_contributions is not None:
        panels.append(("Δα (tilt of the tool axis)", so.tilt_contributions, so.tilt_design_index))
    n = max(len(so.columns), 1) + 1
    fig = new_figure((max(6.5, 0.42 * n + 2.5), 3.9 * len(panels)))
    for ax, (what, c, pose) in zip(np.atleast_1d(fig.subplots(len(panels), 1)), panels, strict=True):
        order = list(c.order())
        labels, share, worst, colours = [], [], [], []
        for k in order:
            p = result.pset.parameters[c.columns[k]]
            labels.append(label_name(p.name))
            share.append(100 * c.at_design[k])
            worst.append(100 * c.worst[k])
            colours.append(_unit_colour(p.unit))
        if c.noise_share.any():
            at = int(np.searchsorted(-np.asarray(share), -100 * c.noise_at_design))
            labels.insert(at, NOISE)
            share.insert(at, 100 * c.noise_at_design)
            worst.insert(at, 100 * float(c.noise_share.max()))
            colours.insert(at, NOISE_COLOUR)
        x = np.arange(len(labels))
        ax.bar(x, share, color=colours, edgecolor="black", linewidth=0.5)
        ax.plot(x, worst, "D", color="black", markersize=4, linestyle="none")
        ax.set_xticks(x, labels, rotation=60, ha="right")
        ax.set_xlim(-0.7, len(labels) - 0.3)
        ax.set_ylabel("share of E[" + what.split()[0] + "²]  [%]")
        ax.grid(axis="y", alpha=0.3)
        cum = ax.twinx()
        cum.plot(x, np.cumsum(share), color="#555555", linewidth=1.2, marker=".")
        cum.set_ylim(0, 140)  # the legend sits above 100 %
        cum.set_ylabel("cumulative at the design point [%]")
        ax.set_title(
            f"{result.mechanism.name}: contributions to E[{what.split()[0]}²] of the {len(order)} "
            f"toleranced errors{'' if what == 'Δλ' else ' — ' + what}\nbars: at grid pose {pose}; "
            "◆: each error's largest share over the task space",
            fontsize=10,
        )
        handles = [
            Patch(facecolor=LENGTH_COLOUR, edgecolor="black", label="length error"),
            Patch(facecolor=ANGLE_COLOUR, edgecolor="black", label="angle error"),
            Line2D([], [], marker="D", color="black", linestyle="none", markersize=4, label="worst share"),
            Line2D([], [], color="#555555", marker=".", label="cumulative"),
        ]
        if c.noise_share.any():
            handles.insert(2, Patch(facecolor=NOISE_COLOUR, edgecolor="black", label=NOISE))
        ax.legend(handles=handles, fontsize=8, loc="upper center", ncol=len(handles))
        ax.set_ylim(0, max(max(worst, default=0.0), max(share, default=0.0)) * 1.4 + 1e-9)
    return fig


def make_figures(result: DesignResult) -> dict[str, Any]:
    """Draw the four figures, by file stem (see :data:`FIGURES`)."""
    return {
        "sensitivity": sensitivity_figure(result),
        "dlambda_histogram": histogram_figure(result),
        "tolerances": tolerance_figure(result),
        "contributions": pareto_figure(result),
    }


def render_figures(
    result: DesignResult, formats: Sequence[str] = FORMATS, dpi: int = 150
) -> dict[str, bytes]:
    """The three figures rendered in memory: ``{"<stem>.<format>": bytes}``, nothing written.

    Raises:
        FiguresError: matplotlib is missing, or a figure cannot be drawn.
        InvalidRequestError: an unknown format.
    """
    bad = [f for f in formats if f not in ("png", "svg", "pdf")]
    if bad or not formats or isinstance(formats, str):
        raise InvalidRequestError(f"figure formats must be png, svg or pdf, got {list(formats)}")
    require_matplotlib()
    rendered: dict[str, bytes] = {}
    try:
        for stem, fig in make_figures(result).items():
            for fmt in formats:
                rendered[f"{stem}.{fmt}"] = render(fig, fmt, dpi)
    except (ValueError, RuntimeError) as err:  # e.g. a label matplotlib cannot typeset
        raise FiguresError(f"matplotlib cannot draw the figures: {err}") from err
    return rendered


def write_figures(
    result: DesignResult,
    out_dir: Path | str,
    formats: Sequence[str] = FORMATS,
    dpi: int = 150,
) -> list[Path]:
    """Write the four figures into ``out_dir`` (created if missing) as ``<stem>.<format>``.

    Every figure is rendered before any file is written; each file is written through a
    temporary file renamed over it.

    Returns:
        The files written: ``sensitivity``, ``dlambda_histogram``, ``tolerances``,
        ``contributions`` in that order, each in every format.

    Raises:
        FiguresError: matplotlib is missing.
        InvalidRequestError: an unknown format.
        OutputError: the folder or a file cannot be written.

    """
    rendered = render_figures(result, formats, dpi)
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(out, err.strerror or str(err)) from err
    for name, data in rendered.items():
        write_atomic(out / name, data)
    return [out / name for name in rendered]
