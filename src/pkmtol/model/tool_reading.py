"""The ``[tool]`` table and the tool task (``task.kind = "tool"``) of ``mechanism.toml``.

Keys (docs/mechanism-format.md, "The tool chain"): ``[tool] urdf`` (the chain, rooted on the
platform link), ``actuated`` (wrist joints driven by the controller), ``locked`` (joint → value
with its unit, e.g. ``wrist_a = "30 deg"``), ``nose_frame`` (the spindle-nose link), ``length``
(nose → TCP along the nose z axis, with its unit; default ``"0 mm"``), ``home`` (first guess of
every joint, rad or m). The task's tool directions: ``[task] axis`` (the cone's axis in K),
``cone`` (its half-angle, default ``"0 deg"``) and ``rings`` (directions per ring, default
``[6]`` for a cone).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from pkmtol.exceptions import InvalidRequestError
from pkmtol.model.dh import DHTable, check_dh_matches
from pkmtol.model.reading import TomlReader, load_urdf
from pkmtol.model.taskspace import ToolDirections
from pkmtol.model.tool import TOOL, Tool, make_tool
from pkmtol.units import parse_angle, parse_length

#: Keys of the task table that belong to ``kind = "tool"`` only.
TOOL_TASK_KEYS = ("axis", "cone", "rings")


def read_tool(
    r: TomlReader, folder: Path, platform_link: str, n_module_actuators: int, dh: DHTable | None = None
) -> Tool:
    """The ``[tool]`` table as a :class:`Tool` (MechanismFormatError naming the key if it is wrong).

    Args:
        r: The reader of mechanism.toml.
        folder: The robot folder (the URDF path is relative to it).
        platform_link: The module's platform link (the chain's root).
        n_module_actuators: Actuators of the parallel module: with the wrist's, they must make
            as many as the task has rows (3 for a locked wrist, 5 with two wrist actuators).
        dh: The chain's ``[tool.dh]`` table, if it has one (checked against the URDF).
    """
    urdf = folder / r.get("tool.urdf", str)
    actuated = r.strings("tool.actuated", default=[], what="joint names")
    locked_doc = r.get("tool.locked", dict, default={})
    nose = r.get("tool.nose_frame", str)
    length = _quantity(r, "tool.length", "0 mm", parse_length)
    home = r.array("tool.home") if "home" in r.get("tool", dict) else None
    model, visual = load_urdf(TOOL, urdf)
    kinds = {model.names[j]: model.joints[j].shortname() for j in range(1, model.njoints)}
    locked: dict[str, float] = {}
    for jname, value in locked_doc.items():
        parse = parse_length if kinds.get(jname, "").startswith("JointModelP") else parse_angle
        locked[jname] = _value(r, f"tool.locked.{jname}", value, parse)
    if home is not None and home.shape != (model.nq,):
        r.fail("tool.home", f"expected {model.nq} numbers, one per joint of {urdf.name}, got {home.tolist()}")
    tool = make_tool(model, platform_link, actuated, locked, nose, length, home, urdf, visual)
    if dh is not None:  # the chain's D–H table (``[tool.dh]``): its URDF must be the table's
        check_dh_matches(tool.as_limb(tool.nose_frame), dh, f"python scripts/dh_to_urdf.py {folder}")
        tool = replace(tool, dh=dh)
    if len(tool.actuated) not in (0, 2):
        r.fail(
            "tool.actuated",
            f"{len(tool.actuated)} actuated wrist joint(s); the tool task has 3 rows (TCP position, a "
            "locked wrist) or 5 (TCP position + tool axis, two wrist actuators): actuate 0 or 2 joints",
        )
    rows = 3 + len(tool.actuated)
    if n_module_actuators + len(tool.actuated) != rows:
        r.fail(
            "tool.actuated",
            f"the module has {n_module_actuators} actuators and the wrist {len(tool.actuated)}: "
            f"{n_module_actuators + len(tool.actuated)} for a task of {rows} rows; the hybrid layer "
            "needs a 3-actuator module (a redundant or deficient machine is not supported)",
        )
    return tool


def read_tool_directions(r: TomlReader, tool: Tool) -> ToolDirections | None:
    """The task's cone of tool axes; None for a locked wrist (the task is the TCP position)."""
    task = r.get("task", dict, default={})
    if not tool.actuated:
        given = [k for k in TOOL_TASK_KEYS if k in task]
        if given:
            r.fail(
                f"task.{given[0]}",
                "the wrist is locked (no [tool] actuated joint): the task is the TCP position only; "
                "remove the tool directions or actuate two wrist joints",
            )
        return None
    axis = r.vector("task.axis", 3)
    if np.linalg.norm(axis) < 1e-12:
        r.fail("task.axis", f"expected a non-zero [x, y, z] (frame K), got {axis.tolist()}")
    cone = _quantity(r, "task.cone", "0 deg", parse_angle)
    if not 0.0 <= cone < np.pi / 2:
        r.fail("task.cone", f"the cone's half-angle must be in [0, 90) deg, got {np.degrees(cone):g} deg")
    rings_arr = r.array("task.rings", default=[6] if cone > 0 else [])
    if rings_arr.ndim != 1 or np.any(rings_arr < 1) or np.any(rings_arr != np.round(rings_arr)):
        r.fail("task.rings", f"expected a list of integers ≥ 1, got {rings_arr.tolist()!r}")
    if rings_arr.size and cone == 0.0:
        r.fail("task.rings", "rings of directions need a cone half-angle > 0 (task.cone)")
    return ToolDirections(
        (float(axis[0]), float(axis[1]), float(axis[2])), cone, tuple(int(k) for k in rings_arr)
    )


def _quantity(r: TomlReader, key: str, default: str, parse: object) -> float:
    value = r.get(key, (str, float, int), default=default)
    return _value(r, key, value, parse)


def _value(r: TomlReader, key: str, value: object, parse: object) -> float:
    if not isinstance(value, str):
        r.fail(key, f'write the unit with the number, e.g. "{value} mm" or "{value} deg"')
    try:
        return float(parse(value, key))  # type: ignore[operator]
    except InvalidRequestError as err:
        r.fail(key, str(err))
        raise
