"""Closed-loop models as one tree with loop constraints (:class:`~pkmtol.model.loop_tree.LoopTree`).

* :func:`tree_from_urdf`: the example-parallel-robots convention whole: a URDF tree and its sidecar
  (``closed_loop`` pairs or ``closedloop<k>_A/_B`` frames, ``type`` ``6d``/``3d``, ``name_mot``,
  ``joint_name``/``joint_type`` ``FIXED``), loops between any two frames (between branches, below
  the platform, between rods); and the ``<constraint>`` elements proposed for urdfdom
  (:func:`urdf_constraints`).
* :func:`~pkmtol.model.mjcf.tree_from_mjcf`: an MJCF file's ``<equality>`` welds and connects.
* :func:`tree_from_constraint_models`: a Pinocchio 4 stack, one ``pin.Model`` and its
  ``FrameAnchorConstraintModel`` / ``PointAnchorConstraintModel`` (or legacy ``RigidConstraintModel``).

No cut into limbs happens here: the general formulation works on the tree itself
(:mod:`pkmtol.kinematics.tree_chain`, :mod:`pkmtol.error_model.tree_separation`).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import ClosedLoopError, UnknownMotorError
from pkmtol.model.limb import LimbLoop
from pkmtol.model.loop_tree import ErrorFrame, LoopTree, PointTask, frame_named, make_loops
from pkmtol.model.sidecar import Sidecar, default_sidecar, read_sidecar
from pkmtol.model.tree_cut import CLOSURE_FRAME, MOTOR_MARK, load_tree

#: ``type`` of a urdfdom ``<constraint>`` → loop kind (the proposal, ros/urdfdom#264).
CONSTRAINT_TYPES = {"fixed": "6d", "weld": "6d", "spherical": "3d", "ball": "3d", "point": "3d"}


def home_vector(model: pin.Model, home: Mapping[str, float] | None, source: str) -> np.ndarray:
    """Joint values (nq,) from values by joint name (others 0), or ClosedLoopError naming an unknown joint."""
    home = values.optional(values.joint_values, "home", home)
    q = np.zeros(model.nq)
    for name, value in (home or {}).items():
        if not model.existJointName(name):
            raise ClosedLoopError(source, name, f"home names joint '{name}', which the tree does not have")
        q[model.joints[model.getJointId(name)].idx_q] = float(value)
    return q


def actuated_indices(model: pin.Model, names: Sequence[str] | None, source: str) -> tuple[int, ...]:
    """Q indices of the actuated joints ``names`` (default: the joints named ``*mot*``), checked."""
    values.optional(values.strings, "actuated", names)
    joints = list(model.names[1:])
    chosen = list(names) if names is not None else [n for n in joints if MOTOR_MARK in n]
    for n in chosen:
        if n not in joints:
            raise UnknownMotorError(source, n, joints)
    if not chosen:
        raise ClosedLoopError(source, "name_mot", "no actuated joint; list the motors (name_mot or actuated)")
    return tuple(joints.index(n) for n in chosen)


def task_of(
    model: pin.Model, task_frame: str, point_m: Sequence[float], source: str
) -> tuple[int, PointTask]:
    """The task frame's id and the point task of ``point_m`` in it."""
    fid = frame_named(model, task_frame, "task frame", source)
    return fid, PointTask(values.vector("point_m", point_m, 3))


def _loop_name(pair: tuple[str, str], k: int) -> str:
    """A loop's name from its frames' names.

    Their common stem (``closedloop<k>``), a ``closedloop<k>`` side, their common prefix
    (``arm1_rod2`` of ``arm1_rod2_socket``/``arm1_rod2_end``), else ``loop<k>``.
    """
    stems = {re.sub(r"_[AB]$", "", name) for name in pair}
    if len(stems) == 1 and pair[0] != pair[1]:
        return stems.pop()
    for name in pair:
        m = CLOSURE_FRAME.match(name)
        if m:
            return f"closedloop{m.group(1)}"
    prefix = os.path.commonprefix(list(pair)).rstrip("_")
    return prefix if len(prefix) >= 3 else f"loop{k}"


def _locked(model: pin.Model, side: Sidecar, source: str) -> pin.Model:
    """The model with the sidecar's ``FIXED`` joints locked at 0 (other re-typings refused)."""
    locked = []
    for jname, jtype in side.joint_types.items():
        if not model.existJointName(jname):
            raise ClosedLoopError(source, jname, f"joint_name '{jname}' is not a joint of the tree")
        if jtype != "FIXED":
            raise ClosedLoopError(
                source,
                jname,
                f"joint_type {jtype} of '{jname}': pkmtol takes 1-DOF joints; write a spherical joint as "
                "three revolutes (or close it by a '3d' loop), a cardan as two revolutes",
            )
        locked.append(model.getJointId(jname))
    return pin.buildReducedModel(model, locked, pin.neutral(model)) if locked else model


def tree_from_urdf(
    urdf: Path | str,
    sidecar: Path | str | Sidecar | None = None,
    *,
    task_frame: str,
    point_m: Sequence[float] = (0.0, 0.0, 0.0),
    platform_frame: str | None = None,
    actuated: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
    name: str | None = None,
) -> LoopTree:
    """A URDF tree with loops: the example-parallel-robots sidecar, or urdfdom ``<constraint>`` elements.

    Args:
        urdf: The tree URDF.
        sidecar: Its sidecar (``robot.yaml`` …) or a :class:`Sidecar`; default: beside the URDF,
            or none when the URDF holds ``<constraint>`` elements.
        task_frame: The frame whose point ``point_m`` is the task point (e.g. the effector link).
        point_m: The task point in the task frame, shape (3,) [m].
        platform_frame: A frame on the platform body (the limbs' split); default the task frame.
        actuated: The actuated joints; default the sidecar's ``name_mot``, else every joint whose
            name contains ``mot``.
        home: Joint values by name where every loop closes (default 0) [rad or m].
        name: The mechanism's name (default the URDF's stem).

    Raises:
        URDFError, MechanismFormatError, ClosedLoopError (and subclasses): naming the culprit.
    """
    urdf = values.path("urdf", urdf)
    src = str(urdf)
    model, _, _ = load_tree(urdf)
    text = urdf.read_text(encoding="utf-8")
    constraints = urdf_constraints(ET.fromstring(text), src) if "<constraint" in text else []
    if constraints and sidecar is None:
        side = Sidecar(motors=None if actuated is None else tuple(actuated))
        model = pin.Model(model)
        loops = []
        for cname, kind, (plink, pplace), (clink, cplace) in constraints:
            fa = _add_frame(model, f"{cname}_A", plink, pplace, src)
            fb = _add_frame(model, f"{cname}_B", clink, cplace, src)
            loops.append(LimbLoop(cname, fa, fb, kind, (model.frames[fa].name, model.frames[fb].name)))
        tloops: tuple[LimbLoop, ...] = tuple(loops)
    else:
        if isinstance(sidecar, Sidecar):
            side = sidecar
        else:
            side = read_sidecar(default_sidecar(urdf) if sidecar is None else values.path("sidecar", sidecar))
        model = _locked(model, side, str(side.path or src))
        pairs = list(side.loops) or _convention_pairs(model)
        if not pairs:
            raise ClosedLoopError(
                src,
                "closed_loop",
                "no loop: list closed_loop pairs in the sidecar or name frames closedloop<k>_A/_B",
            )
        types = list(side.types) or ["6d"] * len(pairs)
        if len(types) != len(pairs):
            raise ClosedLoopError(str(side.path or src), "type", f"{len(types)} types for {len(pairs)} loops")
        tloops = make_loops(
            model,
            [
                (_loop_name(p, k + 1), p[0], p[1], t)
                for k, (p, t) in enumerate(zip(pairs, types, strict=True))
            ],
            src,
        )
    acts = actuated_indices(model, actuated if actuated is not None else side.motors, src)
    tf, task = task_of(model, task_frame, point_m, src)
    pf = tf if platform_frame is None else frame_named(model, platform_frame, "platform frame", src)
    return LoopTree(
        name=name or str(model.name) or urdf.stem,
        model=model,
        loops=tloops,
        actuated=acts,
        task_frame=tf,
        task=task,
        platform_frame=pf,
        home=home_vector(model, home, src),
        error_frames=platform_attachment(model, pf),
    )


def platform_attachment(model: pin.Model, platform: int) -> tuple[ErrorFrame, ...]:
    """The platform link's attachment error, when a URDF fixed joint attaches it (else none).

    As for a limb (DESIGN.md, "Geometric error parameters"): the fixed joint that attaches the
    platform link is an error origin, ``<joint>.dx`` … ``.rz`` at the platform frame; it moves the
    platform frame (and a loop side that is it), not the frames fixed below the platform link (a
    socket: its own loop's error places it).
    """
    f = model.frames[platform]
    parent = model.frames[f.parentFrame]
    if f.type != pin.FrameType.BODY or parent.type != pin.FrameType.FIXED_JOINT:
        return ()
    return (ErrorFrame(str(parent.name), platform, (platform, int(f.parentFrame))),)


def _convention_pairs(model: pin.Model) -> list[tuple[str, str]]:
    sides: dict[int, dict[str, str]] = {}
    for f in model.frames:
        m = CLOSURE_FRAME.match(f.name)
        if m:
            sides.setdefault(int(m.group(1)), {})[m.group(2)] = f.name
    return [(s["A"], s["B"]) for _, s in sorted(sides.items()) if len(s) == 2]


def _add_frame(model: pin.Model, name: str, link: str, placement: pin.SE3, src: str) -> int:
    """The frame at ``placement`` in link ``link``: the link's own frame for the identity, else a new one.

    The new frame is an OP frame ``name``. A constraint on the platform link itself is then the
    platform frame, which the platform attachment's error moves, as for a sidecar pair naming it.
    """
    body = frame_named(model, link, f"constraint frame '{name}'", src)
    if placement.isIdentity():
        return body
    f = model.frames[body]
    return int(
        model.addFrame(pin.Frame(name, f.parentJoint, body, f.placement * placement, pin.FrameType.OP_FRAME))
    )


def urdf_constraints(
    root: ET.Element, src: str
) -> list[tuple[str, str, tuple[str, pin.SE3], tuple[str, pin.SE3]]]:
    """The ``<constraint>`` elements of a URDF (the urdfdom proposal).

    Returns:
        ``(name, kind, (parent link, origin), (child link, origin))`` per element.


    ``<constraint name=… type=…>`` holds ``<parent link=…/>``, ``<parent_origin xyz rpy/>``,
    ``<child link=…/>``, ``<child_origin xyz rpy/>``: the two frames that coincide when the loop is
    closed. Types: ``fixed`` (``6d``) and ``spherical`` (``3d``); a constraint with axes (a revolute
    or universal cut) is refused: cut the loop at a fixed or ball point instead.
    """
    out = []
    for el in root.findall("constraint"):
        name = el.get("name") or ""
        ctype = (el.get("type") or "").lower()
        if not name:
            raise ClosedLoopError(src, "constraint", "a <constraint> without a name; name it")
        if ctype not in CONSTRAINT_TYPES:
            raise ClosedLoopError(
                src,
                name,
                f"<constraint type='{ctype}'>: pkmtol takes {', '.join(sorted(CONSTRAINT_TYPES))} "
                "(a revolute or universal cut: keep the joint in the tree and cut the loop at a fixed "
                "or ball point)",
            )
        sides = []
        for side in ("parent", "child"):
            link_el = el.find(side)
            if link_el is None or not link_el.get("link"):
                raise ClosedLoopError(src, name, f"<constraint name='{name}'> has no <{side} link=…/>")
            org = el.find(f"{side}_origin")
            xyz = _floats(org.get("xyz") if org is not None else None, src, name)
            rpy = _floats(org.get("rpy") if org is not None else None, src, name)
            sides.append((str(link_el.get("link")), pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))))
        out.append((name, CONSTRAINT_TYPES[ctype], sides[0], sides[1]))
    return out


def _floats(text: str | None, src: str, name: str) -> list[float]:
    if text is None:
        return [0.0, 0.0, 0.0]
    try:
        v = [float(x) for x in text.split()]
    except ValueError as err:
        raise ClosedLoopError(src, name, f"origin '{text}' is not three numbers") from err
    if len(v) != 3 or not np.all(np.isfinite(v)):
        raise ClosedLoopError(src, name, f"origin '{text}' is not three finite numbers")
    return v


def tree_from_constraint_models(
    model: pin.Model,
    constraint_models: Sequence[Any],
    actuated: Sequence[str],
    task_frame: str,
    point_m: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    platform_frame: str | None = None,
    home: np.ndarray | Sequence[float] | None = None,
    name: str | None = None,
) -> LoopTree:
    """A Pinocchio 4 stack as a :class:`LoopTree`: frame anchors are ``6d`` loops, point anchors ``3d``.

    Legacy ``RigidConstraintModel`` (``CONTACT_6D`` / ``CONTACT_3D``) are taken too. Each
    constraint's ``joint1``/``joint1_placement`` becomes frame a and ``joint2``/``joint2_placement``
    frame b (frames ``<name>_A``/``_B`` added to a copy of ``model``): Pinocchio's residual
    ``log6(oMc1⁻¹ · oMc2)`` is then the tree's ``6d`` residual, and a point anchor's
    ``R_1⁻¹ (p_2 − p_1)`` the ``3d`` one turned into frame a (tests check both Jacobians and the
    legacy models' opposite sign).

    Args:
        model: The tree (1-DOF revolute and prismatic joints).
        constraint_models: The loops.
        actuated: Names of the actuated joints.
        task_frame: The frame of the task point (in ``model``).
        point_m: The task point in that frame [m].
        platform_frame: A frame on the platform body; default the task frame.
        home: Joint values (nq,) where the loops close; default ``pin.neutral``.
        name: The mechanism's name (default ``model.name``).
    """
    values.instance("model", model, pin.Model, "a pinocchio.Model (the tree)")
    values.instances("constraint_models", constraint_models, object, "Pinocchio constraint models")
    values.strings("actuated", actuated)
    values.text("task_frame", task_frame)
    values.text_or_none("platform_frame", platform_frame)
    values.text_or_none("name", name)
    src = name or str(model.name) or "model"
    m = pin.Model(model)
    loops = []
    for k, c in enumerate(constraint_models):
        kind = _constraint_kind(c, k, src)
        cname = str(getattr(c, "name", "") or f"loop{k + 1}")
        ids = []
        for side, (joint, place) in zip(
            "AB", ((c.joint1_id, c.joint1_placement), (c.joint2_id, c.joint2_placement)), strict=True
        ):
            fname = f"{cname}_{side}"
            ids.append(
                int(m.addFrame(pin.Frame(fname, int(joint), 0, pin.SE3(place), pin.FrameType.OP_FRAME)))
            )
        loops.append(LimbLoop(cname, ids[0], ids[1], kind, (f"{cname}_A", f"{cname}_B")))
    tf, task = task_of(m, task_frame, point_m, src)
    pf = -1 if platform_frame is None else frame_named(m, platform_frame, "platform frame", src)
    q0 = pin.neutral(m) if home is None else values.array("home", home, ndim=1)
    return LoopTree(
        name=src,
        model=m,
        loops=tuple(loops),
        actuated=actuated_indices(m, list(actuated), src),
        task_frame=tf,
        task=task,
        platform_frame=pf,
        home=np.asarray(q0, dtype=float),
    )


def _constraint_kind(c: Any, k: int, src: str) -> str:
    tname = type(c).__name__
    if tname == "FrameAnchorConstraintModel":
        return "6d"
    if tname == "PointAnchorConstraintModel":
        return "3d"
    if tname == "RigidConstraintModel":
        ctype = str(c.type)
        if ctype.endswith("CONTACT_6D"):
            return "6d"
        if ctype.endswith("CONTACT_3D"):
            return "3d"
    raise ClosedLoopError(
        src,
        f"constraint {k + 1}",
        f"a {tname} is not a loop pkmtol takes; use FrameAnchorConstraintModel (6D) or "
        "PointAnchorConstraintModel (3D), or RigidConstraintModel CONTACT_6D / CONTACT_3D",
    )
