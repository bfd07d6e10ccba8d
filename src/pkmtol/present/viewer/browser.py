"""Headless Chromium: screenshots of exported pages (software WebGL)."""

from __future__ import annotations

import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from pkmtol.exceptions import ViewerError
from pkmtol.files import write_atomic

#: Chromium binaries looked for, in order.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome binary on PATH, or None."""
    import shutil

    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


def chromium_command(
    chromium: str,
    html: Path,
    png: Path,
    profile: Path,
    size: tuple[int, int] = (1200, 900),
    budget_ms: int = 10_000,
    fragment: str = "",
    extra: Sequence[str] = (),
) -> list[str]:
    """Build the headless Chromium command that renders ``html`` (software WebGL) to ``png``.

    ``fragment`` (e.g. ``"scene"``) scrolls the page to that anchor first; ``extra`` flags go before
    the page's URL (e.g. ``--log-net-log=FILE``).
    """
    return [
        chromium,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={profile}",
        f"--window-size={size[0]},{size[1]}",
        f"--virtual-time-budget={budget_ms}",
        f"--screenshot={png}",
        *extra,
        Path(html).resolve().as_uri() + (f"#{fragment}" if fragment else ""),
    ]


def screenshot(
    html: Path | str,
    png: Path | str,
    size: tuple[int, int] = (1200, 900),
    timeout_s: float = 120,
    fragment: str = "",
    extra: Sequence[str] = (),
) -> Path:
    """Render an exported page in headless Chromium (software WebGL) and save a PNG.

    ``fragment`` scrolls to an anchor of the page first; ``extra`` adds Chromium flags.

    Raises:
        ViewerError: no Chromium found, or it failed or produced no image.

    """
    chromium = find_chromium()
    if chromium is None:
        raise ViewerError(
            "no Chromium found for the screenshot; install it (Debian: `apt-get install chromium`)"
        )
    png = Path(png)
    with tempfile.TemporaryDirectory(prefix="pkmtol-chromium-") as tmp:
        shot = Path(tmp) / "shot.png"
        cmd = chromium_command(
            chromium, Path(html), shot, Path(tmp) / "profile", size, fragment=fragment, extra=extra
        )
        try:
            done = subprocess.run(
                cmd, stdin=subprocess.DEVNULL, capture_output=True, timeout=timeout_s, check=False
            )
        except subprocess.TimeoutExpired as err:
            raise ViewerError(f"Chromium did not finish within {timeout_s:g} s") from err
        if not shot.is_file():
            tail = done.stderr.decode("utf-8", "replace")[-800:]
            raise ViewerError(f"Chromium made no screenshot (exit {done.returncode}): {tail}")
        write_atomic(png, shot.read_bytes())
    return png
