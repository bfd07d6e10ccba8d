"""Write (or check) a limb-folder robot as ONE MJCF file whose loops are closed by ``<weld>``/``<connect>``.

The output is what ``pkmtol.model.mjcf`` reads (docs/closed-loop.md, "MJCF"): the limbs' URDFs
nested as MJCF bodies under one jointless ``base`` body (Pinocchio's MJCF reader keeps only the
first body under ``<worldbody>``); every URDF joint becomes a body at the joint origin holding one
``hinge`` or ``slide`` joint along the URDF axis, with the URDF limits as ``range``; the URDF
visuals become geoms (their mass comes from MuJoCo's default density, 1000 kg/m³). Limb 1 keeps the
platform body; every other limb k+1 ends in a site ``closedloop<k>_B`` at its last joint, and the
platform carries the partner site ``closedloop<k>_A`` placed where that joint sits when the loop is
closed (the same frames as ``scripts/limbs_to_closed_loop.py`` writes); a ``<weld>`` named
``closedloop<k>`` makes the two sites coincide. A limb's internal loops (``[[limbs.loops]]``) become
a ``<weld>`` (6d) or ``<connect>`` (3d) named ``<limb>_<loop>`` between sites at their frames (the
limb's other fixed links). ``<motor>`` actuators name the actuated joints, and
the keyframe ``home`` holds the limbs' home joint values. The ``mechanism.toml`` beside it holds
pkmtol's own keys and the ``[mjcf]`` table.

Usage:
    python scripts/limbs_to_mjcf.py ROBOT OUT          # write robot.xml and mechanism.toml
    python scripts/limbs_to_mjcf.py ROBOT OUT --check  # exit 1 if OUT differs
"""

from __future__ import annotations

import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))
from limbs_to_closed_loop import toml_value, urdf_origin, write_or_check  # noqa: E402

from pkmtol.model.loader import load_mechanism  # noqa: E402

MJCF_NAME = "robot.xml"


def _num(x: float) -> str:
    return "0" if abs(x) < 5e-16 else repr(float(x))


def _vec(v: np.ndarray) -> str:
    return " ".join(_num(float(x)) for x in v)


def _pose(el: ET.Element, placement: pin.SE3) -> None:
    """Set ``pos`` and ``quat`` (w x y z) of an MJCF element; identity parts are left out."""
    if np.any(np.abs(placement.translation) >= 5e-16):
        el.set("pos", _vec(placement.translation))
    q = pin.Quaternion(placement.rotation).coeffs()  # x y z w
    wxyz = np.array([q[3], q[0], q[1], q[2]])
    if wxyz[0] < 0:
        wxyz = -wxyz
    if not np.allclose(wxyz, [1, 0, 0, 0], rtol=0, atol=5e-16):
        el.set("quat", _vec(wxyz))


def _geoms(body: ET.Element, link: ET.Element, source: Path) -> None:
    """The link's URDF visuals as MJCF geoms (sphere, cylinder, box)."""
    for vis in link.findall("visual"):
        geom = vis.find("geometry")
        shape = None if geom is None else next(iter(geom), None)
        if shape is None:
            continue
        g = ET.SubElement(body, "geom", name=f"{link.get('name')}_visual")
        if shape.tag == "sphere":
            g.set("type", "sphere")
            g.set("size", _num(float(shape.get("radius", "0"))))
        elif shape.tag == "cylinder":
            g.set("type", "cylinder")
            g.set(
                "size", f"{_num(float(shape.get('radius', '0')))} {_num(float(shape.get('length', '0')) / 2)}"
            )
        elif shape.tag == "box":
            half = np.array([float(x) for x in shape.get("size", "0 0 0").split()]) / 2
            g.set("type", "box")
            g.set("size", _vec(half))
        else:
            raise SystemExit(
                f"{source}: link '{link.get('name')}': a {shape.tag} visual has no MJCF counterpart here"
            )
        _pose(g, urdf_origin(vis))
        colour = vis.find("material/color")
        if colour is not None:
            g.set("rgba", colour.get("rgba", "0.5 0.5 0.5 1"))


def mjcf(folder: Path) -> tuple[str, list[str]]:
    """The MJCF text of the limb-folder robot in ``folder`` and its limb names."""
    mech = load_mechanism(folder)
    doc = tomllib.loads((folder / "mechanism.toml").read_text(encoding="utf-8"))
    platform = doc.get("platform_link", "platform")
    root = ET.Element("mujoco", model=f"{mech.name}_mjcf")
    root.append(ET.Comment(f" generated from {folder.name}/ by scripts/limbs_to_mjcf.py; do not edit "))
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    world = ET.SubElement(root, "worldbody")
    base = ET.SubElement(world, "body", name=str(doc.get("base_link", "base")))
    equality = ET.Element("equality")
    actuator = ET.Element("actuator")
    platform_body: ET.Element | None = None
    closures: list[tuple[str, pin.SE3]] = []  # (site on the platform, its placement there)
    loops_inner: list[ET.Element] = []
    for i, limb in enumerate(mech.limbs):
        assert limb.urdf_path is not None
        src = ET.parse(limb.urdf_path).getroot()
        links = {lk.get("name"): lk for lk in src.findall("link")}
        bodies: dict[str, ET.Element] = {str(src.find("link").get("name")): base}  # type: ignore[union-attr]
        for joint in src.findall("joint"):
            child = str(joint.find("child").get("link"))  # type: ignore[union-attr]
            up = str(joint.find("parent").get("link"))  # type: ignore[union-attr]
            parent = platform_body if up == platform and platform_body is not None else bodies[up]
            kind = joint.get("type")
            if kind == "fixed" and child != platform:
                # another fixed link (a loop's frame): a site on its parent body
                if any(j.find("parent").get("link") == child for j in src.findall("joint")):  # type: ignore[union-attr]
                    raise SystemExit(f"{limb.urdf_path}: fixed link '{child}' has children; not written")
                _pose(ET.SubElement(parent, "site", name=child), urdf_origin(joint))
                continue
            if kind == "fixed":
                attach = urdf_origin(joint)
                if i == 0:
                    platform_body = ET.SubElement(parent, "body", name=platform)
                    _pose(platform_body, attach)
                    _geoms(platform_body, links[platform], limb.urdf_path)
                else:
                    # the closure sits at the limb's last joint, axes parallel to the platform's:
                    # B keeps the attachment's rotation, A is a pure translation on the platform
                    b = ET.SubElement(parent, "site", name=f"closedloop{i}_B")
                    _pose(b, pin.SE3(attach.rotation, np.zeros(3)))
                    closures.append(
                        (f"closedloop{i}_A", pin.SE3(np.eye(3), -attach.rotation.T @ attach.translation))
                    )
                    ET.SubElement(
                        equality,
                        "weld",
                        name=f"closedloop{i}",
                        site1=f"closedloop{i}_A",
                        site2=f"closedloop{i}_B",
                    )
                continue
            body = ET.SubElement(parent, "body", name=child)
            _pose(body, urdf_origin(joint))
            axis = joint.find("axis")
            limit = joint.find("limit")
            j = ET.SubElement(
                body,
                "joint",
                name=str(joint.get("name")),
                type={"revolute": "hinge", "prismatic": "slide"}[str(kind)],
                axis="0 0 1" if axis is None else axis.get("xyz", "0 0 1"),
            )
            if limit is not None:
                j.set(
                    "range", f"{_num(float(limit.get('lower', '0')))} {_num(float(limit.get('upper', '0')))}"
                )
            _geoms(body, links[child], limb.urdf_path)
            bodies[child] = body
        for lp in limb.loops:  # internal loops: a <weld> (6d) or a <connect> (3d) between their sites
            tag = "weld" if lp.kind == "6d" else "connect"
            a, b = lp.frame_names
            loops_inner.append(ET.Element(tag, name=f"{limb.name}_{lp.name}", site1=a, site2=b))
        for k in limb.actuated:
            ET.SubElement(actuator, "motor", name=limb.joint_names[k], joint=limb.joint_names[k])
    assert platform_body is not None
    for name, placement in closures:
        _pose(ET.SubElement(platform_body, "site", name=name), placement)
    for el in loops_inner:
        equality.append(el)
    root.append(equality)
    root.append(actuator)
    keyframe = ET.SubElement(root, "keyframe")
    home = np.concatenate([lb.home for lb in mech.limbs])
    ET.SubElement(keyframe, "key", name="home", qpos=_vec(home))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n", [lb.name for lb in mech.limbs]


def generate(folder: Path) -> dict[str, str]:
    """File name → text of the MJCF form of the robot in ``folder``."""
    text, limbs = mjcf(folder)
    doc = tomllib.loads((folder / "mechanism.toml").read_text(encoding="utf-8"))
    name = doc["name"]
    lines = [
        f"# {name} written as one MJCF file ({MJCF_NAME}) whose loops are closed by <weld> equalities;",
        f"# generated from {folder.name}/ by scripts/limbs_to_mjcf.py; do not edit.",
        f"name = {toml_value(name + '_mjcf')}",
        f"description = {toml_value(doc.get('description', ''))}",
        "",
        "[mjcf]",
        f"file = {toml_value(MJCF_NAME)}",
        f"limbs = {toml_value(limbs)}",
        'keyframe = "home"   # joint values where every loop closes: the MJCF keyframe of that name',
    ]
    for table in ("reference_point", "task", "task_space", "design", "cost"):
        if table in doc:
            lines += ["", f"[{table}]"]
            lines += [f"{k} = {toml_value(v)}" for k, v in doc[table].items() if not isinstance(v, dict)]
    return {MJCF_NAME: text, "mechanism.toml": "\n".join(lines) + "\n"}


def main(argv: list[str] | None = None) -> int:
    return write_or_check(argv, __doc__, generate, f"{MJCF_NAME} and mechanism.toml", "limbs_to_mjcf.py")


if __name__ == "__main__":
    sys.exit(main())
