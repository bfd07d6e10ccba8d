"""Perturbed limb models: joint-placement, platform-attachment and loop errors applied to copies of the limbs.

Geometric errors enter as ``jointPlacements[j] · exp6(ε_j)``, the platform attachment
``placement · exp6(ε_e)``, each internal loop's frame b ``placement · exp6(ε_loop)`` and joint zero
offsets ``q_actual = q + δq`` (the offsets are applied by
:meth:`pkmtol.kinematics.closed_chain.ClosedChain.forward`; DESIGN.md, "Geometric error parameters").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.model.mechanism import Mechanism


def perturbed_limb_models(mechanism: Mechanism, eps: Sequence[np.ndarray]) -> list[pin.Model]:
    """Copies of the limb models with joint-placement and platform-attachment errors.

    Args:
        mechanism: The nominal mechanism.
        eps: Per limb, shape (nq_i + 1 + loops_i, 6) (``Limb.n_origins`` rows): ``ε`` of each
            joint origin, of the platform attachment, then of each loop's frame b, each
            ``(dx, dy, dz, rx, ry, rz)`` in that origin's frame [m, rad].

    Returns:
        Models with ``jointPlacements[j] · exp6(ε_j)``, platform frame ``placement · exp6(ε_e)``
        and loop frames ``placement · exp6(ε_loop)``.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism")
    if (
        isinstance(eps, str | bytes | dict)
        or not isinstance(eps, Sequence | np.ndarray)
        or len(eps) != len(mechanism.limbs)
    ):
        raise InvalidArgumentError("eps", eps, f"need {len(mechanism.limbs)} arrays, one per limb")
    eps = [
        values.array_of_shape(f"eps[{i}]", e, (limb.n_origins, 6))
        for i, (limb, e) in enumerate(zip(mechanism.limbs, eps, strict=True))
    ]
    out = []
    for limb, e in zip(mechanism.limbs, eps, strict=True):
        if not e.any():
            out.append(limb.model)  # unperturbed limbs are shared, never modified
            continue
        m = limb.model.copy()
        for j in range(1, m.njoints):
            m.jointPlacements[j] = limb.model.jointPlacements[j] * pin.exp6(e[j - 1])
        delta = pin.exp6(e[limb.nq])
        for fid in limb.attach_frames:
            fr = m.frames[fid]
            fr.placement = limb.model.frames[fid].placement * delta
            m.frames[fid] = fr
        for k, lp in enumerate(limb.loops):
            fr = m.frames[lp.frame_b]
            fr.placement = limb.model.frames[lp.frame_b].placement * pin.exp6(e[limb.nq + 1 + k])
            m.frames[lp.frame_b] = fr
        out.append(m)
    return out
