"""The report's figures: bars, bins, lines, files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from pkmtol.design.job import DesignOptions, allocate  # noqa: E402
from pkmtol.exceptions import FiguresError  # noqa: E402
from pkmtol.model.loader import load_mechanism  # noqa: E402
from pkmtol.present.figures import (  # noqa: E402
    FIGURES,
    HISTOGRAM_BINS,
    histogram_figure,
    label_name,
    render_figures,
    sensitivity_figure,
    tolerance_figure,
    write_figures,
)

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


@pytest.fixture(scope="module")
def result():
    return allocate(
        load_mechanism(ROBOT), DesignOptions(samples=2000, exact_samples=20, verification_poses=200)
    )


def _bars(ax):
    from matplotlib.container import BarContainer

    return [c for c in ax.containers if isinstance(c, BarContainer)]


def test_sensitivity_bars_one_per_uncompensatable_error(result):
    fig = sensitivity_figure(result)
    ax = fig.axes[0]
    (bars,) = _bars(ax)
    n = len(result.uncompensatable)
    assert n == 14  # the paper's Table IV
    assert len(bars) == n
    heights = np.array([b.get_height() for b in bars])
    np.testing.assert_allclose(heights, result.sensitivity[result.uncompensatable])
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert labels == [label_name(result.pset.names[i]) for i in result.uncompensatable]


def test_histogram_bins_line_and_failure_fraction(result):
    fig = histogram_figure(result)
    ax = fig.axes[0]
    (bars,) = _bars(ax)
    assert len(bars) == HISTOGRAM_BINS
    ver = result.verification["gaussian"]
    heights = np.array([b.get_height() for b in bars])
    assert heights.sum() == ver.dlam_linear_m.size  # every sample is in a bin
    # the bins past Δλ* hold the failed samples (up to the bin that straddles Δλ*)
    target_um = result.target_m * 1e6
    centres = np.array([b.get_x() + b.get_width() / 2 for b in bars])
    failed_bins = heights[centres > target_um].sum()
    failed = int(np.sum(ver.dlam_linear_m > result.target_m))
    assert abs(failed_bins - failed) <= heights[np.argmin(np.abs(centres - target_um))]
    (line,) = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert np.allclose(line.get_xdata(), target_um)
    legend = " ".join(t.get_text() for t in ax.get_legend().get_texts())
    assert f"{100 * ver.linear.failure_fraction:.2f} %" in legend
    assert "Δλ* = 50 µm" in legend


def test_histogram_bins_option_and_bad_distribution(result):
    from pkmtol.exceptions import InvalidRequestError

    ax = histogram_figure(result, "uniform_sigma", bins=7).axes[0]
    assert len(_bars(ax)[0]) == 7
    with pytest.raises(InvalidRequestError):
        histogram_figure(result, "cauchy")


def test_tolerances_traditional_vs_new_on_log_scale(result):
    ax = tolerance_figure(result).axes[0]
    assert ax.get_yscale() == "log"
    trad, new = _bars(ax)
    n = len(result.uncompensatable)
    assert len(trad) == len(new) == n
    np.testing.assert_allclose(
        [b.get_height() for b in new],
        result.tolerances[result.uncompensatable, result.design_column] * 1e6,
    )
    # compensation relaxes every tolerance
    assert all(b.get_height() > a.get_height() for a, b in zip(trad, new, strict=True))


def test_write_figures_png_and_svg(result, tmp_path):
    out = tmp_path / "out"
    files = write_figures(result, out)
    assert [f.name for f in files] == [f"{s}.{e}" for s in FIGURES for e in ("png", "svg")]
    for f in files:
        data = f.read_bytes()
        if f.suffix == ".png":
            assert data.startswith(b"\x89PNG\r\n\x1a\n")
            from PIL import Image

            img = np.asarray(Image.open(f).convert("L"), dtype=float)
            assert img.std() > 10  # not blank
        else:
            assert b"<svg" in data[:2000]
    assert sorted(p.name for p in out.iterdir()) == sorted(f.name for f in files)  # no temp files


def test_missing_matplotlib_is_actionable(monkeypatch, result):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(FiguresError, match=r"pkmtol\[plots\]"):
        sensitivity_figure(result)


def test_labels_are_plain_text():
    assert label_name("δθ_{1,4}") == "δθ₁,₄"
    assert label_name("δd_{a,4}") == "δdₐ,₄"
    assert label_name("limb1.limb1_u1.dx") == "limb1.limb1_u1.dx"
    assert label_name("a$b$_{1,2}") == r"a\$b\$₁,₂"  # a $ is never read as math


def test_figures_typeset_no_mathtext(monkeypatch, result):
    """Every label, the log axis's included, is plain text: mathtext is most of a label's cost."""
    from matplotlib.mathtext import MathTextParser

    def refuse(self, s, *args, **kwargs):
        raise AssertionError(f"mathtext typeset: {s!r}")

    monkeypatch.setattr(MathTextParser, "parse", refuse)
    rendered = render_figures(result)
    assert len(rendered) == 2 * len(FIGURES)
    ticks = [t.get_text() for t in tolerance_figure(result).axes[0].get_yticklabels()]
    assert any(t.startswith("10") for t in ticks)


def test_each_figure_is_laid_out_once_and_reproducible(monkeypatch, result):
    """The second format reuses the first one's layout (one draw, no second layout pass)."""
    from matplotlib.figure import Figure

    draws = []
    original = Figure.draw
    monkeypatch.setattr(Figure, "draw", lambda fig, renderer: (draws.append(fig), original(fig, renderer))[1])
    first = render_figures(result)
    # per figure: the layout pass and the drawing of the first format, one drawing of the second
    assert len(draws) == 3 * len(FIGURES)
    assert render_figures(result) == first  # byte for byte, SVG ids included
