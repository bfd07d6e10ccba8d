"""Cutting a closed-loop tree into limbs: which link is the platform, which joints and loops make each limb.

See :mod:`pkmtol.model.closed_loop` for the convention and the rules of the cut.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import (
    ClosedLoopError,
    ClosureFrameError,
    NoLoopError,
    PointLoopError,
    UnknownMotorError,
    URDFError,
)
from pkmtol.model.limb import frame_id
from pkmtol.model.reading import build_model, build_visuals, read_text
from pkmtol.model.sidecar import Sidecar

#: Closure frame names of the convention: ``closedloop<k>_A`` / ``closedloop<k>_B``.
CLOSURE_FRAME = re.compile(r"^closedloop(\d+)_([AB])$")
#: Substring that marks a motor joint when the sidecar has no ``name_mot`` (example-parallel-robots).
MOTOR_MARK = "mot"


@dataclass(frozen=True)
class LimbCut:
    """One limb cut out of the tree: a serial chain, or a tree closed by internal loops.

    Attributes:
        name: Limb name.
        joints: The limb's joints, in the tree's order (q order).
        loop: Loop number k (1-based, sidecar order) that closes this limb on the platform; 0 for
            the reference limb (the platform hangs on it).
        limb_frame: Frame at the limb's end: the limb-side closure frame (B), or the platform
            link for the reference limb.
        platform_side_frame: The closing loop's frame on the platform (A); None for the reference limb.
        attach_name: Name of the limb's platform-attachment error origin (the loop name
            ``closedloop<k>`` for a loop limb; the URDF joint that attaches the platform link,
            or ``<platform>_attach``, for the reference limb).
        actuated: Motor joints of this limb (at most one).
        loops: The limb's internal loops ``(name, frame_a, frame_b, kind)``: every other loop of the
            tree that joins two frames of this limb, or this limb and the platform (then ``frame_a``
            is the platform's frame, copied into the limb's model).
        platform_frames: The platform's frames a loop limb's model carries besides the platform
            frame (the platform sides of its internal loops).
    """

    name: str
    joints: tuple[str, ...]
    loop: int
    limb_frame: str
    platform_side_frame: str | None
    attach_name: str
    actuated: tuple[str, ...]
    loops: tuple[tuple[str, str, str, str], ...] = ()
    platform_frames: tuple[str, ...] = ()


@dataclass(frozen=True)
class TreeCut:
    """How a closed-loop tree was cut into limbs.

    Attributes:
        root_link: The tree's root link (the base frame K).
        platform_link: The platform link (its frame is the platform frame O').
        limbs: Reference limb first, then one limb per loop that closes a part of the tree on the
            platform, in sidecar order.
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
    text = read_text(urdf, lambda problem: URDFError("tree", urdf, problem))
    model, root = build_model("tree", urdf, text)
    visual = build_visuals(model, root, "tree", urdf, text)
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
    ball_advice: str = "write the ball joint at the closure as three revolute joints ending in the "
    "limb-side frame and declare the loop '6d'",
) -> TreeCut:
    """Decide the platform and the limbs of a tree with closure frame pairs.

    The platform is the link holding a side of the most ``6d`` loops. The tree's branches from the
    base are grouped into limbs: two branches joined by a loop away from the platform are one
    limb. The branch holding the platform is the reference limb; every other limb closes on the
    platform by its first ``6d`` loop with a side on the platform, and every other loop becomes an
    internal loop of the limb it lies in (docs/closed-loop.md, "Loops inside limbs").

    Args:
        model: The tree (already with any ``FIXED`` joints locked).
        sidecar: Loops and motors.
        platform_link: The platform link; default: the link holding a side of the most ``6d`` loops.
        limb_names: Names, reference limb first then one per closing loop (default ``limb1`` ...).
        source: The file the tree comes from, for messages.
        loop_names: One name per loop, for the loops' error parameters, when the source format names
            its loops itself (MJCF ``<weld name=...>``). The frame-name convention
            ``closedloop<k>_A/_B`` is then not enforced. Default: the loop name is the frames'
            common stem (``closedloop<k>``), else ``loop<k>``.
        stray_advice: What the message of a moving joint on no limb tells the user to do
            besides closing its loop (the fix depends on the source format).
        ball_advice: How to close a limb whose only way to the platform is a 3D loop (the fix
            depends on the source format).

    Raises:
        NoLoopError: no loop is listed and no closure frames are in the tree.
        ClosureFrameError: a listed frame is missing, or a closure frame has no partner.
        UnknownMotorError: a motor joint is not in the tree.
        PointLoopError: a part of the tree reaches the platform through ``3d`` loops only.
        ClosedLoopError: no single platform, a loop closing on the base or below the platform,
            a loop joining two branches that both have a motor, a motor on no limb, or a moving
            joint on no limb.
    """
    values.text_or_none("platform_link", platform_link)
    values.optional(values.strings, "limb_names", limb_names)
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
    names_of = (
        list(loop_names) if loop_names is not None else [_loop_name(p, k + 1) for k, p in enumerate(loops)]
    )
    jids = [
        (model.frames[_frame_id(model, a)].parentJoint, model.frames[_frame_id(model, b)].parentJoint)
        for a, b in loops
    ]
    j_p = _platform_joint(model, loops, jids, types, platform_link, src)
    first = next((p[s] for p, js in zip(loops, jids, strict=True) for s in (0, 1) if js[s] == j_p), None)
    plat = platform_link or _link_of(model, first or loops[0][0])
    supports = [list(model.supports[j]) for j in range(model.njoints)]

    def below(j: int) -> bool:  # strictly below the platform
        return j != j_p and j_p in supports[j]

    def branch(j: int) -> int:  # the tree's branch from the base that joint j lies on (0: the base)
        return supports[j][1] if j else 0

    group = {j: j for j in range(1, model.njoints) if model.parents[j] == 0}

    def find(b: int) -> int:
        while group[b] != b:
            b = group[b]
        return b

    joins: dict[int, int] = {}  # loop k joined these branches away from the platform
    for k, ((a, b), (ja, jb)) in enumerate(zip(loops, jids, strict=True), 1):
        for side, j in ((a, ja), (b, jb)):
            if below(j):
                raise ClosedLoopError(
                    src,
                    side,
                    f"loop {k}: {side} hangs below the platform '{plat}'; joints beyond the platform "
                    "are not part of the parallel mechanism: close the loop on the platform or above it",
                )
        if ja == j_p and jb == j_p:
            raise ClosedLoopError(src, a, f"loop {k}: both {a} and {b} are on the platform '{plat}'")
        if j_p in (ja, jb):
            side_l, j_l = (b, jb) if ja == j_p else (a, ja)
            if j_l == 0:
                raise ClosedLoopError(
                    src,
                    side_l,
                    f"loop {k}: {side_l} is on the base link; the limb of a loop "
                    "must have at least one joint between the base and its closure frame",
                )
        elif ja == 0 and jb == 0:
            raise ClosedLoopError(src, a, f"loop {k}: both {a} and {b} are on the base link")
        elif ja and jb and find(branch(ja)) != find(branch(jb)):
            joins[k] = find(branch(jb))
            group[find(branch(jb))] = find(branch(ja))
    ref = find(branch(j_p))
    closing: dict[int, int] = {}  # group → the loop that closes it on the platform
    inner: dict[int, list[int]] = {}
    for k, (ja, jb) in enumerate(jids, 1):
        j_l = jb if ja == j_p else ja if jb == j_p else ja or jb
        g = find(branch(j_l))
        if j_p in (ja, jb) and g != ref and types[k - 1] == "6d" and g not in closing:
            closing[g] = k
        else:
            inner.setdefault(g, []).append(k)
    groups = [ref] + sorted(closing, key=closing.__getitem__)
    for g in {find(b) for b in group} - set(groups):
        points = [k for k in inner.get(g, []) if j_p in jids[k - 1]]
        if points:
            k = points[0]
            raise PointLoopError(
                src,
                loops[k - 1][0] if loop_names is None else loop_names[k - 1],
                f"loop {k} ({loops[k - 1][0]} ↔ {loops[k - 1][1]}) is a 3D closure and the only way "
                f"the branch of joint '{model.names[g]}' reaches the platform; pkmtol closes each limb "
                f"on the platform's full pose: {ball_advice}",
            )
    joint_names = list(model.names[1:])
    motors = (
        list(sidecar.motors) if sidecar.motors is not None else [n for n in joint_names if MOTOR_MARK in n]
    )
    for m in motors:
        if m not in joint_names:
            raise UnknownMotorError(sidecar.path or src, m, joint_names)
    for k, g in joins.items():
        mine = [m for m in motors if find(branch(model.getJointId(m))) == find(g)]
        if len(mine) > 1:
            raise ClosedLoopError(
                src,
                loops[k - 1][0],
                f"loop {k} ({loops[k - 1][0]} ↔ {loops[k - 1][1]}) joins two branches from the base away "
                f"from the platform, which makes them one limb with the motors {', '.join(mine)}; "
                "pkmtol's limbs (trees from the base closed by loops) have at most one motor: this "
                "topology is not handled",
            )
    names = list(limb_names) if limb_names is not None else [f"limb{i + 1}" for i in range(len(groups))]
    if len(names) != len(groups):
        raise ClosedLoopError(
            src,
            "limbs",
            f"{len(names)} limb names for {len(groups)} limbs (the reference limb, then one per loop "
            "that closes a limb on the platform)",
        )
    owner: dict[int, int] = {}
    cuts: list[LimbCut] = []
    for i, g in enumerate(groups):
        k0 = closing.get(g, 0)
        ends = [j_p] if k0 == 0 else [jids[k0 - 1][0] if jids[k0 - 1][1] == j_p else jids[k0 - 1][1]]
        internal, copied = [], []
        for k in inner.get(g, []):
            (a, b), (ja, jb) = loops[k - 1], jids[k - 1]
            if jb == j_p or (ja != j_p and b.endswith("_A") and not a.endswith("_A")):
                a, b, ja, jb = b, a, jb, ja  # frame a: the platform side, or the _A frame
            ends += [j for j in (ja, jb) if j and j != j_p]
            if ja == j_p and k0 != 0:
                copied.append(a)
            internal.append((names_of[k - 1], a, b, types[k - 1]))
        joints = sorted({j for e in ends for j in supports[e][1:] if not below(j) and (k0 == 0 or j != j_p)})
        owner.update(dict.fromkeys(joints, i))  # the groups' branches are disjoint: no joint is shared
        if k0 == 0:
            limb_frame, p_frame, attach = plat, None, _reference_attach(model, plat)
        else:
            pa, pb = loops[k0 - 1]
            limb_frame, p_frame = (pb, pa) if jids[k0 - 1][0] == j_p else (pa, pb)
            attach = names_of[k0 - 1]
            if attach in {model.names[j] for j in joints}:
                attach += "_closure"
        cuts.append(
            LimbCut(
                name=names[i],
                joints=tuple(model.names[j] for j in joints),
                loop=k0,
                limb_frame=limb_frame,
                platform_side_frame=p_frame,
                attach_name=attach,
                actuated=(),
                loops=tuple(internal),
                platform_frames=tuple(copied),
            )
        )
    beyond = [model.names[j] for j in range(1, model.njoints) if j not in owner and below(j)]
    stray = [model.names[j] for j in range(1, model.njoints) if j not in owner and not below(j) and j != j_p]
    if stray:
        raise ClosedLoopError(
            src,
            stray[0],
            f"moving joint(s) {', '.join(stray)} lie on no limb (neither between the base and "
            f"a closure nor beyond the platform); close their loop, or {stray_advice}",
        )
    by_limb: list[list[str]] = [[] for _ in cuts]
    for m in motors:
        j = model.getJointId(m)
        if j not in owner:
            raise ClosedLoopError(src, m, f"motor joint '{m}' is beyond the platform, on no limb")
        by_limb[owner[j]].append(m)
    cuts = [dataclasses.replace(c, actuated=tuple(m)) for c, m in zip(cuts, by_limb, strict=True)]
    return TreeCut(
        root_link=_body_of(model, 0), platform_link=plat, limbs=tuple(cuts), beyond_platform=tuple(beyond)
    )


def _platform_joint(
    model: pin.Model,
    loops: list[tuple[str, str]],
    jids: list[tuple[int, int]],
    types: list[str],
    platform_link: str | None,
    src: Path,
) -> int:
    """The platform's joint: ``platform_link``'s, else the body holding a side of the most 6d loops."""
    if platform_link is not None:
        if not model.existFrame(platform_link):
            raise ClosedLoopError(
                src,
                platform_link,
                "platform_link is not a link of the tree (" + ", ".join(_body_names(model)) + ")",
            )
        j_p = int(model.frames[_frame_id(model, platform_link)].parentJoint)
    else:
        count: dict[int, int] = {}
        for (ja, jb), t in zip(jids, types, strict=True):
            for j in {ja, jb} - {0}:
                count[j] = count.get(j, 0) + (t == "6d")
        top = max(count.values(), default=0)
        best = [j for j, c in count.items() if c == top]
        if len(loops) == 1:  # one loop: take the _A side (convention), else the first listed
            a_side = [k for k, name in enumerate(loops[0]) if name.endswith("_A")]
            j_p = jids[0][a_side[0] if a_side else 0]
        elif top == 0 or len(best) > 1:
            raise ClosedLoopError(
                src,
                loops[0][0],
                "no single link holds a side of the most 6d loops, so the platform is ambiguous (loops "
                + "; ".join(
                    f"{a} on '{_body_of(model, ja)}' ↔ {b} on '{_body_of(model, jb)}'"
                    for (a, b), (ja, jb) in zip(loops, jids, strict=True)
                )
                + "); set platform_link",
            )
        else:
            j_p = best[0]
    if j_p == 0:
        raise ClosedLoopError(
            src, platform_link or loops[0][0], "the platform cannot be the root link (the base)"
        )
    return j_p


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
    return frame_id(model, name)


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
