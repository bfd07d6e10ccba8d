"""Perturbed limb models: joint-placement and platform-attachment errors applied to copies of the limbs.

Geometric errors enter as ``jointPlacements[j] · exp6(ε_j)``, the platform attachment
``placement · exp6(ε_e)`` and joint zero offsets ``q_actual = q + δq`` (the offsets are applied by
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
        eps: Per limb, shape (nq_i + 1, 6): ``ε`` of each joint origin then of the platform
            attachment, each ``(dx, dy, dz, rx, ry, rz)`` in that origin's frame [m, rad].

    Returns:
        Models with ``jointPlacements[j] · exp6(ε_j)`` and platform frame ``placement · exp6(ε_e)``.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism")
    if isinstance(eps, str) or len(eps) != len(mechanism.limbs):
        raise InvalidArgumentError("eps", eps, f"need {len(mechanism.limbs)} arrays, one per limb")
    out = []
    for limb, e in zip(mechanism.limbs, eps, strict=True):
        e = np.asarray(e, dtype=float)
        if not e.any():
            out.append(limb.model)  # unperturbed limbs are shared, never modified
            continue
        m = limb.model.copy()
        for j in range(1, m.njoints):
            m.jointPlacements[j] = limb.model.jointPlacements[j] * pin.exp6(e[j - 1])
        delta = pin.exp6(e[-1])
        ids = {limb.platform_frame}
        if m.existFrame(limb.attach_name):
            ids.add(m.getFrameId(limb.attach_name))
        for fid in ids:
            fr = m.frames[fid]
            fr.placement = limb.model.frames[fid].placement * delta
            m.frames[fid] = fr
        out.append(m)
    return out
