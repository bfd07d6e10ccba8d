"""A run's files: the tables (and the figures) rendered in memory, then written through a RunFolder.

:func:`render_tables` renders ``allocation.json``, ``.csv`` and ``.md`` (:mod:`pkmtol.present.tables`)
without writing; :func:`write_outputs` writes a whole run into a folder, all or nothing
(:class:`~pkmtol.present.run_folder.RunFolder`), as ``pkmtol allocate --out`` does.
"""

from __future__ import annotations

from pathlib import Path

import pkmtol.values as values
from pkmtol.design.job import DesignResult
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.present.run_folder import RunFolder
from pkmtol.present.tables import summary_text, to_csv, to_json
from pkmtol.units import DISPLAY_UNITS


def render_tables(r: DesignResult, units: str = "mm") -> dict[str, bytes]:
    """``allocation.json``, ``.csv`` and ``.md`` rendered in memory (nothing written)."""
    if not isinstance(r, DesignResult):
        raise InvalidArgumentError("result", r, "expected a pkmtol.DesignResult (from pkmtol.allocate)")
    values.choice("units", units, DISPLAY_UNITS)
    return {
        "allocation.json": to_json(r).encode(),
        "allocation.csv": to_csv(r, units).encode(),
        "allocation.md": summary_text(r, markdown=True, units=units).encode(),
    }


def write_outputs(
    r: DesignResult,
    out_dir: Path | str,
    extra: dict[str, bytes] | None = None,
    figures: bool = False,
    units: str = "mm",
) -> list[Path]:
    """Write a run into ``out_dir``: allocation.json/.csv/.md, the figures if asked, ``extra`` files.

    With ``figures=True`` the folder holds what ``pkmtol allocate --out`` writes (the figures need
    matplotlib). Everything is rendered in memory first and written all or nothing through a
    :class:`~pkmtol.present.run_folder.RunFolder`: the folder is locked against a second writer,
    the previous run's files that this run does not write are removed, and ``pkmtol-run.json``
    lists the files.

    Raises:
        OutputError: the folder cannot be created or written (nothing has changed then);
            :class:`~pkmtol.exceptions.OutputLockedError` if another run is writing into it.
        FiguresError: ``figures=True`` and matplotlib is missing (nothing is written).
    """
    values.flag("figures", figures)
    out_dir = values.path("out_dir", out_dir, "a folder path (str or pathlib.Path)")
    if extra is not None:
        values.instance("extra", extra, dict, "a dict of file names to bytes, or None")
        for name, data in extra.items():
            values.text("extra", name)
            values.instance(f"extra[{name!r}]", data, bytes, "bytes (the file's contents)")
    contents = render_tables(r, units)
    if figures:
        from pkmtol.present.figures import render_figures

        contents.update(render_figures(r))
    contents.update(extra or {})
    with RunFolder(out_dir) as run:
        return run.write(contents)
