"""Closed-loop URDF import: one URDF tree with closure frame pairs, cut into serial limbs.

The convention is the "extended URDF" of Gepetto's example-parallel-robots (docs/closed-loop.md):
the mechanism is written as one kinematic *tree* rooted at the base link; every kinematic loop is
left open in the tree and closed by a pair of frames that must coincide, named
``closedloop<k>_A`` / ``closedloop<k>_B`` (k = loop number, 1-based). A sidecar file next to the
URDF (``robot.yaml``, or ``robot.toml`` with the same keys) lists the loops and the motors:

``closed_loop``
    list of frame-name pairs ``[[frame, frame], ...]``, one per loop (either order); when the key
    is missing, frames named ``closedloop<k>_A`` / ``closedloop<k>_B`` are paired by ``k``.
``type``
    per loop, ``"6d"`` (the two frames coincide in position and orientation) or ``"3d"`` (position
    only); default all ``"6d"``. pkmtol takes ``"6d"`` loops only.
``name_mot``
    the motor (actuated) joints; default: every joint whose name contains ``mot``.
``joint_name`` / ``joint_type``
    optional joint re-typing; ``FIXED`` locks a joint at 0 (``SPHERICAL`` and ``CARDAN`` are not
    1-DOF joints and are refused: write them as 3 or 2 revolutes).

How the tree is cut (:func:`cut_tree`):

* the **platform** is the link that holds one side of every loop (``platform_link`` overrides it;
  with a single loop, the ``_A`` side's link is taken); its frame is the platform frame O';
* the **reference limb** (limb 1) is the chain from the root to the platform: the branch the
  platform hangs on in the tree;
* each loop k gives one more limb: the chain from the root to the loop's other frame (the
  *limb-side* closure frame), ended by a platform frame placed where the platform is when the
  loop is closed: ``jMp = jMB · (pMA)⁻¹`` (B the limb-side frame relative to the limb's last
  joint, A the platform-side frame relative to the platform frame). Its origin error is that
  limb's platform-attachment parameter, named after the loop (``<limb>.closedloop<k>.dx`` ...);
* joints beyond the platform (e.g. a serial wrist) are not part of the parallel mechanism and are
  left out; any other moving joint that lies on no limb is an error (lock it with ``FIXED``).

Each limb's ``pin.Model`` is built joint by joint from the tree's ``pin.Model`` (same joint
models, placements and limits; the root link, the joint and body frames along the chain), so the
numbers are the tree's own. The result is an ordinary :class:`~pkmtol.mechanism.Mechanism`;
every later stage (kinematics, error model, allocation, viewer) sees serial limbs.
"""

from __future__ import annotations

import ast
import dataclasses
import re
import tomllib
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pinocchio as pin

from pkmtol.exceptions import (
    ClosedLoopError,
    ClosureFrameError,
    MechanismFormatError,
    NoLoopError,
    UnknownMotorError,
    URDFError,
)
from pkmtol.mechanism import (
    DEFAULT_BETAS,
    Limb,
    Mechanism,
    _make_limb,
    _Reader,
)
from pkmtol.taskspace import TaskSpace

#: Closure frame names of the convention: ``closedloop<k>_A`` / ``closedloop<k>_B``.
CLOSURE_FRAME = re.compile(r"^closedloop(\d+)_([AB])$")
#: Sidecar file names tried next to ``<stem>.urdf`` when none is given.
SIDECAR_SUFFIXES = (".yaml", ".yml", ".toml")
#: Substring that marks a motor joint when the sidecar has no ``name_mot`` (example-parallel-robots).
MOTOR_MARK = "mot"


@dataclass(frozen=True)
class Sidecar:
    """The loops and motors of a closed-loop URDF (the sidecar file's contents).

    Attributes:
        path: The sidecar file (None when built in Python).
        loops: Frame-name pairs that must coincide, one per loop, in file order; empty when the
            file has no ``closed_loop`` key (the pairs then come from the frame names).
        types: Per loop, ``"6d"`` or ``"3d"`` (lower case).
        motors: Motor joint names (``name_mot``); None when the key is missing.
        joint_types: Joint re-typing from ``joint_name`` / ``joint_type`` (upper case).
    """

    path: Path | None = None
    loops: tuple[tuple[str, str], ...] = ()
    types: tuple[str, ...] = ()
    motors: tuple[str, ...] | None = None
    joint_types: Mapping[str, str] = dataclasses.field(default_factory=dict)


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


# --- sidecar --------------------------------------------------------------------------------


def default_sidecar(urdf: Path | str) -> Path:
    """The sidecar next to ``urdf``: ``<stem>.yaml``, ``.yml`` or ``.toml``, the first that exists.

    Raises:
        MechanismFormatError: none of them exists.
    """
    urdf = Path(urdf)
    for suffix in SIDECAR_SUFFIXES:
        cand = urdf.with_suffix(suffix)
        if cand.is_file():
            return cand
    raise MechanismFormatError(
        urdf.with_suffix(".yaml"),
        "-",
        "file not found; a closed-loop URDF needs a sidecar listing its loops and motors "
        f"({' or '.join(urdf.with_suffix(s).name for s in SIDECAR_SUFFIXES)}; see docs/closed-loop.md)",
    )


def read_sidecar(path: Path | str) -> Sidecar:
    """Read a sidecar file (YAML as written by example-parallel-robots, or TOML with the same keys).

    YAML is read with PyYAML when it is installed (it comes with meshcat, through pyngrok);
    without it, the ``key: [python literal]`` lines that example-parallel-robots writes are
    still understood. A ``.toml`` file is read with the standard library.

    Raises:
        MechanismFormatError: the file is missing or unreadable, or a key is mistyped.
    """
    path = Path(path)
    if not path.is_file():
        raise MechanismFormatError(path, "-", "file not found; give the sidecar listing the loops and motors")
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".toml":
        try:
            doc: Any = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise MechanismFormatError(path, "-", f"not valid TOML: {err}") from err
    else:
        doc = _load_yaml(path, text)
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise MechanismFormatError(path, "-", f"expected a mapping of keys, got {type(doc).__name__}")
    return sidecar_from_dict(doc, path)


def sidecar_from_dict(doc: Mapping[str, Any], path: Path | str | None = None) -> Sidecar:
    """Validate the sidecar keys of ``doc`` (see the module docstring).

    Raises:
        MechanismFormatError: a key is mistyped or the lists disagree in length.
    """
    where = Path(path) if path is not None else Path("<sidecar>")
    r = _Reader(where, dict(doc))
    loops: list[tuple[str, str]] = []
    for k, pair in enumerate(r.get("closed_loop", list, default=[])):
        if not (isinstance(pair, list | tuple) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
            r.fail(f"closed_loop[{k}]", f"expected a pair of frame names, got {pair!r}")
        loops.append((pair[0], pair[1]))
    types = _str_list(r, "type", default=["6d"] * len(loops))
    if len(types) != len(loops):
        r.fail("type", f"{len(types)} types for {len(loops)} loops; give one type per closed_loop pair")
    types = [t.lower() for t in types]
    for k, t in enumerate(types):
        if t not in ("6d", "3d"):
            r.fail(f"type[{k}]", f"unknown loop type {t!r}; use '6d' or '3d'")
    motors = _str_list(r, "name_mot", default=None)
    names = _str_list(r, "joint_name", default=[])
    jtypes = _str_list(r, "joint_type", default=[])
    if len(names) != len(jtypes):
        r.fail("joint_type", f"{len(jtypes)} types for {len(names)} joint_name entries")
    return Sidecar(
        path=None if path is None else Path(path),
        loops=tuple(loops),
        types=tuple(types),
        motors=None if motors is None else tuple(motors),
        joint_types={n: t.upper() for n, t in zip(names, jtypes, strict=True)},
    )


def _str_list(r: _Reader, key: str, default: Any) -> Any:
    v = r.get(key, list, default=default)
    if v is not None and not all(isinstance(x, str) for x in v):
        r.fail(key, f"expected a list of strings, got {v!r}")
    return v


def _load_yaml(path: Path, text: str) -> Any:
    try:
        import yaml
    except ImportError:
        return _load_literal_yaml(path, text)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise MechanismFormatError(path, "-", f"not valid YAML: {err}") from err


def _load_literal_yaml(path: Path, text: str) -> dict[str, Any]:
    """The ``key: [python literal]`` lines example-parallel-robots writes, without PyYAML."""
    doc: dict[str, Any] = {}
    for n, line in enumerate(text.splitlines(), 1):
        body = line.split("#", 1)[0].strip() if not line.lstrip().startswith("#") else ""
        if not body:
            continue
        key, sep, value = body.partition(":")
        try:
            if not sep:
                raise ValueError("no 'key:'")
            doc[key.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError) as err:
            raise MechanismFormatError(
                path,
                "-",
                f"line {n}: cannot read {line.strip()!r} without PyYAML ({err}); "
                "install PyYAML or write the sidecar as TOML with the same keys",
            ) from err
    return doc


# --- cutting the tree -------------------------------------------------------------------------


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
) -> TreeCut:
    """Decide the platform and the limbs of a tree with closure frame pairs.

    Args:
        model: The tree (already with any ``FIXED`` joints locked).
        sidecar: Loops and motors.
        platform_link: The platform link; default: the link holding one side of every loop.
        limb_names: Names, reference limb first then one per loop (default ``limb1`` ...).
        source: The URDF file, for messages.

    Raises:
        NoLoopError: no loop is listed and no closure frames are in the tree.
        ClosureFrameError: a listed frame is missing, or a closure frame has no partner.
        UnknownMotorError: a motor joint is not in the tree.
        ClosedLoopError: the loops do not meet on one platform, limbs share joints, a loop
            closes on the base, a 3D loop, a motor on no limb, or a moving joint on no limb.
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
    _check_partners(model, loops, src, sidecar.path)
    types = list(sidecar.types) or ["6d"] * len(loops)
    for k, t in enumerate(types):
        if t != "6d":
            raise ClosedLoopError(
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
            "a closure nor beyond the platform); close their loop, or lock them with joint_type FIXED",
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
            attach = _loop_name(loops[k - 1], k)
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


def _check_partners(model: pin.Model, loops: list[tuple[str, str]], src: Path, sidecar: Path | None) -> None:
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


# --- serial limb models ------------------------------------------------------------------------


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


def _limb_visual(visual: Any, jmap: dict[int, int], fmap: dict[int, int], with_base: bool) -> Any:
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


# --- the mechanism -----------------------------------------------------------------------------


def closed_loop_limbs(
    urdf: Path | str,
    sidecar: Path | str | Sidecar | None = None,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
) -> tuple[list[Limb], TreeCut]:
    """Cut a closed-loop URDF into :class:`~pkmtol.mechanism.Limb` objects.

    Args:
        urdf: The tree URDF.
        sidecar: The sidecar file (or a :class:`Sidecar`); default: next to the URDF
            (:func:`default_sidecar`).
        platform_link: The platform link (default: the link holding one side of every loop).
        limb_names: Limb names, reference limb first (default ``limb1`` ...).
        home: Joint values [rad or m] by joint name at which every loop closes (±1 mm, ±1 mrad);
            joints not named are at 0.

    Returns:
        ``(limbs, cut)``: the limbs (reference limb first) and how the tree was cut.

    Raises:
        URDFError, MechanismFormatError, ClosedLoopError (and its subclasses): see
        :func:`load_tree`, :func:`read_sidecar`, :func:`cut_tree`.
    """
    urdf = Path(urdf)
    if isinstance(sidecar, Sidecar):
        side = sidecar
    else:
        side = read_sidecar(default_sidecar(urdf) if sidecar is None else Path(sidecar))
    tree, visual, _ = load_tree(urdf)
    locked = []
    for jname, jtype in side.joint_types.items():
        if not tree.existJointName(jname):
            raise ClosedLoopError(
                side.path or urdf,
                jname,
                f"joint_name '{jname}' is not a joint of the tree (joints: {', '.join(tree.names[1:])})",
            )
        if jtype == "FIXED":
            locked.append(tree.getJointId(jname))
        else:
            raise ClosedLoopError(
                side.path or urdf,
                jname,
                f"joint_type {jtype} of '{jname}': pkmtol takes 1-DOF joints only; write a spherical "
                "joint as three revolutes, a cardan as two",
            )
    if locked:
        if side.motors is not None:
            motors = set(side.motors)
        else:
            motors = {n for n in tree.names[1:] if MOTOR_MARK in n}
        for j in locked:
            if tree.names[j] in motors:
                raise ClosedLoopError(side.path or urdf, tree.names[j], "a motor joint cannot be FIXED")
        q0 = pin.neutral(tree)
        if visual is not None:
            tree, visual = pin.buildReducedModel(tree, visual, locked, q0)
        else:
            tree = pin.buildReducedModel(tree, locked, q0)
    cut = cut_tree(tree, side, platform_link, limb_names, urdf)
    cut = dataclasses.replace(cut, locked=tuple(side.joint_types))
    home = dict(home or {})
    names = set(tree.names[1:])
    for jname in home:
        if jname not in names:
            raise ClosedLoopError(
                urdf,
                jname,
                f"home names joint '{jname}', which is not a joint of the tree "
                f"(joints: {', '.join(tree.names[1:])})",
            )
    limbs = []
    for i, lc in enumerate(cut.limbs):
        model, jmap, fmap = limb_model(tree, cut, lc)
        q_home = [float(home.get(n, 0.0)) for n in lc.joints]
        limb = _make_limb(
            lc.name,
            model,
            list(lc.actuated),
            cut.platform_link,
            q_home,
            urdf,
            visual_model=_limb_visual(visual, jmap, fmap, with_base=i == 0),
        )
        limbs.append(dataclasses.replace(limb, attach_name=lc.attach_name))
    return limbs, cut


def load_closed_loop(
    urdf: Path | str,
    sidecar: Path | str | Sidecar | None = None,
    *,
    reference_point_m: Sequence[float],
    task_space: TaskSpace,
    name: str | None = None,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
    target_m: float = 5e-5,
    betas: Sequence[float] = DEFAULT_BETAS,
    design_beta: float = 2.0,
    description: str = "",
) -> Mechanism:
    """Build a mechanism from a closed-loop URDF and its sidecar (the Python twin of ``[closed_loop]``).

    Args:
        urdf: The tree URDF (closure frames ``closedloop<k>_A`` / ``closedloop<k>_B``).
        sidecar: The sidecar file or a :class:`Sidecar`; default ``<stem>.yaml``/``.yml``/``.toml``.
        reference_point_m: P in the platform frame, shape (3,) [m].
        task_space: Task space of P in K.
        name: Mechanism name (default: the URDF's file stem).
        platform_link: The platform link (default: the link holding one side of every loop).
        limb_names: Limb names, reference limb first (default ``limb1`` ...).
        home: Joint values [rad or m] by joint name where every loop closes (default 0).
        target_m: Δλ* [m].
        betas: β series.
        design_beta: β of the design case.
        description: Free text.

    Raises:
        URDFError, MechanismFormatError, ClosedLoopError: bad tree or sidecar (naming the culprit).
        PlatformMismatchError: a loop is not closed at ``home``.
    """
    urdf = Path(urdf)
    limbs, _ = closed_loop_limbs(urdf, sidecar, platform_link, limb_names, home)
    return Mechanism.from_limbs(
        name or urdf.stem,
        limbs,
        reference_point_m,
        task_space,
        target_m,
        betas,
        design_beta,
        description=description,
    )


def limbs_from_toml(folder: Path, r: _Reader) -> list[Limb]:
    """The limbs of a ``mechanism.toml`` whose ``[closed_loop]`` table names a tree URDF.

    Called by :func:`pkmtol.mechanism.load_mechanism`. Keys (docs/closed-loop.md): ``urdf``
    (required), ``sidecar``, ``platform_link``, ``limbs`` (names), ``home`` (table joint → value).
    """
    urdf = folder / r.get("closed_loop.urdf", str)
    side = r.get("closed_loop.sidecar", str, default=None)
    names = r.get("closed_loop.limbs", list, default=None)
    if names is not None and not all(isinstance(x, str) for x in names):
        r.fail("closed_loop.limbs", f"expected a list of limb names, got {names!r}")
    home = r.get("closed_loop.home", dict, default={})
    for jname, value in home.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            r.fail(f"closed_loop.home.{jname}", f"expected a number (rad or m), got {value!r}")
    limbs, _ = closed_loop_limbs(
        urdf,
        None if side is None else folder / side,
        r.get("closed_loop.platform_link", str, default=None),
        names,
        {k: float(v) for k, v in home.items()},
    )
    return limbs
