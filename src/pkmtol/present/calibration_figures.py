"""Figures of a calibration: Δλ histograms before and after, and the p99 against the number of poses."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.calibration.study import StudyResult
from pkmtol.calibration.workflow import PlanReport
from pkmtol.present.plotting import new_figure, render

BEFORE_COLOUR = "#7f7f7f"
IDEAL_COLOUR = "#e08a1e"
AFTER_COLOURS = ("#3b6fb6", "#2e9e4f", "#9467bd", "#8c564b")
TARGET_COLOUR = "#d62728"


def histogram_figure(study: StudyResult, bins: int = 60) -> Any:
    """Δλ of the held-out poses: before calibration, Eq. 25 (ideal), and after each D-optimal case."""
    fig = new_figure((7.5, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    rows = [(study.ideal, IDEAL_COLOUR)]
    rows += [
        (c.exact, AFTER_COLOURS[k % len(AFTER_COLOURS)])
        for k, c in enumerate(c for c in study.cases if c.case.selection == "d-optimal")
    ]
    finite = np.concatenate([r.dlambda_m[np.isfinite(r.dlambda_m)] for r, _ in rows])
    top = max(float(np.quantile(finite, 0.999)), 1.2 * study.target_m) * 1e6
    edges = np.linspace(0.0, top, bins + 1)
    for summary, colour in rows:
        v = 1e6 * summary.dlambda_m[np.isfinite(summary.dlambda_m)]
        ax.hist(v, bins=edges, histtype="step", lw=1.6, color=colour, density=True, label=summary.label)
    ax.axvline(1e6 * study.target_m, color=TARGET_COLOUR, ls="--", lw=1.2, label="Δλ*")
    before = 1e6 * np.nanmedian(study.before.dlambda_m)
    ax.set_xlabel("Δλ at held-out poses [µm]")
    ax.set_ylabel("density [1/µm]")
    ax.set_title(
        f"{study.machines} machines × {len(study.holdout_points_m)} poses "
        f"(before calibration: median {before:.0f} µm, off the scale)",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper right")
    ax.set_xlim(0.0, top)
    return fig


def pose_count_figure(report: PlanReport, study: StudyResult | None = None) -> Any:
    """Predicted p99 of Δλ against the number of calibration poses, D-optimal and random."""
    fig = new_figure((6.5, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    n = np.array([c[0] for c in report.curve])
    ax.plot(
        n, [1e6 * c[1] for c in report.curve], "o-", color=AFTER_COLOURS[0], label="D-optimal (linear model)"
    )
    ax.plot(
        n,
        [1e6 * c[2] for c in report.curve],
        "s--",
        color=BEFORE_COLOUR,
        label="random, median of 3 (linear)",
    )
    if study is not None:
        for c in study.cases:
            if c.case.controller == report.plan.settings.controller:
                marker = "*" if c.case.selection == "d-optimal" else "x"
                ax.plot(
                    [c.case.poses],
                    [1e6 * c.exact.quantile_m(0.99)],
                    marker,
                    ms=11,
                    color=TARGET_COLOUR,
                    label=f"exact study, {c.case.selection}",
                )
    ax.axhline(1e6 * report.target_m, color=TARGET_COLOUR, ls=":", lw=1.0, label="Δλ*")
    ax.set_xlabel("calibration poses N")
    ax.set_ylabel("p99 of Δλ after calibration [µm]")
    ax.set_yscale("log")
    ax.set_title(f"controller '{report.plan.settings.controller_label}'", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    return fig


def render_figures(
    figures: dict[str, Any], out_dir: Path, formats: tuple[str, ...] = ("png", "svg")
) -> list[tuple[Path, bytes]]:
    """Every figure rendered in every format, as ``(path, bytes)`` (nothing is written here)."""
    return [
        (out_dir / f"{stem}.{fmt}", render(fig, fmt, 150)) for stem, fig in figures.items() for fmt in formats
    ]
