"""Error parameters of a :class:`~pkmtol.model.loop_tree.LoopTree`: names, units and their raw columns.

The ``urdf`` set of a tree (:func:`tree_urdf_set`): every joint placement
``<joint>.dx`` … ``.rz``, every error frame ``<frame>.dx`` …, every loop's closure error
``<loop>.dx`` … (``.dx .dy .dz`` only for a ``3d`` loop: frame b's rotation moves no point), then
every joint's zero offset ``<joint>.offset``. A tree made from limbs takes its limbs' set instead
(:func:`from_limb_set`: the ``urdf`` or ``dh`` set, the same parameters and names).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import pkmtol.values as values
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.model.loop_tree import COMPONENTS, LoopTree
from pkmtol.model.tree_from_limbs import LimbRaw


@dataclass(frozen=True, eq=False)
class TreeParameters:
    """A parameter set of a tree.

    Attributes:
        kind: ``"urdf"``, or the limb set's kind.
        names: Parameter names.
        units: ``"m"`` or ``"rad"`` per parameter.
        actuator: Per parameter, True for an actuated joint's zero offset.
        selection: Shape (n_raw, n): each parameter as a combination of the tree's raw errors.
    """

    kind: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    actuator: tuple[bool, ...]
    selection: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    def raw(self, eta: np.ndarray) -> np.ndarray:
        """Raw errors (n_raw,) of parameter values ``eta`` (n,) [m, rad]."""
        return self.selection @ values.vector("eta", eta, len(self))


def tree_urdf_set(tree: LoopTree) -> TreeParameters:
    """The ``urdf`` parameter set of a tree (see the module docstring)."""
    values.instance("tree", tree, LoopTree, "a pkmtol LoopTree (pkmtol.tree_from_urdf)")
    names, units, act, cols = [], [], [], []
    blocks = [(lab, tree.raw_block("joint", j), 6) for j, lab in enumerate(tree.joint_labels)]
    blocks += [(ef.name, tree.raw_block("frame", k), 6) for k, ef in enumerate(tree.error_frames)]
    blocks += [
        (lab, tree.raw_block("loop", k), 6 if lp.kind == "6d" else 3)
        for k, (lab, lp) in enumerate(zip(tree.loop_labels, tree.loops, strict=True))
    ]
    for label, blk, count in blocks:
        for c in range(count):
            names.append(f"{label}.{COMPONENTS[c]}")
            units.append("m" if c < 3 else "rad")
            act.append(False)
            cols.append(blk.start + c)
    kinds = tree.joint_kinds
    for j, label in enumerate(tree.joint_labels):
        names.append(f"{label}.offset")
        units.append("rad" if kinds[j] == "R" else "m")
        act.append(j in tree.actuated)
        cols.append(tree.offset_start + j)
    return TreeParameters("urdf", tuple(names), tuple(units), tuple(act), np.eye(tree.n_raw)[:, cols])


def from_limb_set(raw: LimbRaw, pset: ParameterSet) -> TreeParameters:
    """The tree's form of a limb parameter set (:class:`~pkmtol.error_model.parameters.ParameterSet`).

    Args:
        raw: Where the limbs' raw errors sit in the tree (``tree_from_mechanism``).
        pset: The limbs' parameter set (same mechanism).
    """
    params = pset.parameters
    return TreeParameters(
        kind=pset.kind,
        names=tuple(p.name for p in params),
        units=tuple(p.unit for p in params),
        actuator=tuple(p.actuator for p in params),
        selection=raw.selection(pset.selections),
    )
