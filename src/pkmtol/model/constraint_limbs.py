"""A Pinocchio 4 constraint stack cut into limbs (``Mechanism.from_constraint_models``).

The stack (one ``pin.Model`` and its frame or point anchors) is read as a
:class:`~pkmtol.model.loop_tree.LoopTree` (:func:`~pkmtol.model.tree_inputs.tree_from_constraint_models`:
each anchor's two sides become frames ``<name>_A``/``<name>_B``), then cut into limbs as a
closed-loop URDF is (:func:`~pkmtol.model.tree_cut.cut_tree`, the platform being the task frame's
link), so that every stage of pkmtol takes it. A stack the cut refuses (loops below the platform,
two motorised branches joined away from it) still runs on the general formulation: use the tree.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.model.limb import Limb
from pkmtol.model.loop_tree import LoopTree
from pkmtol.model.sidecar import Sidecar
from pkmtol.model.tree_cut import cut_tree
from pkmtol.model.tree_inputs import tree_from_constraint_models
from pkmtol.model.tree_limbs import cut_limbs


def limbs_from_constraint_models(
    model: pin.Model,
    constraint_models: Sequence[Any],
    actuated: Sequence[str],
    task_frame: str,
    home: np.ndarray | Sequence[float] | None = None,
    limb_names: Sequence[str] | None = None,
    name: str | None = None,
) -> tuple[list[Limb], LoopTree]:
    """The limbs of a constraint stack and the stack as a tree.

    Raises:
        ClosedLoopError (and subclasses): a constraint of another kind, an unknown joint or frame,
            or a topology the cut into limbs refuses (the message names the culprit).
    """
    tree = tree_from_constraint_models(model, constraint_models, actuated, task_frame, home=home, name=name)
    m = tree.model
    pairs = tuple(lp.frame_names for lp in tree.loops)
    side = Sidecar(loops=pairs, types=tuple(lp.kind for lp in tree.loops), motors=tuple(actuated))
    f = m.frames[tree.task_frame]
    platform = f.name
    if f.type != pin.FrameType.BODY:  # the cut wants a link: the body frame of the task frame's joint
        platform = next(
            (fr.name for fr in m.frames if fr.type == pin.FrameType.BODY and fr.parentJoint == f.parentJoint),
            f.name,
        )
    cut = cut_tree(m, side, platform, limb_names, tree.name, loop_names=[lp.name for lp in tree.loops])
    q = tree.home
    home_map: Mapping[str, float] = {n: float(q[k]) for k, n in enumerate(m.names[1:]) if q[k] != 0.0}
    return cut_limbs(m, None, cut, home_map, tree.name), tree
