"""The sidecar of a closed-loop URDF: its loops and motors (YAML as example-parallel-robots writes, or TOML).

Keys (docs/closed-loop.md): ``closed_loop`` (frame pairs, one per loop), ``type`` (``"6d"`` or
``"3d"`` per loop), ``name_mot`` (motor joints), ``joint_name`` / ``joint_type`` (re-typing).
"""

from __future__ import annotations

import ast
import dataclasses
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pkmtol.exceptions import MechanismFormatError
from pkmtol.model.reading import TomlReader, quoted, read_text

#: Sidecar file names tried next to ``<stem>.urdf`` when none is given.
SIDECAR_SUFFIXES = (".yaml", ".yml", ".toml")


@dataclass(frozen=True)
class Sidecar:
    """The loops and motors of a closed-loop URDF (the sidecar file's contents).

    Attributes:
        path: The sidecar file (None when built in Python).
        loops: Frame-name pairs that must coincide, one per loop, in file order; empty when the
            file has no ``closed_loop`` key (the pairs then come from the frame names).
        types: Per loop, ``"6d"`` or ``"3d"`` (lower case).
        motors: Motor joint names (``name_mot``); None when the key is missing.
        joint_types: Joint re-typing from ``joint_name`` / ``joint_type`` (upper case).
    """

    path: Path | None = None
    loops: tuple[tuple[str, str], ...] = ()
    types: tuple[str, ...] = ()
    motors: tuple[str, ...] | None = None
    joint_types: Mapping[str, str] = dataclasses.field(default_factory=dict)


def default_sidecar(urdf: Path | str) -> Path:
    """The sidecar next to ``urdf``: ``<stem>.yaml``, ``.yml`` or ``.toml``, the first that exists.

    Raises:
        MechanismFormatError: none of them exists.
    """
    urdf = Path(urdf)
    for suffix in SIDECAR_SUFFIXES:
        cand = urdf.with_suffix(suffix)
        if cand.is_file():
            return cand
    raise MechanismFormatError(
        urdf.with_suffix(".yaml"),
        "-",
        "file not found; a closed-loop URDF needs a sidecar listing its loops and motors "
        f"({' or '.join(urdf.with_suffix(s).name for s in SIDECAR_SUFFIXES)}; see docs/closed-loop.md)",
    )


def read_sidecar(path: Path | str) -> Sidecar:
    """Read a sidecar file (YAML as written by example-parallel-robots, or TOML with the same keys).

    YAML is read with PyYAML when it is installed (it comes with meshcat, through pyngrok);
    without it, the ``key: [python literal]`` lines that example-parallel-robots writes are
    still understood. A ``.toml`` file is read with the standard library.

    Raises:
        MechanismFormatError: the file is missing or unreadable, or a key is mistyped.
    """
    path = Path(path)
    if not path.is_file():
        raise MechanismFormatError(path, "-", "file not found; give the sidecar listing the loops and motors")
    text = read_text(path, lambda problem: MechanismFormatError(path, "-", problem))
    if path.suffix == ".toml":
        try:
            doc: Any = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise MechanismFormatError(path, "-", f"not valid TOML: {err}") from err
    else:
        doc = _load_yaml(path, text)
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise MechanismFormatError(path, "-", f"expected a mapping of keys, got {type(doc).__name__}")
    return sidecar_from_dict(doc, path)


def sidecar_from_dict(doc: Mapping[str, Any], path: Path | str | None = None) -> Sidecar:
    """Validate the sidecar keys of ``doc`` (see the module docstring).

    Raises:
        MechanismFormatError: a key is mistyped or the lists disagree in length.
    """
    where = Path(path) if path is not None else Path("<sidecar>")
    r = TomlReader(where, dict(doc))
    loops: list[tuple[str, str]] = []
    for k, pair in enumerate(r.get("closed_loop", list, default=[])):
        if not (isinstance(pair, list | tuple) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
            r.fail(f"closed_loop[{k}]", f"expected a pair of frame names, got {quoted(pair)}")
        loops.append((pair[0], pair[1]))
    types = _str_list(r, "type", default=["6d"] * len(loops))
    if len(types) != len(loops):
        r.fail("type", f"{len(types)} types for {len(loops)} loops; give one type per closed_loop pair")
    types = [t.lower() for t in types]
    for k, t in enumerate(types):
        if t not in ("6d", "3d"):
            r.fail(f"type[{k}]", f"unknown loop type {quoted(t)}; use '6d' or '3d'")
    motors = _str_list(r, "name_mot", default=None)
    names = _str_list(r, "joint_name", default=[])
    jtypes = _str_list(r, "joint_type", default=[])
    if len(names) != len(jtypes):
        r.fail("joint_type", f"{len(jtypes)} types for {len(names)} joint_name entries")
    return Sidecar(
        path=None if path is None else Path(path),
        loops=tuple(loops),
        types=tuple(types),
        motors=None if motors is None else tuple(motors),
        joint_types={n: t.upper() for n, t in zip(names, jtypes, strict=True)},
    )


def _str_list(r: TomlReader, key: str, default: Any) -> Any:
    v = r.get(key, list, default=default)
    if v is not None and not all(isinstance(x, str) for x in v):
        r.fail(key, f"expected a list of strings, got {quoted(v)}")
    return v


def _load_yaml(path: Path, text: str) -> Any:
    try:
        import yaml
    except ImportError:
        return _load_literal_yaml(path, text)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise MechanismFormatError(path, "-", f"not valid YAML: {err}") from err
    except RecursionError as err:  # issue 25: a document nested thousands deep
        raise MechanismFormatError(
            path, "-", "nested too deeply to read (a list or map thousands deep)"
        ) from err


def _load_literal_yaml(path: Path, text: str) -> dict[str, Any]:
    """The ``key: [python literal]`` lines example-parallel-robots writes, without PyYAML."""
    doc: dict[str, Any] = {}
    for n, line in enumerate(text.splitlines(), 1):
        body = line.split("#", 1)[0].strip() if not line.lstrip().startswith("#") else ""
        if not body:
            continue
        key, sep, value = body.partition(":")
        try:
            if not sep:
                raise ValueError("no 'key:'")
            doc[key.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError) as err:
            raise MechanismFormatError(
                path,
                "-",
                f"line {n}: cannot read {line.strip()!r} without PyYAML ({err}); "
                "install PyYAML or write the sidecar as TOML with the same keys",
            ) from err
    return doc
