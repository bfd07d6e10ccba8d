"""Entry points of the 3D viewer: a self-contained HTML page, or the scene served live on 127.0.0.1."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pkmtol.design.job import DesignResult
from pkmtol.exceptions import OutputError
from pkmtol.files import write_atomic
from pkmtol.present.viewer.legend import legend_overlay
from pkmtol.present.viewer.options import ROOT, SceneOptions
from pkmtol.present.viewer.scene import SceneSummary, build_scene
from pkmtol.present.viewer.server import MeshcatServer


@dataclass(frozen=True)
class HtmlExport:
    """What :func:`export_html` wrote.

    Attributes:
        path: The HTML file written.
        bytes: Its size [bytes] (UTF-8).
        server_pid: Process id of the meshcat server that built the page (stopped and reaped
            before :func:`export_html` returned).
        scene: What was drawn (the :func:`build_scene` summary).

    """

    path: Path
    bytes: int
    server_pid: int
    scene: SceneSummary


def export_html(result: DesignResult, path: Path | str, options: SceneOptions | None = None) -> HtmlExport:
    """Write the scene as one self-contained HTML page (meshcat's ``static_html``), atomically.

    Starts a loopback-only meshcat server, builds the scene, takes the page, stops the server
    (reaped before returning, also on error) and writes ``path`` through a temporary file in the
    same folder renamed over it (nothing is written if anything fails). The legend is overlaid on
    the page (the 3D legend panel is hidden; it can be shown from the viewer's controls).

    Returns:
        The file written, its size, the stopped server's process id and the :func:`build_scene`
        summary (:class:`HtmlExport`).

    Raises:
        ViewerError: meshcat is missing or its server did not start.
        OutputError: the file cannot be written.

    """
    path = Path(path)
    if path.parent and not path.parent.is_dir():
        raise OutputError(path, f"folder {path.parent} does not exist")
    export = render_html(result, path, options)
    write_atomic(path, export.data)
    return export.export


@dataclass(frozen=True)
class RenderedPage:
    """A 3D page rendered in memory (:func:`render_html`), not yet written.

    Attributes:
        data: The page (UTF-8).
        export: What writing it to its path gives (:class:`HtmlExport`).
    """

    data: bytes
    export: HtmlExport


def render_html(result: DesignResult, path: Path | str, options: SceneOptions | None = None) -> RenderedPage:
    """The page :func:`export_html` writes to ``path``, rendered in memory only (nothing written).

    Raises:
        ViewerError: meshcat is missing or its server did not start.
    """
    with MeshcatServer() as server:
        vis = server.visualizer
        summary = build_scene(result, vis, options)
        if "legend" in summary.layers:
            # the page has the legend overlaid; the 3D panel stays available in the controls
            vis[f"{ROOT}/legend"].set_property("visible", False)
        page = vis.static_html()
        server_pid = server.pid
    overlay = legend_overlay(list(summary.legend), summary.spheres is not None)
    page = page.replace("</body>", overlay + "\n</body>", 1)
    data = page.encode("utf-8")
    return RenderedPage(
        data, HtmlExport(path=Path(path), bytes=len(data), server_pid=server_pid, scene=summary)
    )


def show(
    result: DesignResult,
    options: SceneOptions | None = None,
    *,
    open_browser: bool = False,
    block: bool = True,
    out: Callable[[str], None] = print,
) -> MeshcatServer | None:
    """Serve the scene live on 127.0.0.1 (``pkmtol show``, ``allocate --view``).

    Prints the viewer's URL and the legend through ``out``. With ``block`` (default) it waits
    until Ctrl-C (or SIGTERM), stops the server and returns None; otherwise it returns the running
    :class:`MeshcatServer`, which the caller must close.
    """
    server = MeshcatServer()
    try:
        summary = build_scene(result, server.visualizer, options)
        out(f"meshcat viewer: {server.web_url}")
        for line in summary.legend:
            out(line)
        if open_browser:
            import webbrowser

            webbrowser.open(server.web_url, new=2)
        if not block:
            return server
        out("press Ctrl-C to stop the viewer")
        import signal

        def _stop(signum: int, frame: Any) -> None:
            raise KeyboardInterrupt

        previous = signal.signal(signal.SIGTERM, _stop)
        try:
            while server.proc.poll() is None:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)
    except BaseException:
        server.close()
        raise
    server.close()
    return None
