"""Measurement files of the instruments other than a registered tracker (CSV, a unit in every header).

Every number carries its unit in its column header, ``name [unit]``; actuator columns are named
``<limb>.<joint>`` (the actuated joints) in mm/m/µm (prismatic) or deg/rad/mrad (revolute), as in
the tracker's file (:mod:`pkmtol.calibration.measurement_files`, whose rules these follow):

* ``tracker-6d``, one row per pose: ``pose,<joints>…,x [mm],y [mm],z [mm],rx [mrad],ry [mrad],rz [mrad]``
  (P in the tracker frame, the orientation as a rotation vector);
* ``ballbar``, one row per reading: ``pose,<joints>…,station,d [mm]`` (``station``: the circle's
  index in ``[calibration]``'s circles, :attr:`Ballbar.centres_m` order);
* ``probe``, one row per touch: ``pose,<joints>…,station`` (the readings at the trigger;
  ``station``: the sphere's index).

A tracker with an identified frame reads the tracker's own file; its coordinates are then in the
tracker frame. Rows are read in one pass (a dictionary of the commands seen per station), so a
file of 10⁶ rows is read in linear time.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pkmtol.calibration.instruments.base import Instrument
from pkmtol.calibration.measurement_files import ANGLE, LENGTH, actuator_columns, csv_rows, read_measurements
from pkmtol.exceptions import MeasurementFileError
from pkmtol.model.mechanism import Mechanism

_HEADER = re.compile(r"^\s*([^\[\]]+?)\s*\[\s*([^\]]*)\s*\]\s*$")
#: Commands are the same pose when they agree to this many decimals (SI: 1e-9 m or rad).
SAME_DECIMALS = 9


@dataclass(frozen=True, eq=False)
class InstrumentMeasurements:
    """An instrument's data read from a file (SI units).

    Attributes:
        commands: Shape (N, f): actuator readings of each pose [m or rad].
        values: Shape (N, r): the measured values [m or rad] (the probe: the artifact's radius).
        stations: Shape (N,): the station of each pose.
        labels: The ``pose`` label of each pose.
        lines: Shape (N,): the file line of each pose.
    """

    commands: np.ndarray
    values: np.ndarray
    stations: np.ndarray
    labels: tuple[str, ...]
    lines: np.ndarray


def _columns(instrument: Instrument) -> tuple[list[tuple[str, str]], bool]:
    """The instrument's value columns ``(name, kind: L or A)`` and whether it has a station column."""
    if instrument.name == "tracker-6d":
        return [("x", "L"), ("y", "L"), ("z", "L"), ("rx", "A"), ("ry", "A"), ("rz", "A")], False
    if instrument.name == "ballbar":
        return [("d", "L")], True
    return [], True


def instrument_csv(
    mechanism: Mechanism,
    instrument: Instrument,
    commands: np.ndarray,
    values: np.ndarray,
    stations: np.ndarray,
    labels: list[str] | None = None,
) -> str:
    """An instrument's data as CSV text (see the module docstring): mm, deg and mrad, full precision."""
    acts = actuator_columns(mechanism)
    cols, has_station = _columns(instrument)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["pose"]
        + [f"{c} [{'mm' if k == 'P' else 'deg'}]" for c, k in acts]
        + (["station"] if has_station else [])
        + [f"{c} [{'mm' if k == 'L' else 'mrad'}]" for c, k in cols]
    )
    for i, u in enumerate(np.asarray(commands, dtype=float)):
        row = [labels[i] if labels else str(i)]
        row += [_fmt(v * (1e3 if k == "P" else 180.0 / math.pi)) for v, (_, k) in zip(u, acts, strict=True)]
        if has_station:
            row.append(str(int(stations[i])))
        row += [_fmt(1e3 * v) for v in np.asarray(values[i], dtype=float)[: len(cols)]]
        w.writerow(row)
    return buf.getvalue()


def instrument_plan_csv(
    mechanism: Mechanism, commands: np.ndarray, points_m: np.ndarray, stations: np.ndarray
) -> str:
    """A ballbar's or a probe's plan as CSV: the station (circle, sphere), the commands, the nominal P."""
    acts = actuator_columns(mechanism)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["pose", "station"]
        + [f"{c} [{'mm' if k == 'P' else 'deg'}]" for c, k in acts]
        + [f"P_{a} [mm]" for a in "xyz"]
    )
    for i, (u, p) in enumerate(zip(commands, points_m, strict=True)):
        vals = [
            f"{v * (1e3 if k == 'P' else 180.0 / math.pi) + 0.0:.6f}"
            for v, (_, k) in zip(u, acts, strict=True)
        ]
        w.writerow([i, int(stations[i])] + vals + [f"{1e3 * x + 0.0:.4f}" for x in p])
    return buf.getvalue()


def _fmt(v: float) -> str:
    return repr(float(v) + 0.0)


def read_instrument_measurements(
    path: Path | str, mechanism: Mechanism, instrument: Instrument, targets: int = 1, stations: int = 1
) -> InstrumentMeasurements:
    """Read an instrument's measurement file.

    Args:
        path: The CSV file.
        mechanism: The mechanism (its actuated joints name the command columns).
        instrument: The measurement model.
        targets: Tracker reflectors (the tracker family).
        stations: Stations the instrument has (circles, spheres).

    Raises:
        MeasurementFileError: a missing, unknown or repeated column, a unit missing or wrong, a value
            that is not a finite number, a station that does not exist, a duplicated pose or touch.
    """
    path = Path(path)
    if instrument.name in ("tracker", "tracker-multi"):
        read = read_measurements(path, mechanism, targets)
        N = read.commands.shape[0]
        return InstrumentMeasurements(
            read.commands, read.measured_m.reshape(N, -1), np.zeros(N, dtype=int), read.labels, read.lines
        )
    rows = _rows(path)
    header_line, header = rows[0]
    acts = actuator_columns(mechanism)
    cols, has_station = _columns(instrument)
    want = {name: (LENGTH if kind == "P" else ANGLE) for name, kind in acts}
    want.update({name: (LENGTH if kind == "L" else ANGLE) for name, kind in cols})
    col_of: dict[str, int] = {}
    scale_of: dict[str, float] = {}
    for j, raw in enumerate(header):
        cell = raw.strip()
        if cell in ("pose", "station"):
            col_of[cell] = j
            continue
        m = _HEADER.match(cell)
        if not m:
            raise MeasurementFileError(
                path, header_line, cell, "no unit: write it in brackets, e.g. 'd [mm]'"
            )
        name, unit = m.group(1).strip(), m.group(2).strip()
        if name not in want:
            known = ", ".join([n for n, _ in acts] + [n for n, _ in cols])
            raise MeasurementFileError(
                path, header_line, name, f"not a column of a {instrument.name} file (columns: {known})"
            )
        if name in col_of:
            raise MeasurementFileError(path, header_line, name, "column given twice")
        if unit not in want[name]:
            what = "a length" if want[name] is LENGTH else "an angle"
            raise MeasurementFileError(
                path,
                header_line,
                name,
                f"unit '{unit}' is not {what} unit; use one of {', '.join(want[name])}",
            )
        col_of[name] = j
        scale_of[name] = want[name][unit]
    needed = [n for n, _ in acts] + (["station"] if has_station else []) + [n for n, _ in cols]
    for name in needed:
        if name not in col_of:
            raise MeasurementFileError(path, header_line, name, "missing column")
    seen: dict[tuple[int, tuple[float, ...]], int] = {}
    commands: list[tuple[float, ...]] = []
    values: list[list[float]] = []
    st: list[int] = []
    labels: list[str] = []
    lines: list[int] = []
    radius = float(getattr(instrument, "radius_m", 0.0))
    for line, r in rows[1:]:
        if len(r) != len(header):
            raise MeasurementFileError(path, line, "", f"{len(r)} fields for {len(header)} columns")
        u = tuple(_number(path, line, n, r[col_of[n]]) * scale_of[n] for n, _ in acts)
        s = 0
        if has_station:
            text = r[col_of["station"]].strip()
            if not re.fullmatch(r"\d+", text) or int(text) >= stations:
                raise MeasurementFileError(
                    path,
                    line,
                    "station",
                    f"'{text}' is not a station index 0…{stations - 1} of the {instrument.name}",
                )
            s = int(text)
        key = (s, tuple(round(x, SAME_DECIMALS) for x in u))
        if key in seen:
            raise MeasurementFileError(
                path,
                line,
                "",
                f"the same commands{' and station' if has_station else ''} as line {seen[key]} (duplicated "
                "row): keep one, or average the repeats before calibrating",
            )
        seen[key] = line
        vals = [_number(path, line, n, r[col_of[n]]) * scale_of[n] for n, _ in cols]
        commands.append(u)
        values.append(vals if cols else [radius])
        st.append(s)
        labels.append(r[col_of["pose"]].strip() if "pose" in col_of else str(len(labels)))
        lines.append(line)
    return InstrumentMeasurements(
        commands=np.array(commands, dtype=float),
        values=np.array(values, dtype=float),
        stations=np.array(st, dtype=int),
        labels=tuple(labels),
        lines=np.array(lines, dtype=int),
    )


def _rows(path: Path) -> list[tuple[int, list[str]]]:
    rows = csv_rows(path)
    if len(rows) < 2:
        raise MeasurementFileError(path, 0, "", "the file needs a header row and at least one measurement")
    return rows


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise MeasurementFileError(path, line, column, f"'{text.strip()[:40]}' is not a number") from None
    if not math.isfinite(v) or abs(v) > 1e9:
        raise MeasurementFileError(
            path, line, column, f"'{text.strip()[:40]}' is not a finite number of a sane size"
        )
    return v
