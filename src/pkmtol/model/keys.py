"""The keys ``mechanism.toml`` may hold, table by table: the one place a new key or table is registered.

:data:`KNOWN_KEYS` maps a table's path to the keys it takes. ``limbs[]`` is every ``[[limbs]]``
entry; ``*`` stands for any one key of a table whose keys are free names (joint or parameter
names), and :data:`ANY` marks such a table. :func:`check_keys` walks a parsed document and raises
:class:`~pkmtol.exceptions.UnknownKeyError` on the first key it does not know, with the closest
known key as a "did you mean" (``difflib``).

To add a key, add it to its table's set here (and read it in the loader); to add a table, add an
entry for its path, e.g. ``"calibration": frozenset({"targets_m", "noise", "poses"})`` for an
optional ``[calibration]`` table, and entries for its sub-tables. A key the loader reads but that is
not registered here is refused, so a test that loads a file using it fails until it is registered.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pkmtol.exceptions import UnknownKeyError

#: A table whose keys are free names (checked by the code that reads it).
ANY: frozenset[str] = frozenset({"*"})

_COST_FIELDS = frozenset({"A", "B", "k", "t_min", "t_max"})

#: Known keys of mechanism.toml by table path (docs/mechanism-format.md, docs/closed-loop.md).
KNOWN_KEYS: dict[str, frozenset[str]] = {
    "": frozenset(
        {
            "name",
            "description",
            "base_link",
            "platform_link",
            "reference_point",
            "task",
            "task_space",
            "design",
            "limbs",
            "closed_loop",
            "mjcf",
            "cost",
            "calibration",
            "drawing",
            "tool",
        }
    ),
    "reference_point": frozenset({"position_m"}),
    "task": frozenset({"kind", "normal", "axis", "cone", "rings"}),
    "tool": frozenset({"urdf", "actuated", "locked", "nose_frame", "length", "home", "dh", "compensation"}),
    "tool.locked": ANY,
    "tool.dh": frozenset({"joint_types", "joint_names", "links", "end", "limits"}),
    "task_space": frozenset({"kind", "radius_m", "z_m", "layers", "rings", "center_xy_m", "points_m"}),
    "design": frozenset({"target", "beta", "design_beta", "orientation_target", "tool_axis"}),
    "limbs[]": frozenset({"name", "urdf", "actuated", "home", "dh", "loops"}),
    "limbs[].loops[]": frozenset({"name", "frames", "type"}),
    "limbs[].dh": frozenset({"joint_types", "joint_names", "links", "end", "limits"}),
    "closed_loop": frozenset({"urdf", "sidecar", "platform_link", "limbs", "home"}),
    "closed_loop.home": ANY,
    "mjcf": frozenset({"file", "platform_link", "limbs", "home", "keyframe", "actuated"}),
    "mjcf.home": ANY,
    "cost": frozenset({"length", "angle", "parameters"}),
    "cost.length": _COST_FIELDS,
    "cost.angle": _COST_FIELDS,
    "cost.parameters": ANY,
    "cost.parameters.*": _COST_FIELDS,
    # read by pkmtol.calibration.settings (its TABLE_KEYS; tests/test_errors_doc.py keeps them equal)
    "calibration": frozenset(
        {
            "targets_m",
            "noise",
            "poses",
            "selection",
            "controller",
            "prior",
            "rank_tolerance",
            "candidates",
            "manufacturing_length",
            "manufacturing_angle",
            "instrument",
            "orientation_noise",
            "tracker_frame",
            "stations_m",
            "ballbar_length",
            "circle_planes",
            "circle_points",
            "artifact",
            "artifact_faces",
            "artifact_radius",
            "approach_directions",
            "tracker_on",
        }
    ),
    # read by pkmtol.model.drawing (its TABLE_KEYS; tests/test_signoff.py keeps them equal)
    "drawing": frozenset({"convention", "k", "feature_length", "feature_lengths", "nominals"}),
    "drawing.feature_lengths": ANY,
    "drawing.nominals": ANY,
}


def check_keys(path: Path, doc: Mapping[str, Any], known: Mapping[str, frozenset[str]] | None = None) -> None:
    """Raise UnknownKeyError for the first key of ``doc`` that its table does not take.

    Args:
        path: The file, for the message.
        doc: The parsed TOML document.
        known: Table path → keys (default :data:`KNOWN_KEYS`).

    Raises:
        UnknownKeyError: naming the dotted key (``limbs[2].actaated``) and the closest known key.
    """
    _check_table(path, doc, "", "", KNOWN_KEYS if known is None else known)


def _check_table(
    path: Path, table: Mapping[str, Any], schema: str, dotted: str, known: Mapping[str, frozenset[str]]
) -> None:
    keys = known.get(schema)
    if keys is None:
        return  # a table nobody registered sub-keys for (a value the reader type-checks)
    for key, value in table.items():
        where = f"{dotted}.{key}" if dotted else key
        if keys is ANY or keys == ANY:
            sub = f"{schema}.*"
        elif key in keys:
            sub = f"{schema}.{key}" if schema else key
        else:
            close = difflib.get_close_matches(key, sorted(keys), n=1, cutoff=0.6)
            raise UnknownKeyError(path, where, keys, close[0] if close else None)
        if isinstance(value, Mapping):
            _check_table(path, value, sub, where, known)
        elif isinstance(value, list) and f"{sub}[]" in known:
            for i, item in enumerate(value):
                if isinstance(item, Mapping):
                    _check_table(path, item, f"{sub}[]", f"{where}[{i}]", known)
