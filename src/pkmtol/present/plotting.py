"""matplotlib, imported only when a figure is drawn: a figure without pyplot, and its bytes."""

from __future__ import annotations

import io
from typing import Any

from pkmtol.exceptions import FiguresError


def require_matplotlib() -> tuple[Any, Any]:
    """``(Figure, FigureCanvasAgg)`` or :class:`FiguresError` with what to do.

    Every matplotlib module the figures use is imported here, so that a missing (or broken)
    matplotlib fails before anything is drawn.
    """
    try:
        import matplotlib.lines  # noqa: F401 - used by the figures
        import matplotlib.patches  # noqa: F401
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as err:
        raise FiguresError(
            f"the figures need matplotlib, which is not installed ({err}); install it with "
            "`pip install 'pkmtol[plots]'` (or `pip install matplotlib`), or pass --no-figures"
        ) from err
    return Figure, FigureCanvasAgg


def new_figure(size: tuple[float, float]) -> Any:
    """A matplotlib ``Figure`` of ``size`` inches with an Agg canvas (no pyplot, no global state)."""
    figure_cls, canvas_cls = require_matplotlib()
    fig = figure_cls(figsize=size, layout="constrained")
    canvas_cls(fig)
    return fig


def render(fig: Any, fmt: str, dpi: int) -> bytes:
    """The figure as ``fmt`` (png, svg, pdf) bytes, without dates or software stamps (reproducible).

    SVG keeps its text as text (``svg.fonttype: none``: smaller, searchable, and no glyph-to-path
    conversion); PNG is written with zlib level 1 (the same pixels, faster). After the first
    rendering the figure's layout engine is removed, not only frozen: with any engine set (even
    the placeholder ``"none"`` leaves), matplotlib draws the whole figure once more, without
    output, before each further format. The axes keep the positions the constrained layout gave
    them.
    """
    from matplotlib import rc_context

    buf = io.BytesIO()
    with rc_context({"svg.fonttype": "none", "svg.hashsalt": "pkmtol"}):
        fig.savefig(
            buf,
            format=fmt,
            dpi=dpi,
            metadata={"Software": None} if fmt == "png" else {"Date": None, "Creator": None},
            **({"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}),
        )
    with rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)  # None under these settings: no engine at all
    return buf.getvalue()
