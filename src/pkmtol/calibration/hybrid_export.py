"""A calibrated robot folder of any machine: the limb URDFs, a hybrid's calibrated tool chain, the TOML.

The module's limbs are written as :mod:`pkmtol.calibration.urdf_export` writes them. A hybrid's
tool chain URDF gets the same treatment: each wrist joint's ``<origin>`` becomes
``origin · exp6(ε_j) · M_j(δq_j)`` (its placement error, then its motion by its zero offset), and
the TCP frame's error ``ε_t`` (run-out, tool length, tilt; ``TCP = nose · Tz(L) · exp6(ε_t)``)
becomes a fixed link ``<nose>_calibrated`` on the nose at ``Tz(L) · exp6(ε_t) · Tz(−L)``, which
the calibrated ``mechanism.toml`` names as the ``nose_frame``: the TCP is then ``Tz(L)`` from
it, exactly the identified one. The TOML adds the ``[task]`` (the tool-axis cone) and ``[tool]``
tables to the module's (:func:`~pkmtol.calibration.urdf_export.calibrated_toml`); it has no D–H
tables (they describe the nominal geometry).
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from pkmtol.calibration.urdf_export import (
    calibrated_toml,
    calibrated_urdfs,
    joint_motion,
    joint_origin,
    set_joint_origin,
)
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.tool_chain import HybridParameterSet
from pkmtol.exceptions import CalibrationError
from pkmtol.kinematics.tool_chain import split_tool_eps
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.tool import Tool

#: Suffix of the link that carries the identified TCP frame (the calibrated folder's nose frame).
CALIBRATED_NOSE = "_calibrated"


def calibrated_files(
    mechanism: Mechanism, pset: ParameterSet, estimate: np.ndarray
) -> tuple[dict[str, str], str]:
    """The calibrated URDFs (by file name) and ``mechanism.toml`` of a module or a hybrid machine.

    Raises:
        CalibrationError: a limb or the tool chain has no URDF file of its own, or a URDF lacks a
            joint of the model (see :func:`~pkmtol.calibration.urdf_export.calibrated_urdfs`).
    """
    est = np.asarray(estimate, dtype=float)
    if mechanism.tool is None or not isinstance(pset, HybridParameterSet):
        return calibrated_urdfs(mechanism, pset, est), calibrated_toml(mechanism, pset, est)
    module = dataclasses.replace(mechanism, tool=None, tool_directions=None)
    module_set, module_est = pset.module_set(), est[: pset.module_count]
    urdfs = calibrated_urdfs(module, module_set, module_est)
    tool = mechanism.tool
    if tool.urdf_path is None or not tool.urdf_path.is_file() or tool.urdf_path.name in urdfs:
        raise CalibrationError(
            "the tool chain: calibrated URDFs are written for a tool chain loaded from its own URDF "
            "file; use the identified parameters (JSON) with your own model instead"
        )
    eps, offsets = split_tool_eps(pset.tool_raw(est), tool)
    urdfs[tool.urdf_path.name] = tool_urdf(tool, eps, offsets)
    toml = calibrated_toml(module, module_set, module_est) + _tool_tables(mechanism, tool)
    return urdfs, toml


def tool_urdf(tool: Tool, eps: np.ndarray, offsets: np.ndarray) -> str:
    """The tool chain's URDF with placement errors ``eps`` (nq + 1, 6) and zero offsets (nq,) written in."""
    assert tool.urdf_path is not None
    path = tool.urdf_path
    root = ET.fromstring(path.read_text(encoding="utf-8"))
    joints = {j.get("name"): j for j in root.findall("joint")}
    for k, name in enumerate(tool.joint_names):
        joint = joints.get(name)
        if joint is None:
            raise CalibrationError(f"the tool chain: joint '{name}' is not in {path.name}")
        set_joint_origin(
            joint, joint_origin(joint) * pin.exp6(pin.Motion(eps[k])) * joint_motion(joint, float(offsets[k]))
        )
    nose = tool.nose_name
    shift = pin.SE3(np.eye(3), np.array([0.0, 0.0, tool.length_m]))
    link = ET.SubElement(root, "link", {"name": nose + CALIBRATED_NOSE})
    link.tail = "\n"
    fixed = ET.SubElement(root, "joint", {"name": nose + "_tcp_calibration", "type": "fixed"})
    ET.SubElement(fixed, "parent", {"link": nose})
    ET.SubElement(fixed, "child", {"link": nose + CALIBRATED_NOSE})
    set_joint_origin(fixed, shift * pin.exp6(pin.Motion(eps[tool.nq])) * shift.inverse())
    ET.indent(root, "  ")
    return (
        '<?xml version="1.0"?>\n<!-- calibrated by pkmtol calibrate: joint origins and the TCP frame '
        "carry the identified errors -->\n" + ET.tostring(root, encoding="unicode") + "\n"
    )


def _tool_tables(mechanism: Mechanism, tool: Tool) -> str:
    assert tool.urdf_path is not None
    lines = [""]
    dirs = mechanism.tool_directions
    if dirs is not None:
        lines += [
            "[task]",
            'kind = "tool"',
            f"axis = {_list(dirs.axis)}",
            f'cone = "{float(dirs.half_angle_rad)!r} rad"',
            f"rings = [{', '.join(str(r) for r in dirs.rings)}]",
            "",
        ]
    else:
        lines += ["[task]", 'kind = "tool"', ""]
    acted = ", ".join(f'"{tool.joint_names[a]}"' for a in tool.actuated)
    lines += [
        "[tool]",
        f'urdf = "{tool.urdf_path.name}"',
        f"actuated = [{acted}]",
        f'nose_frame = "{tool.nose_name + CALIBRATED_NOSE}"',
        f'length = "{float(tool.length_m)!r} m"',
        f"home = {_list(tool.home)}",
    ]
    if tool.locked:  # 3-axis work: the locked joints at their set values
        lines += ["", "[tool.locked]"]
        for j in tool.locked:
            unit = "m" if tool.joint_kinds[j] == "P" else "rad"
            lines.append(f'{tool.joint_names[j]} = "{float(tool.home[j])!r} {unit}"')
    return "\n".join(lines) + "\n"


def _list(values: object) -> str:
    return "[" + ", ".join(repr(float(v) + 0.0) for v in np.asarray(values, dtype=float).ravel()) + "]"
