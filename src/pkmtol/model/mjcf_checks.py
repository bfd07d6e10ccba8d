"""Checks of an MJCF file against what Pinocchio's MJCF reader would lose or misread, naming the culprit.

Pinocchio 4.1's ``buildModelAndConstraintsFromMJCF`` keeps only the first ``<body>`` under
``<worldbody>``, skips ``<include>`` and ``<frame>`` contents, merges the joints of one body into a
composite joint, ignores tendons and every ``<equality>`` kind but ``connect`` and ``weld``, and
reads a weld's explicit ``relpose`` (and a body connect's ``anchor``) relative to the joint frame
instead of the body frame. Each
check here turns one of those into a :class:`~pkmtol.exceptions.MJCFError` (or a subclass) that
says what would go wrong and how to write the file instead (docs/closed-loop.md, "MJCF").
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import (
    LostElementError,
    MJCFError,
    MultiDofJointError,
    TendonError,
    UnsupportedEqualityError,
)

#: ``<actuator>`` children (MuJoCo's actuator shortcuts and ``general``).
ACTUATOR_TAGS = (
    "general",
    "motor",
    "position",
    "velocity",
    "intvelocity",
    "damper",
    "cylinder",
    "muscle",
    "adhesion",
    "plugin",
)
#: Actuator transmissions that are not a joint.
NON_JOINT_TRANSMISSIONS = ("site", "body", "cranksite", "slidersite", "refsite")


@dataclass(frozen=True)
class WeldSpec:
    """One ``<weld>`` of the file, as written.

    Attributes:
        name: The weld's ``name``, or ``closedloop<k>`` (k = its 1-based position among the welds).
        body1: ``body1`` (None when the weld is given by sites).
        body2: ``body2`` (None: the world, or given by sites).
        site1: ``site1`` (None when given by bodies).
        site2: ``site2``.
        relpose: Whether an explicit ``relpose`` is given (else the relative pose at ``qpos0``), or,
            for a ``<connect>`` between bodies, its ``anchor`` (read on body1's joint frame too).
        kind: ``"6d"`` for a ``<weld>``, ``"3d"`` for a ``<connect>`` (a point loop).
    """

    name: str
    body1: str | None
    body2: str | None
    site1: str | None
    site2: str | None
    relpose: bool
    kind: str = "6d"

    @property
    def side1(self) -> str:
        """The body or site named first (for messages)."""
        return str(self.site1 or self.body1)

    @property
    def side2(self) -> str:
        """The body or site named second (``world`` when none)."""
        return str(self.site2 or self.body2 or "world")


def read_xml(path: Path) -> ET.Element:
    """The ``<mujoco>`` root of an MJCF file.

    Raises:
        MJCFError: missing, malformed, or not an MJCF file.
    """
    if not path.is_file():
        raise MJCFError(path, "-", "file not found; check the 'file' entry of the [mjcf] table")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise MJCFError(path, "-", f"malformed XML: {err}") from err
    if root.tag != "mujoco":
        raise MJCFError(path, root.tag, "the root element must be <mujoco> (this is not an MJCF file)")
    if root.get("model") is None:
        raise MJCFError(
            path, "mujoco", "the <mujoco> element needs a model name (Pinocchio refuses it otherwise)"
        )
    return root


def check_structure(path: Path, root: ET.Element) -> None:
    """Refuse what Pinocchio would drop before it reads the file (includes, extra top-level bodies).

    Raises:
        LostElementError: an ``<include>``; more than one body (or a ``<frame>`` with bodies) directly
            under ``<worldbody>``; no body at all.
    """
    for inc in root.iter("include"):
        raise LostElementError(
            path,
            "include",
            [str(inc.get("file"))],
            f"<include file='{inc.get('file')}'>: Pinocchio's MJCF reader does not follow includes, so the "
            "bodies and joints of that file would be lost; paste its content in place",
        )
    world = root.find("worldbody")
    tops = [] if world is None else [el for el in world if el.tag in ("body", "frame", "replicate")]
    if not tops or tops[0].tag != "body":
        raise MJCFError(
            path,
            "worldbody",
            "<worldbody> must start with one body, the fixed base, that holds every limb "
            "(<worldbody><body name='base'> ... </body></worldbody>)",
        )
    dropped = tops[1:]
    if dropped:
        lost = [_label(el) for d in dropped for el in d.iter() if el.tag in ("body", "joint", "freejoint")]
        raise LostElementError(
            path,
            _label(dropped[0]),
            lost,
            f"Pinocchio's MJCF reader keeps only the first body under <worldbody> ('{_label(tops[0])}') and "
            f"drops the rest ({', '.join(lost)}); put every limb inside one jointless base body: "
            "<worldbody><body name='base'> ...all limbs... </body></worldbody>",
        )
    _check_geoms(path, root)


def check_model(path: Path, root: ET.Element, model: pin.Model) -> None:
    """Compare Pinocchio's model with the file: lost bodies or joints, multi-DOF joints, a moving base.

    Raises:
        LostElementError: a body or joint of the file is not in the model.
        MultiDofJointError: a body with several joints (a composite joint), a ball or free joint.
        MJCFError: the first body (the base) has a joint.
    """
    world = root.find("worldbody")
    assert world is not None
    bodies = [el for el in world.iter("body")]
    frames = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
    lost = [el for el in bodies if el.get("name") is not None and el.get("name") not in frames]
    n_bodies = sum(1 for f in model.frames if f.type == pin.FrameType.BODY)
    if lost or n_bodies != len(bodies):
        names = [_label(el) for b in lost for el in b.iter() if el.tag in ("body", "joint", "freejoint")]
        raise LostElementError(
            path,
            names[0] if names else "body",
            names,
            f"Pinocchio's model has {n_bodies} of the file's {len(bodies)} bodies"
            + (f" (lost: {', '.join(names)})" if names else "")
            + "; write every body as a plain nested <body> under the base body (not inside <frame>, "
            "<replicate> or <attach>)",
        )
    for body in bodies:
        joints = [el for el in body if el.tag in ("joint", "freejoint")]
        if len(joints) > 1:
            raise MultiDofJointError(
                path,
                _label(body),
                f"body '{_label(body)}' holds {len(joints)} joints ({', '.join(_label(j) for j in joints)}): "
                "Pinocchio merges them into one composite joint and pkmtol takes 1-DOF joints only; "
                "give each joint its own body (nested bodies at the same place, without geoms)",
            )
        if joints and joints[0].tag == "freejoint":
            raise MultiDofJointError(
                path, _label(joints[0]), "a free joint: the base of a parallel mechanism is fixed; remove it"
            )
    known = set(model.names[1:])
    missing = [
        _label(j) for j in world.iter("joint") if j.get("name") is not None and j.get("name") not in known
    ]
    if missing:
        raise LostElementError(
            path, missing[0], missing, f"joint(s) {', '.join(missing)} are not in Pinocchio's model"
        )
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq != 1 or jm.nv != 1:
            raise MultiDofJointError(
                path,
                model.names[j],
                f"joint '{model.names[j]}' is a {jm.shortname()} ({jm.nv} DOF); pkmtol takes 1-DOF hinge "
                "and slide joints only: write a ball joint as three hinges in three nested bodies",
            )
    base = next(f for f in model.frames if f.type == pin.FrameType.BODY)
    if base.parentJoint != 0:
        raise MJCFError(
            path,
            _label(bodies[0]),
            f"the first body under <worldbody> ('{_label(bodies[0])}') moves: it must be the fixed base of "
            "the mechanism (no joint); put the limbs' first bodies inside a jointless base body",
        )


def check_tendons(path: Path, root: ET.Element) -> None:
    """Refuse tendons (Pinocchio ignores them; pkmtol's mechanisms are rigid links and joints).

    Raises:
        TendonError: a ``<tendon>`` element with content.
    """
    for tendon in root.iter("tendon"):
        for el in tendon:
            raise TendonError(
                path,
                _label(el),
                f"tendon '{_label(el)}' ({el.tag}): Pinocchio's MJCF reader ignores tendons and pkmtol "
                "models rigid links and joints only; remove the tendon (and what refers to it)",
            )


def welds(path: Path, root: ET.Element) -> list[WeldSpec]:
    """The ``<weld>`` (6D) and ``<connect>`` (3D) loops of the file, in order; other equalities are refused.

    Raises:
        UnsupportedEqualityError: another kind (``joint``, ``tendon``, ``distance``, ``flex`` ...), an
            inactive equality, a weld with both sites and bodies, or two welds between the same pair.
        MJCFError: a weld without ``body1`` or ``site1``.
    """
    out: list[WeldSpec] = []
    for eq in [el for block in root.findall("equality") for el in block]:
        label = eq.get("name") or f"{eq.tag} #{len(out) + 1}"
        if eq.tag not in ("weld", "connect"):
            raise UnsupportedEqualityError(
                path,
                label,
                f"<equality><{eq.tag}>: pkmtol turns <weld> (6D) and <connect> (3D) equalities into loops; a "
                f"{eq.tag} constraint has no counterpart in a mechanism of rigid links and joints: remove it",
            )
        if eq.get("active", "true") != "true":
            raise UnsupportedEqualityError(
                path, label, "an inactive weld: a loop is always closed; remove it or set active='true'"
            )
        sites = eq.get("site1") is not None or eq.get("site2") is not None
        bodies = eq.get("body1") is not None or eq.get("body2") is not None
        if sites and (bodies or eq.get("relpose") is not None or eq.get("anchor") is not None):
            raise UnsupportedEqualityError(
                path,
                label,
                "a weld given by sites must not also give bodies, relpose or anchor: the two sites' frames "
                "are what coincides",
            )
        if sites and (eq.get("site1") is None or eq.get("site2") is None):
            raise MJCFError(path, label, f"a {eq.tag} given by sites needs both site1 and site2")
        if not sites and eq.get("body1") is None:
            raise MJCFError(
                path, label, f"a {eq.tag} needs body1 (and body2, the other side of the loop) or two sites"
            )
        relpose = eq.get("relpose")
        explicit = eq.tag == "connect" and not sites  # the anchor is read on body1's joint frame
        if relpose is not None:
            try:
                values = np.array([float(x) for x in relpose.split()])
            except ValueError:
                values = np.zeros(0)
            if values.shape != (7,):
                raise MJCFError(
                    path, label, f"relpose '{relpose}': expected 7 numbers (pos x y z, quat w x y z)"
                )
            explicit = bool(np.any(values[3:] != 0))  # MuJoCo: an all-zero quaternion means "from qpos0"
        out.append(
            WeldSpec(
                name=eq.get("name") or f"closedloop{len(out) + 1}",
                body1=eq.get("body1"),
                body2=eq.get("body2"),
                site1=eq.get("site1"),
                site2=eq.get("site2"),
                relpose=explicit,
                kind="3d" if eq.tag == "connect" else "6d",
            )
        )
    seen: dict[tuple[str, str], str] = {}
    for w in out:
        pair = (w.side1, w.side2)
        key = (min(pair), max(pair))
        if key in seen:
            raise UnsupportedEqualityError(
                path,
                w.name,
                f"weld '{w.name}' joins what weld '{seen[key]}' already joins: one loop written twice",
            )
        seen[key] = w.name
    names = [w.name for w in out]
    for n in names:
        if names.count(n) > 1:
            raise UnsupportedEqualityError(path, n, f"two welds are named '{n}'; give each loop its own name")
    return out


def actuated_joints(path: Path, root: ET.Element) -> list[str]:
    """The joints driven by ``<actuator>`` elements, in file order, each once.

    Raises:
        TendonError: an actuator on a tendon.
        MJCFError: an actuator whose transmission is not a joint (site, body, slider-crank).
    """
    out: list[str] = []
    for block in root.findall("actuator"):
        for act in block:
            if act.tag not in ACTUATOR_TAGS:
                continue
            label = act.get("name") or f"{act.tag} #{len(out) + 1}"
            if act.get("tendon") is not None:
                raise TendonError(
                    path,
                    label,
                    f"actuator '{label}' drives tendon '{act.get('tendon')}'; drive a joint instead",
                )
            joint = act.get("joint") or act.get("jointinparent")
            if joint is None:
                kind = next((t for t in NON_JOINT_TRANSMISSIONS if act.get(t) is not None), "no transmission")
                raise MJCFError(
                    path,
                    label,
                    f"actuator '{label}' acts through {kind}; pkmtol's actuators are joints: "
                    "give joint='...'",
                )
            if joint not in out:
                out.append(joint)
    return out


def check_relpose(path: Path, spec: WeldSpec, model: pin.Model) -> None:
    """Refuse an explicit ``relpose`` on a body whose frame is not its joint's frame.

    Pinocchio 4.1 applies ``relpose`` (and the weld ``anchor`` that goes with it) to the joint frames
    of body1 and body2, MuJoCo to the body frames: they agree only when both bodies sit at their
    joint's origin. Without ``relpose`` (the relative pose at ``qpos0``) they always agree.

    Raises:
        UnsupportedEqualityError: the weld gives ``relpose`` and one body's frame is off its joint.
    """
    if not spec.relpose:
        return
    for body in (spec.body1, spec.body2):
        if body is None:
            continue
        frame = model.frames[model.getFrameId(body, pin.FrameType.BODY)]
        if not frame.placement.isIdentity(1e-12):
            what = "gives relpose" if spec.kind == "6d" else "is anchored on bodies"
            raise UnsupportedEqualityError(
                path,
                spec.name,
                f"{'weld' if spec.kind == '6d' else 'connect'} '{spec.name}' {what}, and body '{body}' does "
                "not sit at its joint's origin (a body without a joint of its own, or a joint with pos): "
                "Pinocchio 4.1 would apply it to the joint frame, not to the body; write the loop with two "
                "sites (site1, site2) that coincide when it is closed"
                + (", or leave relpose out so that the loop closes at qpos0" if spec.kind == "6d" else ""),
            )


def frame_of(path: Path, model: pin.Model, spec: WeldSpec, side: int) -> int:
    """Frame id of side 1 or 2 of a weld: the site, the body, or the world (frame 0).

    Raises:
        LostElementError: the body or site is not in Pinocchio's model.
    """
    site, body = (spec.site1, spec.body1) if side == 1 else (spec.site2, spec.body2)
    if site is None and body is None:
        return 0
    name = str(site or body)
    kind = pin.FrameType.OP_FRAME if site is not None else pin.FrameType.BODY
    if not model.existFrame(name, kind):
        what = "site" if site is not None else "body"
        raise LostElementError(
            path,
            name,
            [name],
            f"weld '{spec.name}' names {what} '{name}', which is not in Pinocchio's model "
            f"({what}s: {', '.join(_names(model, kind))})",
        )
    return int(model.getFrameId(name, kind))


def _names(model: pin.Model, kind: pin.FrameType) -> Sequence[str]:
    return [f.name for f in model.frames if f.type == kind]


def _label(el: ET.Element) -> str:
    return str(el.get("name") or f"<{el.tag}> without a name")


#: The ``<geom>`` attributes that hold numbers (a size must be ≥ 0).
GEOM_NUMBERS = ("size", "pos", "quat", "euler", "axisangle", "fromto", "xyaxes", "zaxis")


def _check_geoms(path: Path, root: ET.Element) -> None:
    """Refuse a ``<geom>`` whose numbers are not finite (or whose size is negative), naming its body."""
    for body in root.iter("body"):
        for geom in body.findall("geom"):
            for attr in GEOM_NUMBERS:
                text = geom.get(attr)
                if text is None:
                    continue
                try:
                    nums = [float(x) for x in text.split()]
                except ValueError:
                    nums = []
                if not nums or not np.isfinite(nums).all() or (attr == "size" and min(nums) < 0):
                    need = "finite numbers ≥ 0" if attr == "size" else "finite numbers"
                    raise MJCFError(
                        path,
                        _label(body),
                        f"its <geom '{_label(geom)}'> {attr} = '{text}': expected {need}; fix the geometry",
                    )
