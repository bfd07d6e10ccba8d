"""Measurement-session files: the plan to measure (CSV) and the tracker's measurements (CSV).

Every number carries its unit in the column header, ``name [unit]``. Actuator columns are named
``<limb>.<joint>`` (the actuated joints), in mm/m/µm for prismatic and deg/rad/mrad for revolute
joints; positions ``x``, ``y``, ``z`` are in K.

Plan (written by ``pkmtol calibrate --plan FILE``)::

    pose,limb1.limb1_p3 [mm],limb2.limb2_p3 [mm],limb3.limb3_p3 [mm],P_x [mm],P_y [mm],P_z [mm]

(a hybrid machine: the wrist's actuators ``wrist.<joint>`` after the module's, and the TCP
``TCP_x, TCP_y, TCP_z``; the targets sit in the TCP frame, 0 = the TCP).

Measurements (read by ``pkmtol calibrate --measurements FILE``), one row per measured target::

    pose,limb1.limb1_p3 [mm],...,target,x [mm],y [mm],z [mm]

``target`` is the 0-based index of the target in ``[calibration] targets_m`` (0 = P when none is
given); ``pose`` is a label. Rows with the same commands form one pose, which must have every
target exactly once.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pkmtol.exceptions import MeasurementFileError
from pkmtol.model.mechanism import Mechanism

LENGTH = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6}
ANGLE = {"rad": 1.0, "mrad": 1e-3, "deg": math.pi / 180.0}
_HEADER = re.compile(r"^\s*([^\[\]]+?)\s*\[\s*([^\]]*)\s*\]\s*$")
#: Commands closer than this (relative to 1 m or 1 rad) belong to the same pose.
SAME_POSE = 1e-9


def actuator_columns(mechanism: Mechanism) -> list[tuple[str, str]]:
    """``(column name, kind)`` of every actuated joint, in the mechanism's actuator order (kind R or P).

    A hybrid machine: the module's, then the wrist's (``wrist.<joint>``).
    """
    out = []
    for limb in mechanism.limbs:
        for a in limb.actuated:
            out.append((f"{limb.name}.{limb.joint_names[a]}", limb.joint_kinds[a]))
    tool = mechanism.tool
    if tool is not None:
        out += [(f"wrist.{tool.joint_names[a]}", tool.joint_kinds[a]) for a in tool.actuated]
    return out


def plan_csv(mechanism: Mechanism, commands: np.ndarray, points_m: np.ndarray) -> str:
    """The plan as CSV text: commands (mm or deg) and the nominal P (mm; a hybrid's TCP), one row a pose."""
    cols = actuator_columns(mechanism)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    point = "TCP" if mechanism.tool is not None else "P"
    w.writerow(
        ["pose"]
        + [f"{c} [{'mm' if k == 'P' else 'deg'}]" for c, k in cols]
        + [f"{point}_{a} [mm]" for a in "xyz"]
    )
    for i, (u, p) in enumerate(zip(commands, points_m, strict=True)):
        vals = [
            f"{v * (1e3 if k == 'P' else 180.0 / math.pi) + 0.0:.6f}"
            for v, (_, k) in zip(u, cols, strict=True)
        ]
        w.writerow([i] + vals + [f"{1e3 * x + 0.0:.4f}" for x in p])
    return buf.getvalue()


def measurements_csv(
    mechanism: Mechanism, commands: np.ndarray, measured_m: np.ndarray, labels: list[str] | None = None
) -> str:
    """Measurements as CSV text: per pose and target, the commands and the measured position (mm)."""
    cols = actuator_columns(mechanism)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["pose"]
        + [f"{c} [{'mm' if k == 'P' else 'deg'}]" for c, k in cols]
        + ["target"]
        + [f"{a} [mm]" for a in "xyz"]
    )
    for i, (u, m) in enumerate(zip(commands, measured_m, strict=True)):
        vals = [_fmt(v * (1e3 if k == "P" else 180.0 / math.pi)) for v, (_, k) in zip(u, cols, strict=True)]
        for t, xyz in enumerate(m):
            w.writerow([labels[i] if labels else i] + vals + [t] + [_fmt(1e3 * x) for x in xyz])
    return buf.getvalue()


def _fmt(v: float) -> str:
    return repr(float(v) + 0.0)


@dataclass(frozen=True, eq=False)
class Measurements:
    """Measurements read from a file (SI units).

    Attributes:
        commands: Shape (N, f): actuator readings of each pose [m or rad].
        measured_m: Shape (N, t, 3): measured target positions in K [m].
        labels: The ``pose`` label of each pose.
        lines: Shape (N,): the file line of each pose's first row.
    """

    commands: np.ndarray
    measured_m: np.ndarray
    labels: tuple[str, ...]
    lines: np.ndarray


def read_measurements(path: Path | str, mechanism: Mechanism, n_targets: int) -> Measurements:
    """Read a measurement file (see the module docstring).

    Raises:
        MeasurementFileError: a missing or unknown column, a unit missing or wrong, a value that is
            not a finite number, a duplicated row, an unknown target, a pose with a target missing.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError as err:
        raise MeasurementFileError(path, 0, "", "file not found") from err
    except UnicodeDecodeError as err:
        raise MeasurementFileError(path, 0, "", f"not UTF-8 text ({err.reason} at byte {err.start})") from err
    rows = [(i + 1, r) for i, r in enumerate(csv.reader(io.StringIO(text))) if any(c.strip() for c in r)]
    if not rows:
        raise MeasurementFileError(path, 0, "", "the file is empty; it needs a header row and measurements")
    header_line, header = rows[0]
    acts = actuator_columns(mechanism)
    want = {name: kind for name, kind in acts}
    col_of: dict[str, int] = {}
    scale_of: dict[str, float] = {}
    for j, cell in enumerate(header):
        cell = cell.strip()
        if cell in ("pose", "target"):
            col_of[cell] = j
            continue
        m = _HEADER.match(cell)
        if not m:
            raise MeasurementFileError(
                path,
                header_line,
                cell,
                "no unit: write the unit in brackets, e.g. 'x [mm]' or 'limb1.limb1_p3 [mm]'",
            )
        name, unit = m.group(1).strip(), m.group(2).strip()
        if name in ("x", "y", "z"):
            table, what = LENGTH, "a length"
        elif name in want:
            table, what = (LENGTH, "a length") if want[name] == "P" else (ANGLE, "an angle")
        else:
            known = ", ".join(n for n, _ in acts)
            raise MeasurementFileError(
                path,
                header_line,
                name,
                f"not an actuated joint of {mechanism.name} nor x, y, z (actuated joints: {known})",
            )
        if unit not in table:
            raise MeasurementFileError(
                path, header_line, name, f"unit '{unit}' is not {what} unit; use one of {', '.join(table)}"
            )
        if name in col_of:
            raise MeasurementFileError(path, header_line, name, "column given twice")
        col_of[name] = j
        scale_of[name] = table[unit]
    for needed in [n for n, _ in acts] + ["target", "x", "y", "z"]:
        if needed not in col_of:
            raise MeasurementFileError(path, header_line, needed, "missing column")
    poses: dict[tuple[float, ...], dict[int, tuple[int, np.ndarray]]] = {}
    order: list[tuple[float, ...]] = []
    labels: dict[tuple[float, ...], str] = {}
    for line, r in rows[1:]:
        if len(r) != len(header):
            raise MeasurementFileError(path, line, "", f"{len(r)} fields for {len(header)} columns")
        u = tuple(_number(path, line, n, r[col_of[n]]) * scale_of[n] for n, _ in acts)
        xyz = np.array([_number(path, line, a, r[col_of[a]]) * scale_of[a] for a in "xyz"])
        t_text = r[col_of["target"]].strip()
        if not re.fullmatch(r"\d+", t_text) or int(t_text) >= n_targets:
            raise MeasurementFileError(
                path,
                line,
                "target",
                f"'{t_text}' is not a target index 0…{n_targets - 1} of [calibration] targets_m",
            )
        key = next((k for k in order if max(abs(a - b) for a, b in zip(k, u, strict=True)) < SAME_POSE), None)
        if key is None:
            key = u
            order.append(u)
            poses[u] = {}
            labels[u] = r[col_of["pose"]].strip() if "pose" in col_of else str(len(order) - 1)
        t = int(t_text)
        if t in poses[key]:
            raise MeasurementFileError(
                path,
                line,
                "target",
                f"target {t} of this pose is already measured at line {poses[key][t][0]} "
                "(duplicated row): keep one, or average the repeats before calibrating",
            )
        poses[key][t] = (line, xyz)
    if not order:
        raise MeasurementFileError(path, 0, "", "no measurement rows after the header")
    measured = np.empty((len(order), n_targets, 3))
    lines = np.empty(len(order), dtype=int)
    for i, key in enumerate(order):
        got = poses[key]
        missing = sorted(set(range(n_targets)) - set(got))
        first = min(v[0] for v in got.values())
        if missing:
            raise MeasurementFileError(
                path,
                first,
                "target",
                f"pose '{labels[key]}' lacks target(s) {missing}; measure them or drop the pose",
            )
        for t, (_, xyz) in got.items():
            measured[i, t] = xyz
        lines[i] = first
    return Measurements(
        commands=np.array(order, dtype=float),
        measured_m=measured,
        labels=tuple(labels[k] for k in order),
        lines=lines,
    )


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise MeasurementFileError(path, line, column, f"'{text}' is not a number") from None
    if not math.isfinite(v):
        raise MeasurementFileError(path, line, column, f"'{text}' is not a finite number")
    return v
