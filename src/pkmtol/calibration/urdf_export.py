"""Calibrated limb URDFs: the identified errors written into the joint origins, for any URDF loader.

Each moving joint's ``<origin>`` becomes ``origin · exp6(ε_j) · M_j(δq_j)`` — the placement error
of the error model (DESIGN.md: ``origin_actual = origin_nominal · exp6(ε)``) followed by the joint's
own motion by its zero offset ``δq_j`` (a rotation about, or a translation along, its axis), so that
the calibrated joint reads the same value as the real one. The fixed joint that attaches the
platform becomes ``origin · exp6(ε_e)``. Everything else of the source URDF (links, visuals,
limits) is kept. A ``mechanism.toml`` beside the URDFs makes the folder loadable by
:func:`pkmtol.load_mechanism`; it has no D–H tables (they describe the nominal geometry).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from pkmtol.calibration.machine import Machine
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import CalibrationError
from pkmtol.model.mechanism import Mechanism


def joint_origin(joint: ET.Element) -> pin.SE3:
    """A URDF joint's ``<origin>`` as a placement (identity when absent)."""
    o = joint.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def set_joint_origin(joint: ET.Element, placement: pin.SE3) -> None:
    """Write ``placement`` as the joint's ``<origin>`` (added when absent)."""
    o = joint.find("origin")
    if o is None:
        o = ET.Element("origin")
        joint.insert(0, o)
    rpy = pin.rpy.matrixToRpy(placement.rotation)
    o.set("xyz", " ".join(repr(float(v)) for v in placement.translation))
    o.set("rpy", " ".join(repr(float(v)) for v in rpy))


def joint_motion(joint: ET.Element, value: float) -> pin.SE3:
    """The motion of a 1-DOF revolute or prismatic URDF joint at ``value`` [rad or m]."""
    axis_el = joint.find("axis")
    axis = np.array(
        [float(v) for v in (axis_el.get("xyz", "1 0 0") if axis_el is not None else "1 0 0").split()]
    )
    axis = axis / np.linalg.norm(axis)
    if joint.get("type") == "prismatic":
        return pin.SE3(np.eye(3), axis * value)
    return pin.SE3(pin.exp3(axis * value), np.zeros(3))


def calibrated_urdfs(mechanism: Mechanism, pset: ParameterSet, estimate: np.ndarray) -> dict[str, str]:
    """The calibrated URDF text of every limb, keyed by the limb URDF's file name.

    Args:
        mechanism: The nominal mechanism (each limb loaded from its own URDF file).
        pset: The parameter set of ``estimate``.
        estimate: Shape (n,): identified errors [m, rad].

    Raises:
        CalibrationError: a limb has no URDF file of its own (built from a ``pin.Model`` or cut
            from a closed-loop tree), or its URDF lacks a joint of the model.
    """
    eps, offsets = pset.perturbation(np.asarray(estimate, dtype=float), mechanism)
    out: dict[str, str] = {}
    start = 0
    for limb, e in zip(mechanism.limbs, eps, strict=True):
        path = limb.urdf_path
        if path is None or not path.is_file() or path.name in out:
            raise CalibrationError(
                f"limb '{limb.name}': calibrated URDFs are written for limbs loaded from their own URDF "
                "file; this limb was built in Python or cut from a closed-loop tree — use the "
                "identified parameters (JSON) with your own model instead"
            )
        root = ET.fromstring(path.read_text(encoding="utf-8"))
        joints = {j.get("name"): j for j in root.findall("joint")}
        dq = offsets[start : start + limb.nq]
        start += limb.nq
        for k, name in enumerate(limb.joint_names):
            joint = joints.get(name)
            if joint is None:
                raise CalibrationError(f"limb '{limb.name}': joint '{name}' is not in {path.name}")
            placement = joint_origin(joint) * pin.exp6(e[k]) * joint_motion(joint, float(dq[k]))
            set_joint_origin(joint, placement)
        attach = joints.get(limb.attach_name)
        if attach is None:
            if np.any(e[limb.nq] != 0.0):
                raise CalibrationError(
                    f"limb '{limb.name}': no fixed joint '{limb.attach_name}' attaches the platform in "
                    f"{path.name}, so its identified error cannot be written"
                )
        else:
            delta = pin.exp6(e[limb.nq])
            set_joint_origin(attach, joint_origin(attach) * delta)
            # the attachment error moves the platform frame only (pkmtol's model): links fixed below
            # the platform link (a loop's socket) keep their place
            below = str(_child(attach))
            for j in joints.values():
                parent = j.find("parent")
                if j.get("type") == "fixed" and parent is not None and parent.get("link") == below:
                    set_joint_origin(j, delta.inverse() * joint_origin(j))
        for k, lp in enumerate(limb.loops):  # a loop's error: the fixed joint of its frame b's link
            fixed = [
                j for j in joints.values() if j.get("type") == "fixed" and _child(j) == lp.frame_names[1]
            ]
            if fixed:
                set_joint_origin(fixed[0], joint_origin(fixed[0]) * pin.exp6(e[limb.nq + 1 + k]))
            elif np.any(e[limb.nq + 1 + k] != 0.0):
                raise CalibrationError(
                    f"limb '{limb.name}': loop '{lp.name}''s frame '{lp.frame_names[1]}' is not a link "
                    f"attached by a fixed joint in {path.name}, so its identified error cannot be written"
                )
        ET.indent(root, "  ")
        out[path.name] = (
            '<?xml version="1.0"?>\n<!-- calibrated by pkmtol calibrate: joint origins carry the '
            "identified errors -->\n" + ET.tostring(root, encoding="unicode") + "\n"
        )
    return out


def calibrated_toml(mechanism: Mechanism, pset: ParameterSet, estimate: np.ndarray) -> str:
    """A ``mechanism.toml`` for the calibrated URDFs (same task space and targets, no D–H tables).

    ``home`` is the calibrated machine's own closure at the nominal home commands (passive joints
    solved exactly), in the calibrated joints' readings.
    """
    machine = Machine(mechanism, pset, estimate)
    q_home = machine.chain.home() - machine.offsets
    ts = mechanism.task_space
    lines = [
        "# written by pkmtol calibrate: the identified machine (limb URDFs beside this file)",
        f"name = {_q(mechanism.name + '_calibrated')}",
        f"description = {_q('calibrated ' + mechanism.name)}",
        f"platform_link = {_q(_platform_link(mechanism))}",
        "",
        "[reference_point]",
        f"position_m = {_list(mechanism.reference_point_m)}",
        "",
    ]
    if mechanism.task_normal is not None:
        lines += ["[task]", 'kind = "planar"', f"normal = {_list(mechanism.task_normal)}", ""]
    lines += [
        "[task_space]",
    ]
    if ts.kind == "cylinder":
        lines += [
            'kind = "cylinder"',
            f"radius_m = {ts.radius_m!r}",
            f"z_m = {_list(ts.z_range_m)}",
            f"layers = {ts.layers}",
            f"rings = [{', '.join(str(r) for r in ts.rings)}]",
            f"center_xy_m = {_list(ts.center_xy_m)}",
        ]
    else:
        assert ts.points_m is not None
        lines += ['kind = "points"', "points_m = [" + ", ".join(_list(p) for p in ts.points_m) + "]"]
    lines += [
        "",
        "[design]",
        f"target = {_q(repr(mechanism.target_m) + ' m')}",
        f"beta = {_list(mechanism.betas)}",
        f"design_beta = {mechanism.design_beta!r}",
    ]
    start = 0
    for limb in mechanism.limbs:
        assert limb.urdf_path is not None
        home = q_home[start : start + limb.nq]
        start += limb.nq
        acted = ", ".join(_q(limb.joint_names[a]) for a in limb.actuated)
        lines += [
            "",
            "[[limbs]]",
            f"name = {_q(limb.name)}",
            f"urdf = {_q(limb.urdf_path.name)}",
            f"actuated = [{acted}]",
            f"home = {_list(home)}",
        ]
        for lp in limb.loops:
            frames = ", ".join(_q(f) for f in lp.frame_names)
            lines += [
                "",
                "[[limbs.loops]]",
                f"name = {_q(lp.name)}",
                f"frames = [{frames}]",
                f"type = {_q(lp.kind)}",
            ]
    return "\n".join(lines) + "\n"


def _child(joint: ET.Element) -> str | None:
    child = joint.find("child")
    return None if child is None else child.get("link")


def _platform_link(mechanism: Mechanism) -> str:
    limb = mechanism.limbs[0]
    return str(limb.model.frames[limb.platform_frame].name)


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _list(values: object) -> str:
    arr = np.asarray(values, dtype=float).ravel()
    if not np.all(np.isfinite(arr)):  # pragma: no cover - the mechanism was validated
        raise CalibrationError("non-finite value in the mechanism description")
    return "[" + ", ".join(repr(float(v) + 0.0) for v in arr) + "]"


def write_calibrated_folder(folder: Path, urdfs: dict[str, str], toml: str) -> list[tuple[Path, bytes]]:
    """The files of a calibrated robot folder, as ``(path, bytes)`` (the caller writes them)."""
    files = [(folder / name, text.encode("utf-8")) for name, text in urdfs.items()]
    files.append((folder / "mechanism.toml", toml.encode("utf-8")))
    return files
