"""Write (or check) a limb-folder robot the way example-parallel-robots writes one: one URDF tree, a sidecar.

The output (``robot.urdf``, ``robot.yaml``, ``mechanism.toml``) is the "extended URDF" of
Gepetto/example-parallel-robots: the limbs' URDFs merged at the common base link, limb 1 carrying
the platform link; every other limb ends where it meets the platform in a link ``closedloop<k>_B``
(at the limb's platform attachment, so that it coincides with the platform link when loop k is
closed: the pair is ``['platform', 'closedloop<k>_B']``); and a limb's own loops close *between its
branches*: a frame of the limb that hung on the platform (the Delta's rod-2 sockets) hangs on the
limb's last link instead (rod 1's end), so the rod-2 loops of arms 2 and 3 close between the rods
and touch neither the platform nor the tree path to it. The sidecar is example-parallel-robots'
``closed_loop`` / ``type`` / ``name_mot`` / ``joint_name`` / ``joint_type`` lines; the
``mechanism.toml`` holds pkmtol's keys (``[closed_loop]``, reference point, task, design, calibration).

Usage:
    python scripts/limbs_to_epr.py robots/delta robots/delta_epr          # write
    python scripts/limbs_to_epr.py robots/delta robots/delta_epr --check  # exit 1 if out of date
"""

from __future__ import annotations

import importlib.util
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pinocchio as pin

from pkmtol.model.loader import load_mechanism

_SPEC = importlib.util.spec_from_file_location(
    "limbs_to_closed_loop", Path(__file__).with_name("limbs_to_closed_loop.py")
)
assert _SPEC is not None and _SPEC.loader is not None
_BASE = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_BASE)


def _origin_of(m: pin.SE3) -> dict[str, str]:
    return {"xyz": _BASE._fmt(m.translation), "rpy": _BASE._fmt(pin.rpy.matrixToRpy(m.rotation))}


def generate(folder: Path) -> dict[str, str]:
    """File name → text of the example-parallel-robots form of the robot in ``folder``."""
    mech = load_mechanism(folder)
    doc = tomllib.loads((folder / "mechanism.toml").read_text(encoding="utf-8"))
    platform = doc.get("platform_link", "platform")
    robot = ET.Element("robot", name=f"{mech.name}_epr")
    robot.append(ET.Comment(f" generated from {folder.name}/ by scripts/limbs_to_epr.py; do not edit "))
    links: list[ET.Element] = []
    joints: list[ET.Element] = []
    seen: set[str] = set()
    loops: list[tuple[str, str]] = []
    types: list[str] = []
    inner: list[tuple[tuple[str, str], str]] = []
    motors, home = [], {}
    for i, limb in enumerate(mech.limbs):
        assert limb.urdf_path is not None
        src = ET.parse(limb.urdf_path).getroot()
        attach = next(j for j in src.findall("joint") if j.find("child").get("link") == platform)  # type: ignore[union-attr]
        below = {
            j.find("child").get("link"): j
            for j in src.findall("joint")
            if j.find("parent").get("link") == platform
        }  # type: ignore[union-attr]
        for link in src.findall("link"):
            name = link.get("name")
            if name in seen or (i > 0 and name == platform):
                continue
            seen.add(str(name))
            links.append(link)
        last = str(attach.find("parent").get("link"))  # type: ignore[union-attr]
        place = _BASE.urdf_origin(attach)
        for joint in src.findall("joint"):
            if i > 0 and joint is attach:
                continue
            child = joint.find("child").get("link")  # type: ignore[union-attr]
            if i > 0 and child in below:  # a frame on the platform: hung on this limb's last link
                j = _BASE._fixed(
                    str(joint.get("name")), last, str(child), **_origin_of(place * _BASE.urdf_origin(joint))
                )
                joints.append(j)
                continue
            joints.append(joint)
        if i > 0:
            b = f"closedloop{i}_B"
            links.append(ET.Element("link", name=b))
            joints.append(_BASE._fixed(f"{b}_joint", last, b, **_origin_of(place)))
            loops.append((platform, b))
            types.append("6d")
        motors += [limb.joint_names[k] for k in limb.actuated]
        home.update({n: float(v) for n, v in zip(limb.joint_names, limb.home, strict=True) if v != 0.0})
        inner += [(lp.frame_names, lp.kind) for lp in limb.loops]
    loops += [pair for pair, _ in inner]
    types += [kind for _, kind in inner]
    for el in links + joints:
        robot.append(el)
    ET.indent(robot, space="  ")
    urdf = '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
    yaml = (
        f"closed_loop: {[list(p) for p in loops]}\ntype: {types}\nname_mot: {motors}\n"
        "joint_name: []\njoint_type: []\n"
    )
    tv = _BASE.toml_value
    lines = [
        f"# {mech.name} written the way Gepetto/example-parallel-robots writes a closed-loop robot: one URDF",
        "# tree (robot.urdf) and its sidecar (robot.yaml); loops close between the rods",
        "# (docs/closed-loop.md).",
        f"# Generated from {folder.name}/ by scripts/limbs_to_epr.py; do not edit.",
        f"name = {tv(mech.name + '_epr')}",
        f"description = {tv(doc.get('description', '') + ' (example-parallel-robots form)')}",
        "",
        "[closed_loop]",
        'urdf = "robot.urdf"',
        'sidecar = "robot.yaml"',
        f"platform_link = {tv(platform)}",
        f"limbs = {tv([lb.name for lb in mech.limbs])}",
        "",
        "[closed_loop.home]  # joint values [rad or m] where every loop closes; others are 0",
    ]
    lines += [f"{name} = {value!r}" for name, value in home.items()]
    for table in ("reference_point", "task", "task_space", "design", "cost", "calibration"):
        if table in doc:
            lines += ["", f"[{table}]"]
            lines += [f"{k} = {tv(v)}" for k, v in doc[table].items() if not isinstance(v, dict)]
    return {"robot.urdf": urdf, "robot.yaml": yaml, "mechanism.toml": "\n".join(lines) + "\n"}


def main(argv: list[str] | None = None) -> int:
    return _BASE.write_or_check(
        argv, __doc__, generate, "robot.urdf, robot.yaml and mechanism.toml", "limbs_to_epr.py"
    )


if __name__ == "__main__":
    sys.exit(main())
