"""A limb mechanism as one tree with loop constraints: the limb formulation as a special case.

:func:`tree_from_mechanism` puts every limb's joints under one root
(:func:`~pkmtol.model.constraints.constraint_models`, limb after limb, so ``q`` is
:attr:`~pkmtol.kinematics.closed_chain.Pose.q_all`) and writes the limbs' closures as loops:

* one ``6d`` loop per limb after the first, frame a the reference limb's platform frame, frame b
  that limb's platform frame; its closure error is the limb's platform-attachment error (it moves
  frame b and every frame of that limb the attachment moves, :attr:`~pkmtol.model.limb.Limb.attach_frames`);
* every internal loop of a limb, as it is (its frames a and b in that limb's part of the tree);
* the reference limb's platform attachment as an :class:`~pkmtol.model.loop_tree.ErrorFrame` at its
  platform frame (moving the frames it moves in the limb, and therefore the task frame and every
  closure's frame a).

:class:`LimbRaw` maps each limb's raw errors (``Limb.n_raw``: joint origins, attachment, loops,
offsets) to the tree's (:attr:`~pkmtol.model.loop_tree.LoopTree.n_raw`), so that any parameter set
of the limbs (``urdf`` or ``dh``) is a parameter set of the tree with the same columns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin

from pkmtol.model.constraints import constraint_models
from pkmtol.model.limb import Limb, LimbLoop
from pkmtol.model.loop_tree import ErrorFrame, LoopTree, PointTask


class LimbMechanism(Protocol):
    """What :func:`tree_from_mechanism` reads of a :class:`~pkmtol.model.mechanism.Mechanism`."""

    @property
    def name(self) -> str:
        """Mechanism name."""
        ...

    @property
    def limbs(self) -> tuple[Limb, ...]:
        """The limbs, reference limb first."""
        ...

    @property
    def reference_point_m(self) -> np.ndarray:
        """P in the platform frame (3,) [m]."""
        ...

    @property
    def task_normal(self) -> np.ndarray | None:
        """The normal of a planar task, or None."""
        ...


@dataclass(frozen=True)
class LimbRaw:
    """Where each limb's raw errors sit among the tree's.

    Attributes:
        index: Per limb, shape (Limb.n_raw,): the tree's raw index of each of the limb's raw errors.
        n_raw: The tree's number of raw errors.
    """

    index: tuple[np.ndarray, ...]
    n_raw: int

    def selection(self, selections: Sequence[np.ndarray]) -> np.ndarray:
        """The tree's selection (n_raw, n) of a limb parameter set's per-limb selections (n_raw_i, m_i)."""
        n = sum(s.shape[1] for s in selections)
        out = np.zeros((self.n_raw, n))
        col = 0
        for idx, sel in zip(self.index, selections, strict=True):
            out[idx, col : col + sel.shape[1]] = sel
            col += sel.shape[1]
        return out


def tree_from_mechanism(
    mechanism: LimbMechanism, models: Sequence[pin.Model] | None = None
) -> tuple[LoopTree, LimbRaw]:
    """The mechanism as one :class:`LoopTree`, and where its limbs' raw errors went.

    Args:
        mechanism: A mechanism of limbs.
        models: Replacement limb models (e.g. perturbed), the limbs' structure; default the limbs'.

    Returns:
        ``(tree, raw)``: the tree (its joints in the order of ``Pose.q_all``, its limbs the
        mechanism's, in order) and the raw-error map.
    """
    cm = constraint_models(mechanism, models)
    limbs = mechanism.limbs
    fm = cm.frame_maps
    pf = cm.platform_frames
    loops: list[LimbLoop] = []
    moves: list[tuple[int, ...]] = []
    labels: list[str] = []
    for i in range(1, len(limbs)):
        loops.append(
            LimbLoop(f"{limbs[i].name}.attach", pf[0], pf[i], "6d", ("platform", limbs[i].attach_name))
        )
        moves.append(
            (pf[i],) + tuple(sorted(fm[i][f] for f in limbs[i].attach_frames if f != limbs[i].platform_frame))
        )
        labels.append(f"{limbs[i].name}.{limbs[i].attach_name}")
    for i, limb in enumerate(limbs):
        for lp in limb.loops:
            loops.append(
                LimbLoop(
                    f"{limb.name}.{lp.name}", fm[i][lp.frame_a], fm[i][lp.frame_b], lp.kind, lp.frame_names
                )
            )
            moves.append((fm[i][lp.frame_b],))
            labels.append(f"{limb.name}.{lp.name}")
    attach = ErrorFrame(
        f"{limbs[0].name}.{limbs[0].attach_name}",
        pf[0],
        tuple(sorted(fm[0][f] for f in limbs[0].attach_frames)),
    )
    names = [f"{lb.name}.{j}" for lb in limbs for j in lb.joint_names]
    tree = LoopTree(
        name=mechanism.name,
        model=cm.model,
        loops=tuple(loops),
        actuated=cm.actuated,
        task_frame=pf[0],
        task=PointTask(np.asarray(mechanism.reference_point_m, dtype=float), mechanism.task_normal),
        platform_frame=pf[0],
        home=np.concatenate([lb.home for lb in limbs]),
        loop_moves=tuple(moves),
        error_frames=(attach,),
        joint_labels=tuple(names),
        loop_labels=tuple(labels),
        groups=tuple(tuple(range(s.start, s.stop)) for s in cm.q_slices),
    )
    index = []
    loop_of = {}  # (limb, internal loop k) -> tree loop index
    k = len(limbs) - 1
    for i, limb in enumerate(limbs):
        for lk in range(len(limb.loops)):
            loop_of[(i, lk)] = k
            k += 1
    for i, limb in enumerate(limbs):
        start = cm.q_slices[i].start
        idx = np.zeros(limb.n_raw, dtype=int)
        for j in range(limb.nq):
            idx[6 * j : 6 * j + 6] = np.arange(6 * (start + j), 6 * (start + j) + 6)
            idx[6 * limb.n_origins + j] = tree.offset_start + start + j
        blk = tree.raw_block("frame", 0) if i == 0 else tree.raw_block("loop", i - 1)
        idx[6 * limb.nq : 6 * limb.nq + 6] = np.arange(blk.start, blk.stop)
        for lk in range(len(limb.loops)):
            b = tree.raw_block("loop", loop_of[(i, lk)])
            at = 6 * (limb.nq + 1 + lk)
            idx[at : at + 6] = np.arange(b.start, b.stop)
        index.append(idx)
    return tree, LimbRaw(tuple(index), tree.n_raw)
