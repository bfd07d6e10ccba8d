"""Reading the files a mechanism is made of: TOML keys with errors that name them, and URDF limbs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import MechanismFormatError, URDFError


def load_urdf(limb: str, path: Path, text: str | None = None) -> tuple[pin.Model, Any]:
    """Read a limb URDF: ``(pin.Model, visual GeometryModel or None)``; raises URDFError naming the limb.

    ``text`` replaces the file's content (a URDF made in memory, e.g. from a changed D–H table).
    """
    if text is None and not path.is_file():
        raise URDFError(limb, path, "file not found; check the 'urdf' entry of this limb in mechanism.toml")
    if text is None:
        text = path.read_text(encoding="utf-8")
    import xml.etree.ElementTree as ET

    try:
        ET.fromstring(text)
    except ET.ParseError as err:
        raise URDFError(limb, path, f"malformed XML: {err}") from err
    try:
        model = pin.buildModelFromXML(text)
    except (RuntimeError, ValueError) as err:
        raise URDFError(limb, path, f"Pinocchio cannot read it: {err}") from err
    try:
        visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    except Exception:  # noqa: BLE001 - visuals are optional (meshes may be missing)
        visual = None
    return model, visual


class TomlReader:
    """Typed access to a TOML document with errors that name the file and the dotted key."""

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
            self.fail(key, f"expected {names}, got {type(node).__name__} {node!r}")
        return node

    def array(self, key: str, default: Any = _MISSING) -> np.ndarray:
        """Read a (nested) list of numbers as a float array; fail naming ``key`` if it is not."""
        v = self.get(key, list, default)
        try:
            return np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            self.fail(key, f"expected a list of numbers (rows of equal length), got {v!r}")
            raise

    def vector(self, key: str, n: int, default: Any = _MISSING) -> np.ndarray:
        """Read a list of ``n`` numbers as an array of shape (n,); fail naming ``key`` otherwise."""
        v = self.get(key, list, default)
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if arr.shape != (n,):
            self.fail(key, f"expected a list of {n} numbers, got {v!r}")
        return arr
