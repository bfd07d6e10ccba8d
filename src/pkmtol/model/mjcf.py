"""MJCF import: a MuJoCo model whose loops are ``<weld>`` (6D) or ``<connect>`` (3D) equalities, as limbs.

The file (docs/closed-loop.md, "MJCF") holds one kinematic tree under one jointless base body;
each loop is left open in the tree and closed by a ``<weld>`` between two bodies (``body1``,
``body2``) or two sites (``site1``, ``site2``), or by a ``<connect>`` (a ball joint: only a point of
each side coincides; two sites, or ``body1`` with its ``anchor``); ``<actuator>`` elements name the
actuated joints. Pinocchio's ``buildModelAndConstraintsFromMJCF`` reads the tree and gives one
``FrameAnchorConstraintModel`` per weld and one ``PointAnchorConstraintModel`` per connect: the two
joints and the placements on them that coincide when the loop is closed. Those placements become a
closure frame pair ``<loop>_A`` / ``<loop>_B`` of the tree (a site is its own closure frame), and the
tree is cut into limbs exactly as a closed-loop URDF is (:func:`~pkmtol.model.tree_cut.cut_tree`):
the platform is the body holding a side of the most welds (with a single weld, ``body1``'s side),
limb 1 the chain from the base to it, one more limb per branch that a weld closes on the platform
(its platform attachment named after the weld, ``<limb>.<weld>.dx`` ...), every other loop an
internal loop of its limb (``<limb>.<loop>.dx`` ...).

What pkmtol cannot take is refused before anything is cut (:mod:`~pkmtol.model.mjcf_checks`):
other equality kinds, tendons, multi-DOF joints, and the bodies and joints Pinocchio's reader would
drop.
"""

from __future__ import annotations

import copy
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import ClosedLoopError, LostElementError, MJCFError, UnsupportedEqualityError
from pkmtol.model.limb import Limb
from pkmtol.model.loop_tree import LoopTree, frame_named, make_loops
from pkmtol.model.mechanism import DEFAULT_BETAS, Mechanism
from pkmtol.model.mjcf_checks import (
    WeldSpec,
    actuated_joints,
    check_model,
    check_relpose,
    check_structure,
    check_tendons,
    frame_of,
    read_xml,
    welds,
)
from pkmtol.model.reading import TomlReader
from pkmtol.model.sidecar import Sidecar
from pkmtol.model.taskspace import TaskSpace
from pkmtol.model.tree_cut import TreeCut, cut_tree
from pkmtol.model.tree_inputs import actuated_indices, home_vector, task_of
from pkmtol.model.tree_limbs import cut_limbs

#: What a message about a moving joint on no limb advises for an MJCF file.
STRAY_ADVICE = "remove them from the file"
#: What a message about a limb that reaches the platform by a <connect> only advises.
BALL_ADVICE = (
    "write the ball joint at the anchor as three hinge joints in three nested bodies ending in the "
    "limb-side body, and close the loop with <weld>"
)


@dataclass(frozen=True)
class MjcfLoop:
    """One ``<weld>`` loop as Pinocchio read it.

    Attributes:
        name: The weld's name (``closedloop<k>`` when it has none).
        frame_a: Closure frame on side 1 (``body1`` / ``site1``) in :attr:`MjcfTree.model`.
        frame_b: Closure frame on side 2 (``body2`` / ``site2``).
        constraint: Pinocchio's ``FrameAnchorConstraintModel`` of the weld, or
            ``PointAnchorConstraintModel`` of the connect (``joint1`` = side 1).
        kind: ``"6d"`` (a ``<weld>``) or ``"3d"`` (a ``<connect>``: only the points coincide).
    """

    name: str
    frame_a: str
    frame_b: str
    constraint: Any
    kind: str = "6d"


@dataclass(frozen=True)
class MjcfTree:
    """An MJCF file as Pinocchio read it, checked, with a closure frame pair per weld.

    Attributes:
        path: The MJCF file.
        model: The tree (``pin.Model``) with the closure frames added.
        visual: Its visual ``pin.GeometryModel`` (None when Pinocchio cannot build it).
        loops: One per ``<weld>``, in file order.
        actuated: The actuated joints (``<actuator>`` joints, or the ones given).
        keyframes: Joint values [rad or m] by joint name, per ``<key name=...>`` of the file.
    """

    path: Path
    model: pin.Model
    visual: Any
    loops: tuple[MjcfLoop, ...]
    actuated: tuple[str, ...]
    keyframes: Mapping[str, Mapping[str, float]]


def read_mjcf(path: Path | str, actuated: Sequence[str] | None = None) -> MjcfTree:
    """Read and check an MJCF file; add a closure frame pair per weld.

    Args:
        path: The MJCF file.
        actuated: The actuated joints; default: the joints of the file's ``<actuator>`` elements.

    Raises:
        MJCFError (and subclasses): see :mod:`pkmtol.model.mjcf_checks`; also a file Pinocchio cannot
            read, an actuated joint that is not in the file, no actuator, or no weld.
    """
    path = values.path("path", path)
    values.optional(values.strings, "actuated", actuated)
    root = read_xml(path)
    check_structure(path, root)
    check_tendons(path, root)
    specs = welds(path, root)
    motors = actuated_joints(path, root) if actuated is None else list(actuated)
    try:
        model = pin.buildModelFromMJCF(str(path))
    except (RuntimeError, ValueError) as err:
        _diagnose(path, root)  # a keyframe's size error hides lost or multi-DOF joints
        raise MJCFError(path, "-", f"Pinocchio cannot read it: {err}") from err
    check_model(path, root, model)
    joints = list(model.names[1:])
    for m in motors:
        if m not in joints:
            src = "listed as actuated" if actuated is not None else "driven by an <actuator>"
            raise MJCFError(
                path, m, f"joint '{m}' {src} is not a joint of the file (joints: {', '.join(joints)})"
            )
    if not motors:
        raise MJCFError(
            path,
            "actuator",
            "no actuated joint: add <actuator><motor joint='...'/></actuator> to the file, "
            "or list the joints in the [mjcf] table's 'actuated'",
        )
    if not specs:
        raise MJCFError(
            path,
            "equality",
            "no <weld> or <connect> equality: this is a serial robot, not a parallel mechanism; close each "
            "loop with <equality><weld body1='platform' body2='...'/></equality> (or site1/site2)",
        )
    for spec in specs:  # both sides are in the model, and Pinocchio reads relpose as MuJoCo means it
        frame_of(path, model, spec, 1)
        frame_of(path, model, spec, 2)
        check_relpose(path, spec, model)
    try:
        model, points, anchors = pin.buildModelAndConstraintsFromMJCF(str(path))
    except (RuntimeError, ValueError) as err:
        raise MJCFError(path, "equality", f"Pinocchio cannot read the equalities: {err}") from err
    try:
        visual = pin.buildGeomFromMJCF(model, str(path), pin.GeometryType.VISUAL)
    except Exception:  # noqa: BLE001 - visuals are optional (meshes may be missing)
        visual = None
    loops = _closure_frames(path, model, specs, list(anchors), list(points))
    keyframes = {}
    for entry in model.referenceConfigurations:
        key, q = str(entry.key()), entry.data()
        if key != "qpos0":
            joints_q = ((model.names[j], model.joints[j].idx_q) for j in range(1, model.njoints))
            keyframes[key] = {name: float(q[iq]) for name, iq in joints_q}
    return MjcfTree(
        path=path, model=model, visual=visual, loops=tuple(loops), actuated=tuple(motors), keyframes=keyframes
    )


def _diagnose(path: Path, root: ET.Element) -> None:
    """Run :func:`check_model` on the file without its keyframes, when Pinocchio reads that."""
    bare = copy.deepcopy(root)
    for key in bare.findall("keyframe"):
        bare.remove(key)
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / path.name
        ET.ElementTree(bare).write(probe, encoding="unicode")
        try:
            model = pin.buildModelFromMJCF(str(probe))
        except (RuntimeError, ValueError):
            return
    check_model(path, root, model)


def _closure_frames(
    path: Path, model: pin.Model, specs: list[WeldSpec], anchors: list[Any], points: list[Any]
) -> list[MjcfLoop]:
    """Match each weld (connect) with Pinocchio's frame (point) anchor by its joints; add closure frames."""
    loops = []
    unused = {"6d": list(anchors), "3d": list(points)}
    for spec in specs:
        sides = (frame_of(path, model, spec, 1), frame_of(path, model, spec, 2))
        joints = tuple(int(model.frames[f].parentJoint) for f in sides)
        match = [c for c in unused[spec.kind] if (c.joint1_id, c.joint2_id) == joints]
        if len(match) > 1:
            raise UnsupportedEqualityError(
                path,
                spec.name,
                f"weld '{spec.name}' and another weld join the same two moving parts (joints "
                f"'{model.names[joints[0]]}' and '{model.names[joints[1]]}'): one loop written twice",
            )
        if not match:
            raise LostElementError(
                path,
                spec.name,
                [spec.name],
                f"weld '{spec.name}' ({spec.side1} ↔ {spec.side2}) is not among the "
                f"{len(unused[spec.kind])} {spec.kind} constraints Pinocchio's MJCF reader returned: it was "
                "dropped (give each weld a "
                "distinct name)",
            )
        c = match[0]
        unused[spec.kind].remove(c)
        names = []
        for side, (fid, placement, suffix) in enumerate(
            ((sides[0], c.joint1_placement, "A"), (sides[1], c.joint2_placement, "B")), 1
        ):
            frame = model.frames[fid]
            site = spec.site1 if side == 1 else spec.site2
            if site is not None:
                # a site is its own closure frame: Pinocchio anchors the constraint at the site
                same = (
                    frame.placement.isApprox(placement, 1e-12)
                    if spec.kind == "6d"
                    else np.allclose(frame.placement.translation, placement.translation, rtol=0, atol=1e-12)
                )
                if not same:
                    raise MJCFError(
                        path, site, f"Pinocchio anchored weld '{spec.name}' away from site '{site}'"
                    )
                names.append(frame.name)
                continue
            name = f"{spec.name}_{suffix}"
            while model.existFrame(name):
                name += "_weld"
            model.addFrame(pin.Frame(name, frame.parentJoint, fid, placement, pin.FrameType.OP_FRAME), False)
            names.append(name)
        loops.append(MjcfLoop(spec.name, names[0], names[1], c, spec.kind))
    return loops


def mjcf_limbs(
    path: Path | str,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
    keyframe: str | None = None,
    actuated: Sequence[str] | None = None,
) -> tuple[list[Limb], TreeCut]:
    """Cut an MJCF file into :class:`~pkmtol.model.limb.Limb` objects.

    Args:
        path: The MJCF file.
        platform_link: The platform body (default: the body holding one side of every weld; with a
            single weld, ``body1``'s).
        limb_names: Limb names, reference limb first then one per weld (default ``limb1`` ...).
        home: Joint values [rad or m] by joint name at which every loop closes (±1 mm, ±1 mrad);
            joints not named are at 0.
        keyframe: Take ``home`` from the file's ``<key name=keyframe qpos=...>`` instead. Without
            ``home`` and ``keyframe``, a keyframe named ``home`` is used when the file has one.
        actuated: The actuated joints (default: the ``<actuator>`` joints).

    Returns:
        ``(limbs, cut)``: the limbs (reference limb first) and how the tree was cut.

    Raises:
        MJCFError (and subclasses), ClosedLoopError: see :func:`read_mjcf` and
            :func:`~pkmtol.model.tree_cut.cut_tree`; also both ``home`` and ``keyframe``, or an
            unknown keyframe.
    """
    values.text_or_none("keyframe", keyframe)
    tree = read_mjcf(path, actuated)
    if home is not None and keyframe is not None:
        raise MJCFError(tree.path, "keyframe", "give either home joint values or a keyframe, not both")
    if keyframe is not None and keyframe not in tree.keyframes:
        raise MJCFError(
            tree.path,
            keyframe,
            f"no <key name='{keyframe}'> in the file's <keyframe> "
            f"(keys: {', '.join(tree.keyframes) or 'none'})",
        )
    if home is None:
        home = tree.keyframes.get(keyframe or "home", {})
    side = Sidecar(
        loops=tuple((lp.frame_a, lp.frame_b) for lp in tree.loops),
        types=tuple(lp.kind for lp in tree.loops),
        motors=tree.actuated,
    )
    cut = cut_tree(
        tree.model,
        side,
        platform_link,
        limb_names,
        tree.path,
        loop_names=[lp.name for lp in tree.loops],
        stray_advice=STRAY_ADVICE,
        ball_advice=BALL_ADVICE,
    )
    return cut_limbs(tree.model, tree.visual, cut, home, tree.path), cut


def load_mjcf(
    path: Path | str,
    *,
    reference_point_m: Sequence[float],
    task_space: TaskSpace,
    name: str | None = None,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
    keyframe: str | None = None,
    actuated: Sequence[str] | None = None,
    target_m: float = 5e-5,
    betas: Sequence[float] = DEFAULT_BETAS,
    design_beta: float = 2.0,
    description: str = "",
) -> Mechanism:
    """Build a mechanism from an MJCF file (the Python twin of the ``[mjcf]`` table).

    Args:
        path: The MJCF file (loops closed by ``<weld>``).
        reference_point_m: P in the platform frame, shape (3,) [m].
        task_space: Task space of P in K.
        name: Mechanism name (default: the file's stem).
        platform_link: The platform body (default: the body holding one side of every weld).
        limb_names: Limb names, reference limb first (default ``limb1`` ...).
        home: Joint values [rad or m] by joint name where every loop closes.
        keyframe: Or: the file's keyframe holding them (default ``home`` if the file has it).
        actuated: The actuated joints (default: the ``<actuator>`` joints).
        target_m: Δλ* [m].
        betas: β series.
        design_beta: β of the design case.
        description: Free text.

    Raises:
        MJCFError (and subclasses), ClosedLoopError: see :func:`mjcf_limbs`.
        PlatformMismatchError: a loop is not closed at ``home``.
    """
    path = values.path("path", path)
    limbs, _ = mjcf_limbs(path, platform_link, limb_names, home, keyframe, actuated)
    return Mechanism.from_limbs(
        name or path.stem,
        limbs,
        reference_point_m,
        task_space,
        target_m,
        betas,
        design_beta,
        description=description,
    )


def limbs_from_toml(folder: Path, r: TomlReader) -> list[Limb]:
    """The limbs of a ``mechanism.toml`` whose ``[mjcf]`` table names an MJCF file.

    Called by :func:`pkmtol.model.loader.load_mechanism`. Keys (docs/closed-loop.md, "MJCF"):
    ``file`` (required), ``platform_link``, ``limbs`` (names), ``home`` (table joint → value) or
    ``keyframe`` (a ``<key>`` of the file), ``actuated`` (joint names).
    """
    path = folder / r.get("mjcf.file", str)
    names = r.strings("mjcf.limbs", default=None, what="names")
    actuated = r.strings("mjcf.actuated", default=None, what="names")
    home = r.joint_values("mjcf.home", default=None)
    keyframe = r.get("mjcf.keyframe", str, default=None)
    if home is not None and keyframe is not None:
        r.fail("mjcf", "give either 'home' (joint values) or 'keyframe' (a <key> of the file), not both")
    limbs, _ = mjcf_limbs(
        path, r.get("mjcf.platform_link", str, default=None), names, home, keyframe, actuated
    )
    return limbs


def tree_from_mjcf(
    path: Path | str,
    *,
    task_frame: str,
    point_m: Sequence[float] = (0.0, 0.0, 0.0),
    platform_frame: str | None = None,
    actuated: Sequence[str] | None = None,
    keyframe: str | None = None,
    home: Mapping[str, float] | None = None,
) -> LoopTree:
    """An MJCF file as one tree: each ``<weld>`` a ``6d`` loop, each ``<connect>`` a ``3d`` one, anywhere.

    Args:
        path: The MJCF file.
        task_frame: The body or site whose point ``point_m`` is the task point.
        point_m: The task point in that frame [m].
        platform_frame: A frame on the platform body; default the task frame.
        actuated: The actuated joints (default the ``<actuator>`` joints).
        keyframe: The ``<key>`` whose ``qpos`` closes the loops (default ``home`` if the file has it).
        home: Joint values by name instead of a keyframe.
    """
    values.text_or_none("keyframe", keyframe)
    mj = read_mjcf(path, actuated)
    src = str(mj.path)
    model = mj.model
    loops = make_loops(model, [(lp.name, lp.frame_a, lp.frame_b, lp.kind) for lp in mj.loops], src)
    if home is None:
        key = keyframe if keyframe is not None else ("home" if "home" in mj.keyframes else None)
        if key is not None and key not in mj.keyframes:
            raise ClosedLoopError(
                src, key, f"no <key name='{key}'> (keys: {', '.join(mj.keyframes) or 'none'})"
            )
        home = mj.keyframes[key] if key is not None else {}
    tf, task = task_of(model, task_frame, point_m, src)
    pf = -1 if platform_frame is None else frame_named(model, platform_frame, "platform frame", src)
    return LoopTree(
        name=str(model.name or Path(src).stem),
        model=model,
        loops=loops,
        actuated=actuated_indices(model, mj.actuated, src),
        task_frame=tf,
        task=task,
        platform_frame=pf,
        home=home_vector(model, home, src),
    )
