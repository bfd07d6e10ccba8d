"""The limbs of a cut tree: each limb's ``pin.Model`` built joint by joint from the tree, visuals, Limb.

See :mod:`pkmtol.model.closed_loop` for the convention and :mod:`pkmtol.model.tree_cut` for the cut.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import ClosedLoopError
from pkmtol.model.limb import Limb, frame_id, make_limb
from pkmtol.model.tree_cut import LimbCut, TreeCut


def limb_model(
    tree: pin.Model, cut: TreeCut, limb: LimbCut
) -> tuple[pin.Model, dict[int, int], dict[int, int]]:
    """The ``pin.Model`` of one limb (a chain or a tree), built joint by joint from the tree.

    Returns:
        ``(model, joint_map, frame_map)``: the limb model (root link, the limb's joints with the
        tree's joint models, placements and limits, their joint and body frames; for a loop limb a
        frame named after the platform link at the limb's end, and the platform's frames of its
        internal loops, placed where they are when the limb's closing loop is closed) and the maps
        tree index → limb index of the joints and frames copied.
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
        j_p = tree.frames[frame_id(tree, cut.platform_link)].parentJoint
        assert limb.platform_side_frame is not None
        f_b = frame_id(tree, limb.limb_frame)
        end = jmap[tree.frames[f_b].parentJoint]
        jMB = tree.frames[f_b].placement
        jpMA = _placement_on(tree, limb.platform_side_frame, j_p)
        for name in (cut.platform_link, *limb.platform_frames):
            # a frame X of the platform, where it is when the closing loop is closed: jMB · (jpMA)⁻¹ · jpMX
            jMx = jMB * jpMA.inverse() * _placement_on(tree, name, j_p)
            m.addFrame(pin.Frame(name, end, fmap.get(f_b, 0), jMx, pin.FrameType.OP_FRAME), False)
    return m, jmap, fmap


def _placement_on(tree: pin.Model, frame: str, joint: int) -> pin.SE3:
    f = tree.frames[frame_id(tree, frame)]
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
    home = values.optional(values.joint_values, "home", home) or {}
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
            loops=lc.loops,
        )
        limbs.append(dataclasses.replace(limb, attach_name=lc.attach_name))
    return limbs
