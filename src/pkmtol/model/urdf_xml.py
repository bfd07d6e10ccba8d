"""What pkmtol asks of a URDF's XML before Pinocchio reads it: numbers, unit axes, no mimic, a tree.

Pinocchio (through urdfdom) silently normalises a joint axis such as ``0 0 5``, keeps a zero axis
as a joint that does not move, ignores ``<mimic>`` and reports most other faults only on stderr.
:func:`check_urdf_tree` refuses each of these with a :class:`~pkmtol.exceptions.URDFError` that
names the joint or link; :func:`fill_missing_limits` reads a revolute or continuous joint
without ``lower``/``upper`` (urdfdom: [0, 0]) as ±π with a
:class:`~pkmtol.exceptions.MissingLimitWarning` and refuses such a prismatic joint
(:class:`~pkmtol.exceptions.MissingLimitError`); :func:`resolve_meshes` finds the mesh files
the visuals name and drops (with a :class:`~pkmtol.exceptions.MissingMeshWarning`) the visuals
whose mesh does not exist.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from pkmtol.exceptions import MissingLimitError, MissingLimitWarning, MissingMeshWarning, URDFError
from pkmtol.values import MAX_LENGTH_M

#: Joint types of the URDF format (pkmtol's limbs take revolute and prismatic; see make_limb).
URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: A joint axis must have this length to within this tolerance.
AXIS_TOLERANCE = 1e-6

_Fail = Callable[[str], NoReturn]


def fill_missing_limits(root: ET.Element, limb: str, path: Path | None) -> bool:
    """Give every revolute or continuous joint of ``root`` without a range the range [−π, π], in place.

    A missing ``lower`` becomes −π and a missing ``upper`` +π (urdfdom would read both as 0, a joint
    that cannot move); a continuous joint becomes revolute over [−π, π] (pkmtol's limbs take bounded
    joints). Each joint so read gets a :class:`~pkmtol.exceptions.MissingLimitWarning`. A missing
    ``effort``/``velocity`` of a ``<limit>`` written here is set to 0 (pkmtol does not use them).

    Returns:
        Whether ``root`` was changed.

    Raises:
        MissingLimitError: a prismatic joint without ``lower`` or ``upper`` (no stroke can be assumed).
    """
    changed = False
    for joint in root.findall("joint"):
        jtype, name = joint.get("type"), str(joint.get("name", ""))
        limit = joint.find("limit")
        if jtype == "prismatic":
            if limit is None or limit.get("lower") is None or limit.get("upper") is None:
                raise MissingLimitError(limb, path, name)
            continue
        if jtype not in ("revolute", "continuous"):
            continue
        continuous = jtype == "continuous"
        if not continuous and limit is not None and None not in (limit.get("lower"), limit.get("upper")):
            continue
        if limit is None:
            limit = ET.SubElement(joint, "limit")
        if continuous:
            limit.attrib.pop("lower", None)
            limit.attrib.pop("upper", None)
            joint.set("type", "revolute")
        limit.set("lower", limit.get("lower", repr(-math.pi)))
        limit.set("upper", limit.get("upper", repr(math.pi)))
        for attr in ("effort", "velocity"):
            limit.set(attr, limit.get(attr, "0"))
        lo, hi = (_float_or_nan(limit.get(a, "")) for a in ("lower", "upper"))
        warnings.warn(MissingLimitWarning(limb, path, name, lo, hi, continuous), stacklevel=4)
        changed = True
    return changed


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def check_urdf_tree(root: ET.Element, limb: str, path: Path | None) -> None:
    """Raise URDFError naming the culprit unless ``root`` is a URDF tree pkmtol can read.

    Checked: the ``<robot>`` root; unique link and joint names; every joint's type, parent and
    child links; finite ``origin`` and ``axis`` numbers; unit axes; ``lower ≤ upper`` limits on
    revolute and prismatic joints; no ``<mimic>``; links forming one tree (no link with two
    parents, no loop, one root).
    """

    def fail(problem: str) -> NoReturn:
        raise URDFError(limb, path, problem)

    if root.tag != "robot":
        fail(f"the root element is <{root.tag}>, not <robot>: not a URDF")
    links: list[str] = []
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            fail("a <link> has no name")
        if name in links:
            fail(f"link '{name}' is defined twice; link names must be unique")
        links.append(str(name))
        _check_geometry(link, str(name), fail)
    parent_of: dict[str, tuple[str, str]] = {}
    joints: set[str] = set()
    for joint in root.findall("joint"):
        jname = joint.get("name")
        if not jname:
            fail("a <joint> has no name")
        if jname in joints:
            fail(f"joint '{jname}' is defined twice; joint names must be unique")
        joints.add(str(jname))
        _check_joint(joint, str(jname), links, fail)
        parent = str(joint.find("parent").get("link"))  # type: ignore[union-attr]
        child = str(joint.find("child").get("link"))  # type: ignore[union-attr]
        if child in parent_of:
            fail(
                f"link '{child}' is the child of two joints ('{parent_of[child][0]}' and '{jname}'): "
                "a kinematic loop; a limb URDF is a serial chain (write each chain of a loop as a limb "
                "in mechanism.toml, or use a closed-loop tree with closure frames, docs/closed-loop.md)"
            )
        parent_of[child] = (str(jname), parent)
    _check_connected(links, parent_of, fail)


def _check_joint(joint: ET.Element, name: str, links: Sequence[str], fail: _Fail) -> None:
    def bad(problem: str) -> NoReturn:
        fail(f"joint '{name}': {problem}")

    jtype = joint.get("type")
    if jtype not in URDF_JOINT_TYPES:
        bad(f"unknown type {jtype!r}; URDF joint types are {', '.join(URDF_JOINT_TYPES)}")
    for tag in ("parent", "child"):
        el = joint.find(tag)
        link = None if el is None else el.get("link")
        if not link:
            bad(f"no <{tag} link=...>")
        elif link not in links:
            bad(f"its {tag} link '{link}' is not a <link> of the file")
    if joint.find("parent").get("link") == joint.find("child").get("link"):  # type: ignore[union-attr]
        bad("its parent and child are the same link: a kinematic loop")
    origin = joint.find("origin")
    if origin is not None:
        for attr in ("xyz", "rpy"):
            xyz = _numbers(origin.get(attr, "0 0 0"), 3, f"origin {attr}", bad)
            if attr == "xyz" and max(abs(v) for v in xyz) > MAX_LENGTH_M:
                bad(f"origin xyz = {origin.get(attr)!r}: beyond ±{MAX_LENGTH_M:g} m; is the unit right (m)?")
    if joint.find("mimic") is not None:
        bad(
            f"mimics joint '{joint.find('mimic').get('joint')}' (<mimic>); pkmtol has no coupled "  # type: ignore[union-attr]
            "joints: remove the <mimic> element and make the joint independent, or fixed"
        )
    axis_el = joint.find("axis")
    if axis_el is not None and jtype not in ("fixed", "floating"):
        axis = _numbers(axis_el.get("xyz", "1 0 0"), 3, "axis xyz", bad)
        norm = math.sqrt(sum(a * a for a in axis))
        if norm == 0.0:
            bad("its axis is (0 0 0): a joint needs a direction; write a unit vector such as '0 0 1'")
        if abs(norm - 1.0) > AXIS_TOLERANCE:
            unit = " ".join(f"{a / norm:.12g}" for a in axis)
            bad(f"its axis has length {norm:.6g}, not 1; write the unit vector '{unit}'")
    if jtype in ("revolute", "prismatic"):
        limit = joint.find("limit")
        if limit is None:
            bad(f"a {jtype} joint needs <limit lower=... upper=... effort=... velocity=...> (rad or m)")
        else:
            lo = _numbers(limit.get("lower", "0"), 1, "limit lower", bad)[0]
            hi = _numbers(limit.get("upper", "0"), 1, "limit upper", bad)[0]
            for attr in ("effort", "velocity"):
                if limit.get(attr) is not None:
                    _numbers(str(limit.get(attr)), 1, f"limit {attr}", bad)
            if lo > hi:
                bad(f"its limits are reversed (lower {lo:g} > upper {hi:g})")


#: Per geometry element: its size attributes and how many numbers each holds.
GEOMETRY_SIZES = {
    "box": (("size", 3),),
    "cylinder": (("radius", 1), ("length", 1)),
    "sphere": (("radius", 1),),
}


def _check_geometry(link: ET.Element, name: str, fail: _Fail) -> None:
    """Refuse a visual or collision of ``link`` whose origin, size or mesh scale is not finite (≥ 0)."""

    def bad(problem: str) -> NoReturn:
        fail(f"link '{name}': {problem}; fix the numbers of its <visual>/<collision>")

    for tag in ("visual", "collision"):
        for item in link.findall(tag):
            origin = item.find("origin")
            for attr in ("xyz", "rpy"):
                if origin is not None and origin.get(attr) is not None:
                    _numbers(str(origin.get(attr)), 3, f"<{tag}> origin {attr}", bad)
            geometry = item.find("geometry")
            for shape in [] if geometry is None else list(geometry):
                sizes = [
                    *GEOMETRY_SIZES.get(shape.tag, ()),
                    *((("scale", 3),) if shape.tag == "mesh" else ()),
                ]
                for attr, n in sizes:
                    text = shape.get(attr)
                    if text is None and attr == "scale":
                        continue
                    numbers = _numbers(str(text or ""), n, f"<{tag}> <{shape.tag}> {attr}", bad)
                    if any(v < 0 for v in numbers):
                        bad(f"<{tag}> <{shape.tag}> {attr} = {text!r}: expected numbers ≥ 0")


def _numbers(text: str, n: int, what: str, bad: _Fail) -> list[float]:
    parts = text.split()
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        bad(f"{what} = {text!r}: expected {n} finite number{'s' if n > 1 else ''}")
    return values


def _check_connected(links: Sequence[str], parent_of: dict[str, tuple[str, str]], fail: _Fail) -> None:
    roots = [name for name in links if name not in parent_of]
    if not links:
        fail("the URDF has no <link>")
    if not roots:
        fail("every link is the child of a joint: the joints form a kinematic loop")
    if len(roots) > 1:
        fail(
            f"{len(roots)} root links ({', '.join(roots[:5])}): the links are not connected into one "
            "tree; connect them with joints or remove the stray links"
        )
    children: dict[str, list[str]] = {}
    for child, (_, parent) in parent_of.items():
        children.setdefault(parent, []).append(child)
    seen, todo = set(), [roots[0]]
    while todo:
        link = todo.pop()
        seen.add(link)
        todo.extend(children.get(link, []))
    loop = [parent_of[name][0] for name in links if name not in seen]
    if loop:
        fail(
            f"joints {', '.join(sorted(loop)[:6])} form a kinematic loop not connected to the root link "
            f"'{roots[0]}'; a limb URDF is a serial chain"
        )


def resolve_meshes(root: ET.Element, limb: str, path: Path) -> ET.Element:
    """A copy of ``root`` whose mesh file names are absolute paths; visuals with a missing mesh dropped.

    A relative name is looked up beside the URDF; ``package://<pkg>/<file>`` in the URDF's folder
    and its parent (as ``<pkg>/<file>``) and beside the URDF (as ``<file>``); ``file://`` as given.
    Each missing mesh is reported by a :class:`~pkmtol.exceptions.MissingMeshWarning`.
    """
    out = ET.fromstring(ET.tostring(root))
    for link in out.findall("link"):
        for tag in ("visual", "collision"):
            for vis in list(link.findall(tag)):
                for mesh in vis.iter("mesh"):
                    name = mesh.get("filename", "")
                    found = _find_mesh(name, path.parent)
                    if found is None:
                        if tag == "visual":
                            warnings.warn(MissingMeshWarning(limb, path, name), stacklevel=4)
                        link.remove(vis)
                        break
                    mesh.set("filename", str(found))
    return out


def _find_mesh(name: str, folder: Path) -> Path | None:
    if name.startswith("package://"):
        rest = name[len("package://") :]
        pkg_file = rest.split("/", 1)
        candidates = [folder / rest, folder.parent / rest]
        if len(pkg_file) == 2:
            candidates.append(folder / pkg_file[1])
    elif name.startswith("file://"):
        candidates = [Path(name[len("file://") :])]
    else:
        candidates = [folder / name]
    for c in candidates:
        if name and c.is_file():
            return c.resolve()
    return None
