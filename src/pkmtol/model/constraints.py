"""The mechanism for Pinocchio 4's constraint API: one ``pin.Model`` of all limbs, an anchor per loop.

pkmtol keeps a mechanism as serial limbs that all end in the platform frame O'. Pinocchio 4's
constrained dynamics and solvers (``constraintDynamics``, the ADMM solver, ``getConstraintsJacobian``)
want the other form: one kinematic tree and the loops as constraint models. :func:`constraint_models`
builds it from the limbs as they are (nominal, or perturbed by
:func:`~pkmtol.kinematics.perturbation.perturbed_limb_models`):

* the tree: every limb's joints under the common root, in limb order, with the limb's joint
  models, placements, limits, inertias, armature, damping and friction, so that
  ``q = concatenate(limb q's)`` — the order of :attr:`pkmtol.kinematics.closed_chain.Pose.q_all`;
  the frames of every limb (the base's from limb 1 only; a name used twice gets the limb's name in
  front, ``limb2/platform``);
* one ``FrameAnchorConstraintModel`` per limb after the first: ``joint1`` is that limb's last joint
  with its platform frame's placement, ``joint2`` the reference limb's last joint with its platform
  frame's placement. The loop is closed when the two frames coincide; Pinocchio's residual is
  ``log6(oMc1⁻¹ · oMc2)`` (6, ``[v; ω]`` in frame c1);
* then one constraint per internal loop of a limb (limb order, ``name`` ``<limb>.<loop>``): a
  ``FrameAnchorConstraintModel`` (``6d``) or a ``PointAnchorConstraintModel`` (``3d``, residual
  ``R_a⁻¹ (p_b − p_a)``, 3 in frame a) with ``joint1`` frame a's joint and placement, ``joint2``
  frame b's.

The platform's own inertia is counted once: limb URDFs each carry the platform link (Pinocchio adds
its inertia to the last joint), so a loop limb's last body gives back the inertia of the platform
frame and of every frame below it; the reference limb keeps it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError, URDFError
from pkmtol.model.limb import Limb


class MechanismLimbs(Protocol):
    """What :func:`constraint_models` needs of a mechanism: its name and its limbs (reference limb first)."""

    @property
    def name(self) -> str:
        """Mechanism name."""
        ...

    @property
    def limbs(self) -> tuple[Limb, ...]:
        """The limbs; limb 0 holds the platform."""
        ...


@dataclass(frozen=True, eq=False)
class ConstrainedModel:
    """A mechanism as one Pinocchio model and its loop-closure constraints.

    Attributes:
        model: All limbs' joints under one root (frame K), limb after limb; ``nq == nv``.
        constraints: One ``pin.FrameAnchorConstraintModel`` per limb after the first (see the
            module docstring for ``joint1`` / ``joint2``; ``name`` is the limb's name), then one
            frame or point anchor per internal loop of a limb (``name`` ``<limb>.<loop>``).
        limb_names: The limbs, reference limb first.
        q_slices: Per limb, its entries in ``q`` (and ``v``).
        actuated: Indices into ``q`` (and ``v``) of the actuated joints, limb order.
        platform_frames: Per limb, the frame id in :attr:`model` of that limb's platform frame
            (limb 0's is the platform frame O').
        frame_maps: Per limb, its frame ids → frame ids in :attr:`model` (the base's frames of a
            limb after the first map to limb 1's).
    """

    model: pin.Model
    constraints: tuple[Any, ...]
    limb_names: tuple[str, ...]
    q_slices: tuple[slice, ...]
    actuated: tuple[int, ...]
    platform_frames: tuple[int, ...]
    frame_maps: tuple[dict[int, int], ...] = ()

    @property
    def platform_frame(self) -> int:
        """Frame id of the platform frame O' (the reference limb's)."""
        return self.platform_frames[0]

    def q(self, limb_q: Sequence[np.ndarray]) -> np.ndarray:
        """``q`` of the model from the limbs' joint values (e.g. ``Pose.q``), shape (nq,) [rad or m].

        Raises:
            InvalidRequestError: not one vector per limb of that limb's size.
        """
        sizes = [s.stop - s.start for s in self.q_slices]
        if isinstance(limb_q, str | bytes | dict) or not isinstance(limb_q, Sequence | np.ndarray):
            raise InvalidArgumentError(
                "limb_q", limb_q, f"expected one joint vector per limb, of sizes {sizes}"
            )
        if len(limb_q) != len(self.q_slices):
            raise InvalidRequestError(f"need one joint vector per limb of sizes {sizes}")
        return np.concatenate(
            [values.vector(f"limb_q[{k}]", x, n) for k, (x, n) in enumerate(zip(limb_q, sizes, strict=True))]
        )

    def _q_data(self, q: Any, data: Any) -> tuple[np.ndarray, Any]:
        """``q`` checked (nq,) and ``data`` (a new ``pin.Data`` if None)."""
        q = values.vector("q", q, self.model.nq)
        values.optional(
            values.instance, "data", data, pin.Data, "a pin.Data of this model (model.createData())"
        )
        return q, self.model.createData() if data is None else data

    def constraint_vector(self) -> Any:
        """The constraints as a ``pin.StdVec_ConstraintModel`` (for ``getConstraintsJacobian``, ADMM)."""
        out = pin.StdVec_ConstraintModel()
        for c in self.constraints:
            out.append(pin.ConstraintModel(c))
        return out

    def rigid_constraints(self) -> list[Any]:
        """The constraints as legacy ``pin.RigidConstraintModel`` (6D or 3D), for ``constraintDynamics``.

        Converted by ``pin.convertToRigidConstraintModel``. Their Jacobian is minus the
        ``FrameAnchorConstraintModel``'s, and ``pin.getConstraintsJacobian`` gives it only after each
        model's ``calc`` has filled its data (with fresh datas it returns another matrix, silently).
        """
        return [pin.convertToRigidConstraintModel(self.model, c) for c in self.constraints]

    def residuals(self, q: np.ndarray, data: Any = None) -> np.ndarray:
        """Pinocchio's constraint residuals at ``q`` (each loop's ``constraint_position_error``).

        Shape (6·(L−1) + Σ loop rows,): a frame anchor's block is ``log6(oMc1⁻¹ · oMc2)`` [m, rad],
        a point anchor's ``R_1⁻¹ (p_2 − p_1)`` [m] (``calc`` after ``forwardKinematics``).
        """
        q, data = self._q_data(q, data)
        pin.forwardKinematics(self.model, data, q)
        out = []
        for c in self.constraints:
            cd = c.createData()
            c.calc(self.model, data, cd)
            out.append(np.array(cd.constraint_position_error))
        return np.concatenate(out) if out else np.zeros(0)

    def jacobian(self, q: np.ndarray, data: Any = None) -> np.ndarray:
        """Pinocchio's constraint Jacobian at ``q`` (``getConstraintsJacobian``), shape (rows, nv).

        At a closed configuration it is the derivative of :meth:`residuals`.
        """
        q, data = self._q_data(q, data)
        models = self.constraint_vector()
        datas = pin.StdVec_ConstraintData()
        for cm in models:
            datas.append(cm.createData())
        pin.computeJointJacobians(self.model, data, q)
        for cm, cd in zip(models, datas, strict=True):
            cm.calc(self.model, data, cd)
        return np.array(pin.getConstraintsJacobian(self.model, data, models, datas))


def constraint_models(
    mechanism: MechanismLimbs, models: Sequence[pin.Model] | None = None
) -> ConstrainedModel:
    """The mechanism as one Pinocchio model plus one ``FrameAnchorConstraintModel`` per loop.

    Args:
        mechanism: The mechanism (a :class:`~pkmtol.model.mechanism.Mechanism`).
        models: Replacement limb models of the same structure, e.g. perturbed ones
            (:func:`~pkmtol.kinematics.perturbation.perturbed_limb_models`); default: the limbs'.

    Returns:
        The model and constraints; a closed-chain configuration of the limbs (``Pose.q``) maps to
        the model's ``q`` by :meth:`ConstrainedModel.q` and makes every residual zero.

    Raises:
        URDFError: a replacement model does not match its limb (joint count or names).
    """
    limbs = getattr(mechanism, "limbs", None)
    if not isinstance(limbs, tuple) or len(limbs) < 2 or not all(isinstance(lb, Limb) for lb in limbs):
        raise InvalidArgumentError(
            "mechanism", mechanism, "expected a pkmtol.Mechanism (pkmtol.load_mechanism)"
        )
    if models is not None:
        values.instances("models", models, pin.Model, "pin.Model")
    lms = list(models) if models is not None else [lb.model for lb in limbs]
    if len(lms) != len(limbs):
        raise URDFError(limbs[0].name, None, f"{len(lms)} limb models for {len(limbs)} limbs")
    for limb, lm in zip(limbs, lms, strict=True):
        if tuple(lm.names[1:]) != limb.joint_names:
            raise URDFError(limb.name, None, "the replacement model's joints are not the limb's")
    joint_names = [n for lb in limbs for n in lb.joint_names]
    prefix = len(set(joint_names)) != len(joint_names)
    m = pin.Model()
    m.name = mechanism.name
    used: set[str] = {f.name for f in m.frames}
    last_joint, platform_frames, q_slices, actuated = [], [], [], []
    frame_maps: list[dict[int, int]] = []
    base_frames: dict[str, int] = {}
    inner: list[Any] = []  # the limbs' internal loops, after the limbs' closures on the platform
    for i, (limb, lm) in enumerate(zip(limbs, lms, strict=True)):
        jmap = {0: 0}
        start = m.nq
        give_back = _platform_inertia(lm, limb.platform_frame) if i > 0 else pin.Inertia.Zero()
        for j in range(1, lm.njoints):
            jm = lm.joints[j]
            iq, iv = jm.idx_q, jm.idx_v
            name = f"{limb.name}/{lm.names[j]}" if prefix else lm.names[j]
            jid = m.addJoint(
                jmap[lm.parents[j]],
                jm,
                lm.jointPlacements[j],
                name,
                lm.effortLimit[iv : iv + jm.nv],
                lm.velocityLimit[iv : iv + jm.nv],
                lm.lowerPositionLimit[iq : iq + jm.nq],
                lm.upperPositionLimit[iq : iq + jm.nq],
            )
            inertia = lm.inertias[j] - give_back if j == lm.njoints - 1 else lm.inertias[j]
            m.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
            nv = m.joints[jid].idx_v
            for vec in ("armature", "damping", "friction"):
                getattr(m, vec)[nv : nv + jm.nv] = getattr(lm, vec)[iv : iv + jm.nv]
            jmap[j] = jid
        fmap = {0: 0}
        for fid, f in enumerate(lm.frames):
            if fid and i > 0 and f.parentJoint == 0:
                fmap[fid] = base_frames.get(f.name, 0)
                continue
            if fid == 0:
                continue
            parent = fmap.get(f.parentFrame, 0)
            if f.type == pin.FrameType.JOINT:
                fmap[fid] = m.addJointFrame(jmap[f.parentJoint], parent)
                continue
            name = f.name if f.name not in used and not (i > 0 and fid == limb.platform_frame) else ""
            name = name or f"{limb.name}/{f.name}"
            inertia = f.inertia if i == 0 or not _below(lm, fid, limb.platform_frame) else pin.Inertia.Zero()
            fmap[fid] = m.addFrame(
                pin.Frame(name, jmap[f.parentJoint], parent, f.placement, f.type, inertia), False
            )
            used.add(name)
            if i == 0 and f.parentJoint == 0:
                base_frames[f.name] = fmap[fid]
        last_joint.append(jmap[lm.frames[limb.platform_frame].parentJoint])
        platform_frames.append(fmap[limb.platform_frame])
        for lp in limb.loops:  # frame a is joint1's side, frame b joint2's: residual of a → b
            fa, fb = lm.frames[lp.frame_a], lm.frames[lp.frame_b]
            anchor = pin.FrameAnchorConstraintModel if lp.kind == "6d" else pin.PointAnchorConstraintModel
            c = anchor(m, jmap[fa.parentJoint], fa.placement, jmap[fb.parentJoint], fb.placement)
            c.name = f"{limb.name}.{lp.name}"
            inner.append(c)
        q_slices.append(slice(start, m.nq))
        actuated += [start + a for a in limb.actuated]
        frame_maps.append(fmap)
    constraints = []
    ref = lms[0].frames[limbs[0].platform_frame].placement
    for i in range(1, len(limbs)):
        placement = lms[i].frames[limbs[i].platform_frame].placement
        c = pin.FrameAnchorConstraintModel(m, last_joint[i], placement, last_joint[0], ref)
        c.name = limbs[i].name
        constraints.append(c)
    return ConstrainedModel(
        model=m,
        constraints=tuple(constraints + inner),
        limb_names=tuple(lb.name for lb in limbs),
        q_slices=tuple(q_slices),
        actuated=tuple(actuated),
        platform_frames=tuple(platform_frames),
        frame_maps=tuple(frame_maps),
    )


def _below(model: pin.Model, fid: int, platform: int) -> bool:
    """Whether frame ``fid`` is the platform frame, its fixed-joint frame, or hangs below the platform."""
    pf = model.frames[platform]
    if fid == platform or (fid == pf.parentFrame and model.frames[fid].type == pin.FrameType.FIXED_JOINT):
        return True
    f = model.frames[fid]
    while f.parentFrame != 0 and f.parentJoint == pf.parentJoint:
        if f.parentFrame == platform:
            return True
        f = model.frames[f.parentFrame]
    return False


def _platform_inertia(model: pin.Model, platform: int) -> pin.Inertia:
    """The inertia, in the last joint's frame, of the platform frame and the frames below it."""
    total = pin.Inertia.Zero()
    for fid, f in enumerate(model.frames):
        if fid and _below(model, fid, platform):
            total += f.placement.act(f.inertia)
    return total
