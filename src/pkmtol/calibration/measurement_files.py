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
import gc
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
    """Read a measurement file (see the module docstring), in time linear in its rows.

    The garbage collector is paused meanwhile: the millions of cells and rows of a large file are
    all alive until the end, and collecting them over and over made the reading grow faster than
    the file (10⁶ rows: 50 s instead of a few; scripts/benchmark.py --measurement-files-only).

    Raises:
        MeasurementFileError: a missing or unknown column, a unit missing or wrong, a value that is
            not a finite number, a duplicated row, an unknown target, a pose with a target missing.
    """
    collecting = gc.isenabled()
    gc.disable()
    try:
        return _read(Path(path), mechanism, n_targets)
    finally:
        if collecting:
            gc.enable()


def _read(path: Path, mechanism: Mechanism, n_targets: int) -> Measurements:
    rows = csv_rows(path)
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
            if cell in col_of:  # two of them: which is which cannot be told
                raise MeasurementFileError(path, header_line, cell, "column given twice")
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
    body = rows[1:]
    if not body:
        raise MeasurementFileError(path, 0, "", "no measurement rows after the header")
    for line, r in body:
        if len(r) != len(header):
            raise MeasurementFileError(path, line, "", f"{len(r)} fields for {len(header)} columns")
    lines_of = np.array([line for line, _ in body], dtype=int)
    cells = list(zip(*(r for _, r in body), strict=True))  # the columns
    names = [n for n, _ in acts]
    U = np.column_stack([_numbers(path, cells[col_of[n]], lines_of, n) * scale_of[n] for n in names])
    XYZ = np.column_stack([_numbers(path, cells[col_of[a]], lines_of, a) * scale_of[a] for a in "xyz"])
    targets = _targets(path, cells[col_of["target"]], lines_of, n_targets)
    pose_of = _group(U)
    n_poses = int(pose_of.max()) + 1
    code = pose_of * n_targets + targets  # one code per (pose, target)
    order = np.argsort(code, kind="stable")
    repeat = np.flatnonzero(code[order][1:] == code[order][:-1])
    if repeat.size:
        dup = order[repeat + 1]  # each repeat's row, its first measurement just before it
        i = int(dup.min())
        j = int(order[repeat[np.argmin(dup)]])
        raise MeasurementFileError(
            path,
            int(lines_of[i]),
            "target",
            f"target {targets[i]} of this pose is already measured at line {lines_of[j]} "
            "(duplicated row): keep one, or average the repeats before calibrating",
        )
    seen = np.zeros((n_poses, n_targets), dtype=bool)
    seen[pose_of, targets] = True
    measured = np.empty((n_poses, n_targets, 3))
    measured[pose_of, targets] = XYZ
    first = np.full(n_poses, len(body), dtype=int)
    np.minimum.at(first, pose_of, np.arange(len(body)))
    firsts = first.tolist()
    labels = tuple(
        body[i][1][col_of["pose"]].strip() if "pose" in col_of else str(k) for k, i in enumerate(firsts)
    )
    lacking = np.flatnonzero(~seen.all(axis=1))
    if lacking.size:
        k = int(lacking[0])
        missing = [int(t) for t in np.flatnonzero(~seen[k])]
        raise MeasurementFileError(
            path,
            int(lines_of[first[k]]),
            "target",
            f"pose '{labels[k]}' lacks target(s) {missing}; measure them or drop the pose",
        )
    return Measurements(commands=U[first], measured_m=measured, labels=labels, lines=lines_of[first])


#: Commands are binned on a grid this much coarser than :data:`SAME_POSE` before they are compared.
_BIN = 1000.0
#: Largest magnitude of a value in its file's unit (1e9 mm = 1000 km: beyond it, not a measurement).
_LARGEST = 1e9


def _group(U: np.ndarray) -> np.ndarray:
    """The pose index (0, 1, … in order of first appearance) of every row's commands (N, f).

    Rows whose commands agree within :data:`SAME_POSE` form one pose. The commands are binned on a
    grid :data:`_BIN` × ``SAME_POSE`` wide (``np.unique``, no Python loop over the rows); a row
    within ``SAME_POSE`` of a bin edge joins the neighbouring bin's pose when it agrees with it.
    A bin that holds commands further apart than ``SAME_POSE`` (poses 1e-9 … 1e-6 apart) is left
    to :func:`_group_rows`, which compares every row with the poses of its bins.
    """
    cell = _BIN * SAME_POSE
    scaled = U / cell
    keys = np.round(scaled)
    near = np.abs(scaled - keys) > 0.5 - 1.0 / _BIN
    packed = _packed(keys)
    uniq, first, inverse = np.unique(packed, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    if np.any(np.max(np.abs(U - U[first[inverse]]), axis=1) >= SAME_POSE):
        return _group_rows(U)
    parent = np.arange(len(uniq))
    for i in np.flatnonzero(near.any(axis=1)).tolist():  # rare: within SAME_POSE of a bin edge
        candidates = [keys[i]]
        for j in np.flatnonzero(near[i]).tolist():
            step = 1.0 if scaled[i, j] > keys[i, j] else -1.0
            for c in list(candidates):
                moved = c.copy()
                moved[j] += step
                candidates.append(moved)
        for c in candidates[1:]:
            b = int(np.searchsorted(uniq, _packed(c[None, :])[0]))
            if b < len(uniq) and uniq[b] == _packed(c[None, :])[0]:
                if np.max(np.abs(U[first[b]] - U[i])) < SAME_POSE:
                    ra, rb = _root(parent, int(inverse[i])), _root(parent, b)
                    parent[max(ra, rb)] = min(ra, rb)
    while True:  # pointer jumping: every bin to its root
        up = parent[parent]
        if np.array_equal(up, parent):
            break
        parent = up
    starts = np.full(len(uniq), len(U))
    np.minimum.at(starts, parent, first)  # each pose's first row
    pose_bins = np.flatnonzero(parent == np.arange(len(parent)))  # the roots
    rank = np.empty(len(uniq), dtype=int)
    rank[pose_bins[np.argsort(starts[pose_bins], kind="stable")]] = np.arange(len(pose_bins))
    return rank[parent[inverse]]


def _packed(keys: np.ndarray) -> np.ndarray:
    """Rows of bin indices (m, f) as one sortable value each (their int64 bytes)."""
    k = np.ascontiguousarray(keys.astype(np.int64))
    return k.view(np.dtype((np.void, 8 * k.shape[1]))).ravel()


def _root(parent: np.ndarray, b: int) -> int:
    while parent[b] != b:
        b = int(parent[b])
    return b


def _group_rows(U: np.ndarray) -> np.ndarray:
    """:func:`_group` row by row: each row compared with the poses of its bin and of the bins it is near."""
    cell = _BIN * SAME_POSE
    scaled = U / cell
    keys = np.round(scaled)
    frac = scaled - keys
    near: np.ndarray = np.abs(frac) > 0.5 - 1.0 / _BIN
    near_any = np.asarray(near.any(axis=1), dtype=bool).tolist()
    bins: dict[tuple[float, ...], list[int]] = {}
    poses: list[list[float]] = []
    out = np.empty(len(U), dtype=int)
    rows = U.tolist()
    for i, (key_list, u) in enumerate(zip(keys.tolist(), rows, strict=True)):
        key = tuple(key_list)
        candidates = [key]
        if near_any[i]:
            for j in np.flatnonzero(near[i]).tolist():
                step = 1.0 if frac[i, j] > 0 else -1.0
                candidates += [c[:j] + (c[j] + step,) + c[j + 1 :] for c in candidates]
        found = -1
        for c in candidates:
            for k in bins.get(c, ()):
                if max(abs(a - b) for a, b in zip(poses[k], u, strict=True)) < SAME_POSE:
                    found = k
                    break
            if found >= 0:
                break
        if found < 0:
            found = len(poses)
            poses.append(u)
            bins.setdefault(key, []).append(found)
        out[i] = found
    return out


#: The most a measurement or allocation file may hold [bytes]; more is refused unread, not read
#: until memory runs out (``--measurements /dev/zero`` was killed by the kernel at 23 GB).
MAX_FILE_BYTES = 256 * 2**20


def read_limited(path: Path, limit: int | None = None) -> bytes | None:
    """The bytes of ``path``, or None when it holds more than ``limit`` (default :data:`MAX_FILE_BYTES`).

    Raises:
        OSError: it cannot be opened or read.
    """
    limit = MAX_FILE_BYTES if limit is None else limit
    with path.open("rb") as f:
        data = f.read(limit + 1)
    return None if len(data) > limit else data


def csv_rows(path: Path) -> list[tuple[int, list[str]]]:
    """The non-empty CSV rows of ``path`` with their 1-based line numbers (every measurement format's reader).

    Raises:
        MeasurementFileError: a folder, a missing or unreadable file, one larger than
            :data:`MAX_FILE_BYTES`, not UTF-8, not CSV.
    """
    if path.is_dir():
        raise MeasurementFileError(path, 0, "", "is a folder; give the measurement CSV file")
    try:
        data = read_limited(path)
        if data is None:
            raise MeasurementFileError(
                path,
                0,
                "",
                f"holds more than {MAX_FILE_BYTES // 2**20} MiB (a device or an endless stream?); a "
                "tracker file of 10⁶ rows is about 120 MB: give the session's file, or split it",
            )
        text = data.decode("utf-8-sig")
    except FileNotFoundError as err:
        raise MeasurementFileError(path, 0, "", "file not found") from err
    except UnicodeDecodeError as err:
        raise MeasurementFileError(path, 0, "", f"not UTF-8 text ({err.reason} at byte {err.start})") from err
    except OSError as err:
        raise MeasurementFileError(path, 0, "", f"cannot be read ({err.strerror or err})") from err
    try:
        return [(i + 1, r) for i, r in enumerate(csv.reader(io.StringIO(text))) if "".join(r).strip()]
    except csv.Error as err:
        raise MeasurementFileError(path, 0, "", f"not a CSV file ({err})") from err


def _numbers(path: Path, cells: tuple[str, ...], lines: np.ndarray, column: str) -> np.ndarray:
    """A column's cells as finite numbers of a sane size (in the file's unit), or the first bad one named."""
    try:
        v = np.array(cells, dtype=float)
    except ValueError:
        for line, text in zip(lines.tolist(), cells, strict=True):
            _number(path, line, column, text)
        raise  # pragma: no cover - a cell numpy cannot read is one float() cannot read
    bad = np.flatnonzero(~np.isfinite(v) | (np.abs(v) > _LARGEST))
    if bad.size:
        _number(path, int(lines[bad[0]]), column, cells[bad[0]])
    return v


def _targets(path: Path, cells: tuple[str, ...], lines: np.ndarray, n_targets: int) -> np.ndarray:
    """The ``target`` column as indices 0 … n_targets − 1."""
    try:
        out = np.array(cells, dtype=np.int64)  # accepts " 1", refuses "1.0" and "x"
    except (ValueError, OverflowError):
        out = None
    if out is not None and out.size and out.min() >= 0 and out.max() < n_targets:
        if all(c.strip().isdigit() for c in set(cells)):  # no '+1'
            return out
    for line, text in zip(lines.tolist(), cells, strict=True):
        t_text = text.strip()
        if not t_text.isdigit() or not t_text.isascii() or int(t_text) >= n_targets:
            raise MeasurementFileError(
                path,
                line,
                "target",
                f"'{t_text[:40]}' is not a target index 0…{n_targets - 1} of [calibration] targets_m",
            )
    return np.array([int(c) for c in cells], dtype=int)  # pragma: no cover - refused above


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise MeasurementFileError(path, line, column, f"'{text.strip()[:40]}' is not a number") from None
    if not math.isfinite(v):
        raise MeasurementFileError(path, line, column, f"'{text.strip()[:40]}' is not a finite number")
    if abs(v) > _LARGEST:
        raise MeasurementFileError(
            path,
            line,
            column,
            f"'{text.strip()[:40]}' is larger than {_LARGEST:g} in its unit: not a measurement",
        )
    return v
