"""``calibrate --tolerances``: the design-β σ of an ``allocation.json`` of ``pkmtol allocate``, checked.

The file must be an allocation of the same mechanism and parameter set, and its parameters must be
this mechanism's: a file of another robot, or with a name that is not one of this robot's, is refused
(it would leave every uncompensatable error at 0 and a calibration study that flatters the design).
Every field read is type-checked, so a malformed file is a named error, never a traceback.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.calibration.measurement_files import MAX_FILE_BYTES, read_limited
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import InvalidRequestError, MechanismFormatError


def read_tolerances(
    path: Path, mechanism_name: str, pset: ParameterSet, settings: CalibrationSettings
) -> tuple[np.ndarray, str]:
    """Design-β σ of every parameter of ``pset`` (NaN where not allocated) [m or rad], and a label.

    A calibrated-mode design's identified parameters are drawn at the manufacturing σ of
    ``settings``.

    Raises:
        MechanismFormatError: not an allocation.json (unreadable, not JSON, a field missing or of
            the wrong type: the field is named).
        InvalidRequestError: an allocation of another mechanism or parameter set, or whose
            parameter names match none of this one's.
    """
    try:
        data = read_limited(path)
        if data is None:
            raise MechanismFormatError(
                path,
                "-",
                f"holds more than {MAX_FILE_BYTES // 2**20} MiB: not an allocation.json of `pkmtol allocate`",
            )
        doc = json.loads(data.decode("utf-8"))
    except (OSError, ValueError) as err:
        raise MechanismFormatError(path, "-", f"not an allocation.json of `pkmtol allocate` ({err})") from err
    if not isinstance(doc, dict):
        raise MechanismFormatError(
            path, "-", "not an allocation.json of `pkmtol allocate` (not a JSON object)"
        )
    betas = _field(path, doc, "beta", list)
    beta = _field(path, doc, "design_beta", float)
    kind = _field(path, doc, "parameter_set", str)
    rows = _field(path, doc, "parameters", list)
    if not betas or not all(_is_number(b) for b in betas):
        raise MechanismFormatError(path, "beta", "expected a non-empty list of numbers")
    col = int(np.argmin(np.abs(np.asarray(betas, dtype=float) - beta)))
    if abs(float(betas[col]) - beta) > 1e-9 * max(abs(beta), 1.0):
        raise MechanismFormatError(path, "design_beta", f"{beta:g} is not one of the file's β {betas[:8]}")
    name = doc.get("mechanism")
    if isinstance(name, str) and name != mechanism_name:
        raise InvalidRequestError(
            f"--tolerances {path}: an allocation of '{name}', not of '{mechanism_name}'; give the "
            f"allocation.json of `pkmtol allocate` on {mechanism_name}"
        )
    if kind != pset.kind:
        raise InvalidRequestError(
            f"{path} allocates the '{kind}' parameter set but this calibration uses '{pset.kind}'; "
            f"give --set {kind}"
        )
    by_name: dict[str, Any] = {}
    classes_in_mode: dict[str, Any] = {}
    for i, row in enumerate(rows):
        if not isinstance(row, dict) or not isinstance(row.get("name"), str):
            raise MechanismFormatError(path, f"parameters[{i}]", "expected an object with a 'name'")
        t = row.get("tolerance")
        if t is None:  # a parameter the allocation does not tolerance (compensatable, absorbed)
            t = [None] * len(betas)
        if not isinstance(t, list) or len(t) != len(betas) or not all(v is None or _is_number(v) for v in t):
            raise MechanismFormatError(
                path, f"parameters[{i}].tolerance", f"expected a list of {len(betas)} numbers (or null)"
            )
        if any(v is not None and not (math.isfinite(v) and v >= 0) for v in t):
            raise MechanismFormatError(
                path, f"parameters[{i}].tolerance", "a tolerance must be finite and ≥ 0"
            )
        by_name[row["name"]] = t
        classes_in_mode[row["name"]] = row.get("class_in_mode")
    known = set(pset.names)
    unknown = [n for n in by_name if n not in known]
    if unknown or not by_name:
        shown = ", ".join(f"'{n[:40]}'" for n in unknown[:3]) + (" …" if len(unknown) > 3 else "")
        what = (
            f"none of its {len(by_name)} parameter names"
            if len(unknown) == len(by_name)
            else "the parameter(s)"
        )
        raise InvalidRequestError(
            f"--tolerances {path}: {what} {shown or '(none)'} "
            f"{'is' if len(unknown) == 1 else 'are'} not of {mechanism_name}'s {pset.kind} set; give the "
            "allocation.json of `pkmtol allocate` on this robot"
        )
    chosen = _chosen(path, doc.get("method_design"))
    tol = np.full(len(pset), np.nan)
    manufacturing = settings.manufacturing_sigma(pset)
    for i, pname in enumerate(pset.names):
        t = chosen.get(pname) if chosen else None
        if t is None:
            row = by_name.get(pname)
            t = None if row is None else row[col]
        if t is not None:
            tol[i] = float(t)
        elif classes_in_mode.get(pname) == "identified":
            tol[i] = manufacturing[i]  # removed by the calibration: drawn at manufacturing σ
    design = doc.get("method_design")
    method = design.get("method") if chosen and isinstance(design, dict) else None
    what = f"'{method}' design" if method is not None else "FOSM design-β tolerances"
    return tol, f"{what} of {path}"


def _field(path: Path, doc: dict[str, Any], key: str, kind: type) -> Any:
    value = doc.get(key)
    ok = _is_number(value) if kind is float else isinstance(value, kind)
    if not ok:
        want = {float: "a number", str: "a name", list: "a list"}[kind]
        raise MechanismFormatError(
            path,
            key,
            f"expected {want}, got {_short(value)}; is this an allocation.json of `pkmtol allocate`?",
        )
    return float(value) if kind is float and value is not None else value


def _chosen(path: Path, design: Any) -> dict[str, float]:
    """The tolerances of a ``--method`` design (``method_design``), if the file has one."""
    if design is None:
        return {}
    names = design.get("parameters") if isinstance(design, dict) else None
    values = design.get("tolerance") if isinstance(design, dict) else None
    if (
        not isinstance(design, dict)
        or not isinstance(design.get("method"), str)
        or not isinstance(names, list)
        or not isinstance(values, list)
        or len(names) != len(values)
        or not all(isinstance(n, str) for n in names)
        or not all(_is_number(v) and math.isfinite(v) and v >= 0 for v in values)
    ):
        raise MechanismFormatError(
            path, "method_design", "expected {method, parameters: [names], tolerance: [numbers ≥ 0]}"
        )
    return dict(zip(names, (float(v) for v in values), strict=True))


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
