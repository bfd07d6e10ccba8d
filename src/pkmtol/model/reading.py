"""Reading the files a mechanism is made of: TOML keys with errors that name them, and URDF limbs."""

from __future__ import annotations

import contextlib
import math
import os
import reprlib
import sys
import tempfile
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import MechanismFormatError, PkmtolWarning, URDFError
from pkmtol.model.urdf_xml import check_urdf_tree, fill_missing_limits, resolve_meshes
from pkmtol.values import MAX_LENGTH_M

_QUOTE = reprlib.Repr()
_QUOTE.maxlevel, _QUOTE.maxlist, _QUOTE.maxtuple, _QUOTE.maxdict = 3, 8, 8, 8
_QUOTE.maxstring, _QUOTE.maxother, _QUOTE.maxlong = 60, 60, 40


def quoted(value: object, limit: int = 120) -> str:
    """``repr(value)`` for a message: at most ``limit`` characters, nested lists cut.

    A YAML alias bomb of 9⁹ shared items then quotes in microseconds instead of 2 GB.
    """
    text = _QUOTE.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_text(path: Path, fail: Callable[[str], Exception]) -> str:
    """The UTF-8 text of ``path``; ``fail(problem)`` is raised if it cannot be read or decoded."""
    try:
        data = path.read_bytes()
    except OSError as err:
        raise fail(f"cannot read the file: {err.strerror or err}") from err
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise fail(
            f"not UTF-8 text (byte 0x{data[err.start]:02x} at line {line}); save the file as UTF-8"
        ) from err


@contextlib.contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """Capture what C/C++ code writes on the process's stderr (file descriptor 2) meanwhile.

    Yields a list that holds the captured text (one string) after the block. urdfdom prints the
    reason it rejects a URDF there; this puts it into the exception instead of the terminal.
    """
    out: list[str] = []
    with contextlib.suppress(AttributeError, ValueError, OSError):
        sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            out.append(tmp.read().decode("utf-8", "replace"))


def parser_reason(text: str) -> str:
    """The error lines (``Error: ...``) of urdfdom's stderr, without the source locations."""
    lines = []
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("at line"):
            continue
        lines.append(line.removeprefix("Error:").strip())
    return "; ".join(dict.fromkeys(lines))


def build_model(limb: str, path: Path, text: str) -> tuple[pin.Model, ET.Element]:
    """Parse a URDF text: ``(pin.Model, XML root)``; URDFError names the limb and the parser's reason.

    A revolute or continuous joint without a range is read over [−π, π] with a
    :class:`~pkmtol.exceptions.MissingLimitWarning` (:func:`~pkmtol.model.urdf_xml.fill_missing_limits`).
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise URDFError(limb, path, f"malformed XML: {err}") from err
    if fill_missing_limits(root, limb, path):
        text = ET.tostring(root, encoding="unicode")
    check_urdf_tree(root, limb, path)
    with captured_stderr() as noise:
        try:
            model = pin.buildModelFromXML(text)
            problem = None
        except (RuntimeError, ValueError) as err:
            model, problem = None, str(err)
    if problem is not None or model is None:
        reason = parser_reason(noise[0]) if noise else ""
        raise URDFError(
            limb, path, f"Pinocchio cannot read it: {reason or problem}" + (f" ({problem})" if reason else "")
        )
    return model, root


def build_visuals(model: pin.Model, root: ET.Element, limb: str, path: Path, text: str | None = None) -> Any:
    """The visual ``pin.GeometryModel`` (None if it has none or it cannot be built, with a warning).

    ``text`` is the URDF text of ``root``; it is used as it is when the visuals name no mesh file.
    """
    if root.find("link/visual") is None:
        return None
    if text is None or root.find(".//mesh") is not None:
        text = ET.tostring(resolve_meshes(root, limb, path), encoding="unicode")
    with captured_stderr() as noise:
        try:
            return pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
        except Exception as err:  # noqa: BLE001 - visuals are optional; say why they are missing
            problem = str(err)
    reason = parser_reason(noise[0]) if noise else ""
    warnings.warn(
        PkmtolWarning(
            f"limb '{limb}' ({path}): its visuals cannot be read ({reason or problem}); "
            "the 3D scene shows the limb without them (results are not affected)"
        ),
        stacklevel=3,
    )
    return None


def load_urdf(limb: str, path: Path, text: str | None = None) -> tuple[pin.Model, Any]:
    """Read a limb URDF: ``(pin.Model, visual GeometryModel or None)``; raises URDFError naming the limb.

    ``text`` replaces the file's content (a URDF made in memory, e.g. from a changed D–H table).
    """
    if text is None and not path.is_file():
        raise URDFError(limb, path, "file not found; check the 'urdf' entry of this limb in mechanism.toml")
    if text is None:
        text = read_text(path, lambda problem: URDFError(limb, path, problem))
    model, root = build_model(limb, path, text)
    return model, build_visuals(model, root, limb, path, text)


def check_finite(path: Path, doc: Any, where: str = "") -> None:
    """Raise MechanismFormatError naming the dotted key of the first ``nan`` or ``inf`` anywhere in ``doc``.

    Every table is covered, also those read later by other stages (``[calibration]``, ``[cost]``).
    """
    if isinstance(doc, dict):
        for key, value in doc.items():
            check_finite(path, value, f"{where}.{key}" if where else str(key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            check_finite(path, value, f"{where}[{i}]")
    elif isinstance(doc, float) and not math.isfinite(doc):
        raise MechanismFormatError(
            path, where, f"{quoted(doc)} is not a finite number; write the number itself"
        )


class TomlReader:
    """Typed access to a TOML document with errors that name the file and the dotted key.

    Numbers must be finite: TOML's ``nan`` and ``inf`` are refused wherever a number is read.
    """

    def __init__(self, path: Path, doc: dict[str, Any], prefix: str = "") -> None:
        self.path, self.doc, self.prefix = path, doc, prefix

    def fail(self, key: str, problem: str) -> None:
        """Raise MechanismFormatError naming the file and the dotted ``key``."""
        raise MechanismFormatError(self.path, self.prefix + key, problem)

    _MISSING = object()

    def get(self, key: str, types: Any, default: Any = _MISSING) -> Any:
        """The value at dotted ``key``, checked against ``types`` (``default`` if missing, else an error)."""
        node: Any = self.doc
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                if default is not self._MISSING:
                    return default
                self.fail(key, "missing; see docs/mechanism-format.md")
            node = node[part]
        tt = types if isinstance(types, tuple) else (types,)
        if isinstance(node, bool) or not isinstance(node, tt):
            names = " or ".join(t.__name__ for t in tt)
            self.fail(key, f"expected {names}, got {type(node).__name__} {quoted(node)}")
        if isinstance(node, float) and not math.isfinite(node):
            self.fail(key, f"expected a finite number, got {quoted(node)}")
        return node

    def lengths(self, key: str, n: int | None = None, default: Any = _MISSING) -> np.ndarray:
        """Like :meth:`vector` (``n`` numbers) or :meth:`array` (``n`` None), each within ±10 km [m]."""
        arr = self.array(key, default) if n is None else self.vector(key, n, default)
        if arr.size and float(np.max(np.abs(arr))) > MAX_LENGTH_M:
            self.fail(
                key,
                f"a length beyond ±{MAX_LENGTH_M:g} m, got {quoted(arr.tolist())}; "
                "is the unit right (metres)?",
            )
        return arr

    def array(self, key: str, default: Any = _MISSING) -> np.ndarray:
        """Read a (nested) list of finite numbers as a float array; fail naming ``key`` if it is not."""
        v = self.get(key, list, default)
        if _has_non_number(v):
            self.fail(key, f"expected a list of numbers (rows of equal length), got {quoted(v)}")
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError, OverflowError):
            self.fail(key, f"expected a list of numbers (rows of equal length), got {quoted(v)}")
            raise
        if not np.all(np.isfinite(arr)):
            self.fail(key, f"every number must be finite (no nan or inf), got {quoted(v)}")
        return arr

    def vector(self, key: str, n: int, default: Any = _MISSING) -> np.ndarray:
        """Read a list of ``n`` finite numbers as an array of shape (n,); fail naming ``key`` otherwise."""
        v = self.get(key, list, default)
        arr = self.array(key, default) if isinstance(v, list) else np.zeros(0)
        if arr.shape != (n,):
            self.fail(key, f"expected a list of {n} numbers, got {quoted(v)}")
        return arr

    def strings(self, key: str, default: Any = _MISSING, what: str = "strings") -> list[str]:
        """Read a list of strings; fail naming ``key`` (and ``what`` they are) if an entry is not one."""
        v = self.get(key, list, default)
        if v is not None and not all(isinstance(x, str) for x in v):
            self.fail(key, f"expected a list of {what}, got {quoted(v)}")
        return v  # type: ignore[no-any-return]

    def joint_values(self, key: str, default: Any = _MISSING) -> dict[str, float] | None:
        """Read a table joint name → value [rad or m]; fail naming ``key.<joint>`` at a non-number."""
        table = self.get(key, dict, default)
        if table is None:
            return None
        for jname, value in table.items():
            if isinstance(value, bool) or not isinstance(value, int | float):
                self.fail(f"{key}.{jname}", f"expected a number (rad or m), got {quoted(value)}")
        return {k: float(v) for k, v in table.items()}


def _has_non_number(value: Any) -> bool:
    if isinstance(value, list):
        return any(_has_non_number(v) for v in value)
    return isinstance(value, bool) or not isinstance(value, int | float)
