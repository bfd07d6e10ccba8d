"""Robots with loops inside limbs, built for the tests: the Delta's 6D variant, a slider-crank seed robot."""

from __future__ import annotations

import importlib.util
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"

#: Slider-crank of the seed robot's limb 1 [m]: crank pivot on the cylinder, crank, connecting rod.
CRANK_PIVOT_Z = 0.31
CRANK = 0.4
ROD = 0.6


def delta_script():
    """The module ``scripts/delta_urdf.py``."""
    spec = importlib.util.spec_from_file_location("delta_urdf", ROOT / "scripts" / "delta_urdf.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def delta_variant(folder: Path, loop: str) -> Path:
    """Write the Delta with rod 2 closed by a ``loop`` ('3d' or '6d') loop into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for path, text in delta_script().generate(folder, loop).items():
        path.write_text(text, encoding="utf-8")
    return folder


def _crank_angle(q3: float) -> float:
    """Crank angle φ ∈ (−π/2, π/2) [rad] of the in-line slider-crank that puts the piston at ``q3`` [m]."""
    lo, hi = -np.pi / 2 + 1e-9, np.pi / 2 - 1e-9
    for _ in range(200):  # bisection: q3(φ) rises on (−π/2, π/2) for these dimensions
        mid = 0.5 * (lo + hi)
        value = CRANK_PIVOT_Z + CRANK * np.sin(mid) + np.sqrt(ROD**2 - (CRANK * np.cos(mid)) ** 2)
        lo, hi = (mid, hi) if value < q3 else (lo, mid)
    return 0.5 * (lo + hi)


def _xyz_rpy(m: pin.SE3) -> dict[str, str]:
    fmt = lambda v: " ".join(repr(float(x)) for x in v)  # noqa: E731
    return {"xyz": fmt(m.translation), "rpy": fmt(pin.rpy.matrixToRpy(m.rotation))}


def slider_crank_variant(folder: Path) -> Path:
    """The seed robot with limb 1 driven by a slider-crank: a four-bar (R-U-S-P) inside the limb.

    Limb 1's prismatic joint ``limb1_p3`` becomes passive; a crank ``limb1_crank`` (actuated) on the
    cylinder link drives the piston through a connecting rod (universal joint at the crank pin) whose
    end must meet the piston pin: a ``3d`` loop. The rest of the mechanism is the seed robot's.
    """
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("limb2.urdf", "limb3.urdf", "limb4.urdf"):
        (folder / name).write_text((SEED / name).read_text(encoding="utf-8"), encoding="utf-8")
    tree = ET.parse(SEED / "limb1.urdf")
    robot = tree.getroot()
    p3 = next(j for j in robot.findall("joint") if j.get("name") == "limb1_p3")
    o = p3.find("origin")
    assert o is not None
    rpy = np.array([float(x) for x in o.get("rpy", "0 0 0").split()])
    frame = pin.SE3(pin.rpy.rpyToMatrix(rpy), np.array([float(x) for x in o.get("xyz", "0 0 0").split()]))
    doc = (SEED / "mechanism.toml").read_text(encoding="utf-8")
    home_q3 = float(re.search(r"home = \[0\.32175, 0\.0, ([0-9.]+),", doc).group(1))  # type: ignore[union-attr]
    phi0 = _crank_angle(home_q3)
    pin_f = np.array(
        [CRANK * np.cos(phi0), 0.0, CRANK_PIVOT_Z + CRANK * np.sin(phi0)]
    )  # crank pin in p3's frame F
    d = np.array([0.0, 0.0, home_q3]) - pin_f
    assert abs(np.linalg.norm(d) - ROD) < 1e-9
    d /= ROD
    y = np.array([0.0, 1.0, 0.0])
    r_rod_f = np.column_stack(
        [np.cross(y, d), y, d]
    )  # rod frame in F: y along the crank axis, z along the rod
    # crank: rotation about F's y; q = −φ puts the pin at (r cos φ, 0, z_c + r sin φ)
    crank_at = frame * pin.SE3(np.eye(3), np.array([0.0, 0.0, CRANK_PIVOT_Z]))
    r_crank_home = pin.utils.rotate("y", -phi0)
    u_at = pin.SE3(r_crank_home.T @ r_rod_f, np.array([CRANK, 0.0, 0.0]))

    def add_link(name: str) -> None:
        ET.SubElement(robot, "link", name=name)

    def add_joint(
        name: str, kind: str, parent: str, child: str, at: pin.SE3, axis: str | None = None
    ) -> None:
        j = ET.SubElement(robot, "joint", name=name, type=kind)
        ET.SubElement(j, "origin", **_xyz_rpy(at))
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=child)
        if axis is not None:
            ET.SubElement(j, "axis", xyz=axis)
            ET.SubElement(j, "limit", lower="-3.0", upper="3.0", effort="1000", velocity="1")

    for name in ("limb1_crank_link", "limb1_rod_cross", "limb1_rod", "limb1_rod_end", "limb1_piston_pin"):
        add_link(name)
    add_joint("limb1_crank", "revolute", "limb1_l2", "limb1_crank_link", crank_at, "0 1 0")
    add_joint("limb1_rod_u1", "revolute", "limb1_crank_link", "limb1_rod_cross", u_at, "0 1 0")
    add_joint("limb1_rod_u2", "revolute", "limb1_rod_cross", "limb1_rod", pin.SE3.Identity(), "1 0 0")
    add_joint(
        "limb1_rod_end_fix", "fixed", "limb1_rod", "limb1_rod_end", pin.SE3(np.eye(3), np.array([0, 0, ROD]))
    )
    add_joint("limb1_piston_pin_fix", "fixed", "limb1_l3", "limb1_piston_pin", pin.SE3.Identity())
    ET.indent(robot, "  ")
    (folder / "limb1.urdf").write_text(ET.tostring(robot, encoding="unicode"), encoding="utf-8")
    model = pin.buildModelFromUrdf(str(folder / "limb1.urdf"))
    seed_home = [0.32175, 0.0, home_q3, 0.0, 0.0, -0.32175]
    values = dict(
        zip(["limb1_u1", "limb1_u2", "limb1_p3", "limb1_s4", "limb1_s5", "limb1_s6"], seed_home, strict=True)
    )
    values.update({"limb1_crank": -phi0, "limb1_rod_u1": 0.0, "limb1_rod_u2": 0.0})
    home = ", ".join(repr(values[n]) for n in model.names[1:])
    # limb 1 without its D–H table (a limb with loops takes the urdf set), actuated at the crank
    start = doc.index("# ---- limb 1")
    end = doc.index("# ---- limb 2")
    limb1 = (
        "# ---- limb 1: UPS whose leg is driven by a slider-crank (R-U-S-P four-bar) ----\n"
        "[[limbs]]\n"
        'name = "limb1"\n'
        'urdf = "limb1.urdf"\n'
        'actuated = ["limb1_crank"]\n'
        f"home = [{home}]\n\n"
        "[[limbs.loops]]\n"
        'name = "rod"\n'
        'frames = ["limb1_piston_pin", "limb1_rod_end"]\n'
        'type = "3d"\n\n'
    )
    (folder / "mechanism.toml").write_text(doc[:start] + limb1 + doc[end:], encoding="utf-8")
    return folder


def merged(mech, into: int, other: int):
    """The mechanism with limb ``other`` (passive) merged into limb ``into`` as a branch closed by a 6D loop.

    The merged limb's tree holds both limbs' joints (``constraint_models`` of the two); limb
    ``other``'s platform frame becomes the loop's frame b (its attachment error becomes the loop's
    error) and limb ``into``'s platform frame its frame a. Same kinematics, same parameters (renamed):
    returns ``(mechanism, names)`` with ``names`` the merged parameter name of each original one.
    """
    from types import SimpleNamespace

    from pkmtol.model.limb import make_limb
    from pkmtol.model.mechanism import Mechanism

    a, b = mech.limbs[into], mech.limbs[other]
    assert not b.actuated, f"limb {b.name} is actuated"
    cm = __import__("pkmtol.model.constraints", fromlist=["constraint_models"]).constraint_models(
        SimpleNamespace(name="pair", limbs=(a, b))
    )
    fa, fb = cm.platform_frames
    names = [cm.model.frames[fa].name, cm.model.frames[fb].name]
    limb = make_limb(
        a.name,
        cm.model,
        [a.joint_names[k] for k in a.actuated],
        names[0],
        np.concatenate([a.home, b.home]),
        None,
        loops=[(b.name, names[0], names[1], "6d")],
    )
    limbs = [limb if i == into else lb for i, lb in enumerate(mech.limbs) if i != other]
    new = Mechanism.from_limbs(mech.name + "_merged", limbs, mech.reference_point_m, mech.task_space)
    rename = {}
    for lb in (a, b):
        for j in lb.joint_names:
            for comp in ("dx", "dy", "dz", "rx", "ry", "rz", "offset"):
                rename[f"{lb.name}.{j}.{comp}"] = f"{a.name}.{j}.{comp}"
    for comp in ("dx", "dy", "dz", "rx", "ry", "rz"):
        rename[f"{a.name}.{a.attach_name}.{comp}"] = f"{a.name}.{limb.attach_name}.{comp}"
        rename[f"{b.name}.{b.attach_name}.{comp}"] = f"{a.name}.{b.name}.{comp}"
    for lb in mech.limbs:
        if lb not in (a, b):
            for j in list(lb.joint_names) + [lb.attach_name]:
                for comp in ("dx", "dy", "dz", "rx", "ry", "rz", "offset"):
                    rename[f"{lb.name}.{j}.{comp}"] = f"{lb.name}.{j}.{comp}"
    return new, rename
