"""Cutting a closed-loop URDF tree into serial limbs: which link is the platform, which joints make each limb.

See :mod:`pkmtol.model.closed_loop` for the convention and the rules of the cut.
"""

from __future__ import annotations

import dataclasses
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pinocchio as pin

from pkmtol.exceptions import (
    ClosedLoopError,
    ClosureFrameError,
    NoLoopError,
    PointLoopError,
    UnknownMotorError,
    URDFError,
)
from pkmtol.model.limb import Limb, make_limb
from pkmtol.model.sidecar import Sidecar

#: Closure frame names of the convention: ``closedloop<k>_A`` / ``closedloop<k>_B``.
CLOSURE_FRAME = re.compile(r"^closedloop(\d+)_([AB])$")
#: Substring that marks a motor joint when the sidecar has no ``name_mot`` (example-parallel-robots).
MOTOR_MARK = "mot"


@dataclass(frozen=True)
class LimbCut:
    """One serial limb cut out of the tree.

    Attributes:
        name: Limb name.
        joints: Joint names from the root to the limb's end, in q order.
        loop: Loop number k (1-based, sidecar order) this limb closes; 0 for the reference limb.
        limb_frame: Frame at the limb's end: the limb-side closure frame (B), or the platform
            link for the reference limb.
        platform_side_frame: The loop's frame on the platform (A); None for the reference limb.
        attach_name: Name of the limb's platform-attachment error origin (the loop name
            ``closedloop<k>`` for a loop limb; the URDF joint that attaches the platform link,
            or ``<platform>_attach``, for the reference limb).
        actuated: Motor joints of this limb (at most one).
    """

    name: str
    joints: tuple[str, ...]
    loop: int
    limb_frame: str
    platform_side_frame: str | None
    attach_name: str
    actuated: tuple[str, ...]


@dataclass(frozen=True)
class TreeCut:
    """How a closed-loop tree was cut into limbs.

    Attributes:
        root_link: The tree's root link (the base frame K).
        platform_link: The platform link (its frame is the platform frame O').
        limbs: Reference limb first, then one limb per loop in sidecar order.
        beyond_platform: Moving joints below the platform, left out of the mechanism.
        locked: Joints locked at 0 by ``joint_type: FIXED``.
    """

    root_link: str
    platform_link: str
    limbs: tuple[LimbCut, ...]
    beyond_platform: tuple[str, ...] = ()
    locked: tuple[str, ...] = ()


def load_tree(urdf: Path | str) -> tuple[pin.Model, Any, str]:
    """Read the closed-loop URDF tree: ``(model, visual_model or None, root link name)``.

    Raises:
        URDFError: missing, malformed, or unreadable by Pinocchio (the limb is named ``tree``).
    """
    urdf = Path(urdf)
    if not urdf.is_file():
        raise URDFError("tree", urdf, "file not found")
    text = urdf.read_text(encoding="utf-8")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise URDFError("tree", urdf, f"malformed XML: {err}") from err
    try:
        model = pin.buildModelFromXML(text)
    except (RuntimeError, ValueError) as err:
        raise URDFError("tree", urdf, f"Pinocchio cannot read it: {err}") from err
    try:
        visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL, None, [str(urdf.parent)])
    except Exception:  # noqa: BLE001 - visuals are optional (meshes may be missing)
        visual = None
    children = {j.find("child").get("link") for j in root.findall("joint") if j.find("child") is not None}  # type: ignore[union-attr]
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    return model, visual, str(roots[0]) if roots else "universe"


def cut_tree(
    model: pin.Model,
    sidecar: Sidecar,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    source: Path | str | None = None,
    *,
    loop_names: Sequence[str] | None = None,
    stray_advice: str = "lock them with joint_type FIXED",
) -> TreeCut:
    """Decide the platform and the limbs of a tree with closure frame pairs.

    Args:
        model: The tree (already with any ``FIXED`` joints locked).
        sidecar: Loops and motors.
        platform_link: The platform link; default: the link holding one side of every loop.
        limb_names: Names, reference limb first then one per loop (default ``limb1`` ...).
        source: The file the tree comes from, for messages.
        loop_names: One name per loop, for the loop limbs' platform-attachment parameters, when
            the source format names its loops itself (MJCF ``<weld name=...>``). The frame-name
            convention ``closedloop<k>_A/_B`` is then not enforced. Default: the loop name is
            the frames' common stem (``closedloop<k>``), else ``loop<k>``.
        stray_advice: What the message of a moving joint on no limb tells the user to do
            besides closing its loop (the fix depends on the source format).

    Raises:
        NoLoopError: no loop is listed and no closure frames are in the tree.
        ClosureFrameError: a listed frame is missing, or a closure frame has no partner.
        UnknownMotorError: a motor joint is not in the tree.
        PointLoopError: a ``'3d'`` loop.
        ClosedLoopError: the loops do not meet on one platform, limbs share joints, a loop
            closes on the base, a motor on no limb, or a moving joint on no limb.
    """
    src = Path(source) if source is not None else Path("<tree>")
    loops = list(sidecar.loops) or _convention_pairs(model, src)
    if not loops:
        raise NoLoopError(
            src,
            "the tree has no closure frames 'closedloop<k>_A'/'closedloop<k>_B' and the "
            "sidecar lists no closed_loop pairs: this is a serial robot, not a parallel "
            "mechanism; add the closure frames and list them under closed_loop",
        )
    _check_partners(model, loops, src, sidecar.path, convention=loop_names is None)
    if loop_names is not None and len(loop_names) != len(loops):
        raise ClosedLoopError(src, "loops", f"{len(loop_names)} loop names for {len(loops)} loops")
    types = list(sidecar.types) or ["6d"] * len(loops)
    for k, t in enumerate(types):
        if t != "6d":
            raise PointLoopError(
                src,
                loops[k][0],
                f"loop {k + 1} ({loops[k][0]} ↔ {loops[k][1]}) is a {t.upper()} closure; pkmtol closes "
                "each limb on the platform's full pose: write the ball joint at the closure as three "
                "revolute joints ending in the limb-side frame and declare the loop '6d'",
            )
    fids = [(_frame_id(model, a), _frame_id(model, b)) for a, b in loops]
    jids = [(model.frames[fa].parentJoint, model.frames[fb].parentJoint) for fa, fb in fids]

    # the platform: the body (Pinocchio joint) holding one side of every loop
    if platform_link is not None:
        if not model.existFrame(platform_link):
            raise ClosedLoopError(
                src,
                platform_link,
                "platform_link is not a link of the tree (" + ", ".join(_body_names(model)) + ")",
            )
        j_p = model.frames[model.getFrameId(platform_link)].parentJoint
    else:
        common = set(jids[0])
        for pair in jids[1:]:
            common &= set(pair)
        common.discard(0)
        if not common:
            raise ClosedLoopError(
                src,
                loops[0][0],
                "no link holds one side of every loop: pkmtol cuts a tree whose loops all close on one "
                "platform (loops "
                + "; ".join(
                    f"{a} on '{_body_of(model, ja)}' ↔ {b} on '{_body_of(model, jb)}'"
                    for (a, b), (ja, jb) in zip(loops, jids, strict=True)
                )
                + "); set platform_link if the platform is ambiguous",
            )
        if len(common) > 1:  # one loop: take the _A side (convention), else the first listed
            a_side = [k for k, name in enumerate(loops[0]) if name.endswith("_A")]
            j_p = jids[0][a_side[0] if a_side else 0]
        else:
            j_p = common.pop()
    if j_p == 0:
        raise ClosedLoopError(
            src, platform_link or loops[0][0], "the platform cannot be the root link (the base)"
        )
    first = loops[0][0] if jids[0][0] == j_p else loops[0][1]
    plat = platform_link or _link_of(model, first)
    supports = [list(model.supports[j]) for j in range(model.njoints)]

    cuts: list[tuple[int, list[int], int, str, str | None]] = []  # (loop, path, end joint, limb frame, A)
    cuts.append((0, supports[j_p][1:], j_p, plat, None))
    for k, ((a, b), (ja, jb)) in enumerate(zip(loops, jids, strict=True), 1):
        if ja == j_p and jb == j_p:
            raise ClosedLoopError(src, a, f"loop {k}: both {a} and {b} are on the platform '{plat}'")
        if ja == j_p:
            side_p, side_l, j_l = a, b, jb
        elif jb == j_p:
            side_p, side_l, j_l = b, a, ja
        else:
            raise ClosedLoopError(
                src,
                a,
                f"loop {k} ({a} on '{_body_of(model, ja)}' ↔ {b} on '{_body_of(model, jb)}') "
                f"does not close on the platform '{plat}'; each loop must have one frame on the platform",
            )
        if j_l == 0:
            raise ClosedLoopError(
                src,
                side_l,
                f"loop {k}: {side_l} is on the base link; the limb of a loop "
                "must have at least one joint between the base and its closure frame",
            )
        if j_p in supports[j_l]:
            raise ClosedLoopError(
                src,
                side_l,
                f"loop {k}: {side_l} hangs below the platform '{plat}'; "
                "each limb must run from the base to the platform",
            )
        cuts.append((k, supports[j_l][1:], j_l, side_l, side_p))

    owner: dict[int, int] = {}
    names = list(limb_names) if limb_names is not None else [f"limb{i + 1}" for i in range(len(cuts))]
    if len(names) != len(cuts):
        raise ClosedLoopError(
            src,
            "limbs",
            f"{len(names)} limb names for {len(cuts)} limbs (the reference limb, then one per loop)",
        )
    for i, entry in enumerate(cuts):
        for j in entry[1]:
            if j in owner:
                raise ClosedLoopError(
                    src,
                    model.names[j],
                    f"joint '{model.names[j]}' is shared by limbs '{names[owner[j]]}' and '{names[i]}'; "
                    "pkmtol needs limbs that are independent serial chains from the base: give each "
                    "limb its own joints (two joints on the same axis if need be)",
                )
            owner[j] = i
    beyond = [model.names[j] for j in range(1, model.njoints) if j not in owner and j_p in supports[j]]
    stray = [model.names[j] for j in range(1, model.njoints) if j not in owner and j_p not in supports[j]]
    if stray:
        raise ClosedLoopError(
            src,
            stray[0],
            f"moving joint(s) {', '.join(stray)} lie on no limb (neither between the base and "
            f"a closure nor beyond the platform); close their loop, or {stray_advice}",
        )

    joint_names = list(model.names[1:])
    if sidecar.motors is not None:
        motors = list(sidecar.motors)
    else:
        motors = [n for n in joint_names if MOTOR_MARK in n]
    for m in motors:
        if m not in joint_names:
            raise UnknownMotorError(sidecar.path or src, m, joint_names)
    by_limb: list[list[str]] = [[] for _ in cuts]
    for m in motors:
        j = model.getJointId(m)
        if j not in owner:
            raise ClosedLoopError(src, m, f"motor joint '{m}' is beyond the platform, on no limb")
        by_limb[owner[j]].append(m)

    limbs = []
    for i, (k, path, _end, limb_frame, p_frame) in enumerate(cuts):
        if k == 0:
            attach = _reference_attach(model, plat)
        else:
            attach = loop_names[k - 1] if loop_names is not None else _loop_name(loops[k - 1], k)
            if attach in {model.names[j] for j in path}:
                attach += "_closure"
        limbs.append(
            LimbCut(
                name=names[i],
                joints=tuple(model.names[j] for j in path),
                loop=k,
                limb_frame=limb_frame,
                platform_side_frame=p_frame,
                attach_name=attach,
                actuated=tuple(by_limb[i]),
            )
        )
    return TreeCut(
        root_link=_body_of(model, 0), platform_link=plat, limbs=tuple(limbs), beyond_platform=tuple(beyond)
    )


def _convention_pairs(model: pin.Model, src: Path) -> list[tuple[str, str]]:
    """Pairs ``(closedloop<k>_A, closedloop<k>_B)`` by loop number, from the frame names."""
    sides: dict[int, dict[str, str]] = {}
    for f in model.frames:
        m = CLOSURE_FRAME.match(f.name)
        if m:
            sides.setdefault(int(m.group(1)), {})[m.group(2)] = f.name
    pairs = []
    for k in sorted(sides):
        s = sides[k]
        if len(s) != 2:
            have = next(iter(s.values()))
            want = f"closedloop{k}_{'B' if 'A' in s else 'A'}"
            raise ClosureFrameError(
                src,
                have,
                f"its partner '{want}' is not in the tree; add it (the frame "
                f"that must coincide with {have} when loop {k} is closed)",
            )
        pairs.append((s["A"], s["B"]))
    return pairs


def _check_partners(
    model: pin.Model, loops: list[tuple[str, str]], src: Path, sidecar: Path | None, convention: bool = True
) -> None:
    listed = {name for pair in loops for name in pair}
    present = sorted(f.name for f in model.frames if CLOSURE_FRAME.match(f.name))
    for k, (a, b) in enumerate(loops, 1):
        for name, partner in ((a, b), (b, a)):
            if not model.existFrame(name):
                raise ClosureFrameError(
                    src,
                    name,
                    f"listed in loop {k} (partner of '{partner}') but not in the tree "
                    f"(closure frames present: {', '.join(present) or 'none'}); add a link of that name "
                    "or fix the sidecar",
                )
    if not convention:
        return
    for name in present:
        m = CLOSURE_FRAME.match(name)
        assert m is not None
        if name not in listed:
            partner = f"closedloop{m.group(1)}_{'B' if m.group(2) == 'A' else 'A'}"
            if not model.existFrame(partner):
                raise ClosureFrameError(src, name, f"its partner '{partner}' is not in the tree")
            raise ClosureFrameError(
                sidecar or src,
                name,
                "closure frame of the tree not listed in the sidecar's closed_loop; add "
                f"['{min(name, partner)}', '{max(name, partner)}'] (or rename it if it closes no loop)",
            )


def _frame_id(model: pin.Model, name: str) -> int:
    return int(model.getFrameId(name))


def _body_names(model: pin.Model) -> list[str]:
    return [f.name for f in model.frames if f.type == pin.FrameType.BODY]


def _body_of(model: pin.Model, joint: int) -> str:
    """The link that moves with ``joint`` (the child link of the joint; the root link for 0)."""
    for f in model.frames:
        if f.type != pin.FrameType.BODY or f.parentJoint != joint:
            continue
        parent = model.frames[f.parentFrame]
        if joint == 0 or parent.type == pin.FrameType.JOINT:
            return str(f.name)
    return str(model.names[joint])


def _link_of(model: pin.Model, frame: str) -> str:
    """The link a frame is attached to (through fixed joints), or the child link of a joint frame."""
    f = model.frames[model.getFrameId(frame)]
    while f.type != pin.FrameType.JOINT:
        parent = model.frames[f.parentFrame]
        if parent.type == pin.FrameType.BODY or f.parentFrame == 0:
            return str(parent.name)
        f = parent
    return _body_of(model, f.parentJoint)


def _reference_attach(model: pin.Model, platform: str) -> str:
    """The URDF fixed joint attaching the platform link, else ``<platform>_attach``."""
    f = model.frames[model.getFrameId(platform)]
    parent = model.frames[f.parentFrame]
    if parent.type == pin.FrameType.FIXED_JOINT:
        return str(parent.name)
    return f"{platform}_attach"


def _loop_name(pair: tuple[str, str], k: int) -> str:
    stems = {re.sub(r"_[AB]$", "", name) for name in pair}
    return stems.pop() if len(stems) == 1 and not pair[0].endswith(pair[1]) else f"loop{k}"


def limb_model(
    tree: pin.Model, cut: TreeCut, limb: LimbCut
) -> tuple[pin.Model, dict[int, int], dict[int, int]]:
    """The serial ``pin.Model`` of one limb, built joint by joint from the tree.

    Returns:
        ``(model, joint_map, frame_map)``: the limb model (root link, the limb's joints with the
        tree's joint models, placements and limits, their joint and body frames, and a frame named
        after the platform link at the limb's end) and the maps tree index → limb index of the
        joints and frames copied.
    """
    m = pin.Model()
    m.name = limb.name
    path = [tree.getJointId(n) for n in limb.joints]
    jmap = {0: 0}
    for j in path:
        jm = tree.joints[j]
        iq, iv = jm.idx_q, jm.idx_v
        jmap[j] = m.addJoint(
            jmap[tree.parents[j]],
            jm,
            tree.jointPlacements[j],
            tree.names[j],
            tree.effortLimit[iv : iv + jm.nv],
            tree.velocityLimit[iv : iv + jm.nv],
            tree.lowerPositionLimit[iq : iq + jm.nq],
            tree.upperPositionLimit[iq : iq + jm.nq],
        )
        m.appendBodyToJoint(jmap[j], tree.inertias[j], pin.SE3.Identity())
    fmap = {0: 0}
    keep = set(jmap)
    for fid, f in enumerate(tree.frames):
        if fid == 0 or f.parentJoint not in keep:
            continue
        parent = fmap.get(f.parentFrame, 0)
        if f.type == pin.FrameType.JOINT:
            fmap[fid] = m.addJointFrame(jmap[f.parentJoint], parent)
        else:
            fmap[fid] = m.addFrame(
                pin.Frame(f.name, jmap[f.parentJoint], parent, f.placement, f.type, f.inertia), False
            )
    if limb.loop != 0:
        if m.existFrame(cut.platform_link):
            raise ClosedLoopError(
                Path("<tree>"),
                cut.platform_link,
                f"limb '{limb.name}' already has a frame named like the platform link",
            )
        j_p = tree.frames[tree.getFrameId(cut.platform_link)].parentJoint
        assert limb.platform_side_frame is not None
        f_b = tree.getFrameId(limb.limb_frame)
        jMB = tree.frames[f_b].placement
        jpMA = _placement_on(tree, limb.platform_side_frame, j_p)
        jpMp = _placement_on(tree, cut.platform_link, j_p)
        jMp = jMB * jpMA.inverse() * jpMp
        frame = pin.Frame(cut.platform_link, jmap[path[-1]], fmap.get(f_b, 0), jMp, pin.FrameType.OP_FRAME)
        m.addFrame(frame, False)
    return m, jmap, fmap


def _placement_on(tree: pin.Model, frame: str, joint: int) -> pin.SE3:
    f = tree.frames[tree.getFrameId(frame)]
    assert f.parentJoint == joint
    return f.placement


def limb_visual(visual: Any, jmap: dict[int, int], fmap: dict[int, int], with_base: bool) -> Any:
    """The tree's visuals that move with the limb's joints (and the base's, for one limb)."""
    if visual is None:
        return None
    gm = pin.GeometryModel()
    for go in visual.geometryObjects:
        if go.parentJoint not in jmap or (go.parentJoint == 0 and not with_base):
            continue
        g = go.copy()
        g.parentJoint = jmap[go.parentJoint]
        g.parentFrame = fmap.get(go.parentFrame, 0)
        gm.addGeometryObject(g)
    return gm


def cut_limbs(
    tree: pin.Model,
    visual: Any,
    cut: TreeCut,
    home: Mapping[str, float] | None,
    source: Path | str,
) -> list[Limb]:
    """The :class:`~pkmtol.model.limb.Limb` objects of a cut tree (reference limb first).

    Args:
        tree: The tree the cut was made on.
        visual: The tree's visual ``pin.GeometryModel`` (or None).
        cut: How the tree was cut (:func:`cut_tree`).
        home: Joint values [rad or m] by joint name at which every loop closes; others are 0.
        source: The file the tree comes from (each limb's ``urdf_path``, and messages).

    Raises:
        ClosedLoopError: ``home`` names a joint that is not in the tree.
        URDFError: a limb is not a serial chain of 1-DOF joints (:func:`~pkmtol.model.limb.make_limb`).
    """
    source = Path(source)
    home = dict(home or {})
    names = set(tree.names[1:])
    for jname in home:
        if jname not in names:
            raise ClosedLoopError(
                source,
                jname,
                f"home names joint '{jname}', which is not a joint of the tree "
                f"(joints: {', '.join(tree.names[1:])})",
            )
    limbs = []
    for i, lc in enumerate(cut.limbs):
        model, jmap, fmap = limb_model(tree, cut, lc)
        q_home = [float(home.get(n, 0.0)) for n in lc.joints]
        limb = make_limb(
            lc.name,
            model,
            list(lc.actuated),
            cut.platform_link,
            q_home,
            source,
            visual_model=limb_visual(visual, jmap, fmap, with_base=i == 0),
        )
        limbs.append(dataclasses.replace(limb, attach_name=lc.attach_name))
    return limbs
