"""The frames a batched solve reads at each Newton iterate, and the perturbed machines behind them.

:class:`BatchFrames` gives :class:`~pkmtol.kinematics.batch.BatchChain` every limb's platform frame
(placement and LOCAL Jacobian) and each internal loop's frames a and b (the order of
:attr:`ClosedChain.frame_tables <pkmtol.kinematics.closed_chain.ClosedChain.frame_tables>`), for many
problems at once:
from the compiled kernels (:mod:`pkmtol.kinematics.frame_tables`, the ``fast`` extra) or from
Pinocchio, one ``Data`` per limb reused for every pose. A perturbed machine (the exact
verification, a calibration study) is a table of joint placements ``jointPlacements[j] · exp6(ε_j)``
for the kernels, or a scratch slot model whose placements are written in place for Pinocchio (no
``Model`` copy and no ``createData`` per sample); the platform attachment error ``exp6(ε_e)`` and
the loops' frame-b errors are applied in numpy either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from pkmtol.kinematics import acceleration, se3_batch
from pkmtol.kinematics.closed_chain import ClosedChain

#: A loop's frames over a batch: ``(oMa, oMb, J_a, J_b)``, (b, 4, 4) and (b, 6, nq) each.
LoopFrames = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class Perturbation(NamedTuple):
    """The machines of a batch's problems (:meth:`BatchFrames.perturb`).

    Attributes:
        models: Per limb, each problem's model (the Pinocchio path; None with the kernels).
        table: Shape (B, n, 4, 4): each problem's joint placements (the kernels; else None).
        joint_eps: Shape (B, n, 6): the joint placement errors behind ``table`` (else None).
        attach: Per limb, ``exp6(ε_e)`` (B, 4, 4) of the platform attachment, or None.
        loops: Per limb, per internal loop, ``exp6(ε)`` (B, 4, 4) of its frame b, or None.
    """

    models: list[list[pin.Model]] | None
    table: np.ndarray | None
    joint_eps: np.ndarray | None
    attach: list[np.ndarray | None]
    loops: list[list[np.ndarray | None]]


class Evaluation(NamedTuple):
    """The frames of a batch at one Newton iterate.

    Attributes:
        placements: Shape (L, b, 4, 4): each limb's platform placement in K.
        jacobians: Per limb, shape (b, 6, nq_i): its LOCAL Jacobian (a view of ``padded``).
        loop_frames: Per limb, per internal loop, ``(oMa, oMb, J_a, J_b)``.
        padded: Shape (L, b, 6, w): the Jacobians, zero-padded to the widest limb.
    """

    placements: np.ndarray
    jacobians: list[np.ndarray]
    loop_frames: list[list[LoopFrames]]
    padded: np.ndarray


class BatchFrames:
    """The frames of one mechanism's limbs for batches of problems (not thread-safe: reused workspaces).

    Args:
        chain: The per-pose solver whose limb models (nominal, or replacements) and ``Data`` (one
            per limb, reused for every pose) to evaluate; its frame tables are built on the first
            use of the kernels, once.
    """

    def __init__(self, chain: ClosedChain) -> None:
        self.mechanism = chain.mechanism
        self.models = chain.models
        self.datas = chain.datas
        self.fids = chain.fids
        self._chain = chain
        self._cols = [
            slice(int(a), int(b)) for a, b in zip(chain.offsets[:-1], chain.offsets[1:], strict=True)
        ]
        self._width = max(limb.nq for limb in self.mechanism.limbs)
        # the scratch models of each slot: a perturbed limb of slot s runs on _slots[i][s]
        self._slots: list[list[pin.Model]] = [[] for _ in self.models]

    def perturb(self, eps: Sequence[np.ndarray], count: int) -> Perturbation:
        """The machines of ``count`` problems: joint placements, attachment and loop-frame errors.

        With the compiled kernels the joint placements are a table (count, n, 4, 4); without, each
        perturbed problem's limbs are scratch slot models whose placements are written in place.
        ``attach`` is ``exp6(ε_e)`` of shape (count, 4, 4) per limb (None when no problem perturbs
        the attachment), ``loops`` the same per loop's frame b.
        """
        kernels = acceleration.kernels()
        models: list[list[pin.Model]] | None = None if kernels is not None else []
        joint_eps, attach, loops = [], [], []
        for i, (limb, e) in enumerate(zip(self.mechanism.limbs, eps, strict=True)):
            e = np.asarray(e, dtype=float).reshape(count, limb.n_origins, 6)
            if models is None:
                joint_eps.append(e[:, : limb.nq])
            else:
                models.append(self._slot_models(i, e[:, : limb.nq]))
            deltas: list[np.ndarray | None] = []
            for k in range(limb.nq, limb.n_origins):  # the attachment, then each loop's frame b
                hit = e[:, k].any()
                deltas.append(
                    np.array([pin.exp6(e[s, k]).homogeneous for s in range(count)]) if hit else None
                )
            attach.append(deltas[0])
            loops.append(deltas[1:])
        if kernels is None:
            return Perturbation(models, None, None, attach, loops)
        every = np.concatenate(joint_eps, axis=1)
        return Perturbation(None, self._chain.frame_tables.perturbed(kernels, every), every, attach, loops)

    def slots_of(self, perturbation: Perturbation | None, index: np.ndarray) -> Perturbation | None:
        """The perturbation of problems ``index`` with slot models (for Pinocchio's kinematics).

        Made with the kernels (:meth:`perturb`), the joint errors are in ``joint_eps`` and the
        slots are written from them; made without, the problems' slot models are taken as they are.
        """
        if perturbation is None:
            return None
        if perturbation.joint_eps is not None:
            e = perturbation.joint_eps[index]
            models = [self._slot_models(i, e[:, cols]) for i, cols in enumerate(self._cols)]
        else:
            models = [[ms[k] for k in index] for ms in perturbation.models or []]
        return Perturbation(
            models,
            None,
            None,
            [None if a is None else a[index] for a in perturbation.attach],
            [[None if d is None else d[index] for d in loops] for loops in perturbation.loops],
        )

    def _slot_models(self, i: int, e: np.ndarray) -> list[pin.Model]:
        """Limb ``i``'s model of each problem: its nominal one, or a slot with ``placement · exp6(ε)``."""
        nominal = self.models[i]
        slots = self._slots[i]
        while len(slots) < len(e):
            slots.append(nominal.copy())
        models = []
        hit = np.asarray(e.any(axis=(1, 2)), dtype=bool)
        for s in range(len(e)):
            if not hit[s]:
                models.append(nominal)
                continue
            m = slots[s]
            for j in range(1, nominal.njoints):
                m.jointPlacements[j] = nominal.jointPlacements[j] * pin.exp6(e[s, j - 1])
            models.append(m)
        return models

    def evaluate(
        self, q: np.ndarray, idx: np.ndarray, perturbation: Perturbation | None, by_pinocchio: bool = False
    ) -> Evaluation:
        """The platform frames, their Jacobians and the loop frames of problems ``idx`` at ``q``.

        The frames come from the compiled kernels (:mod:`pkmtol.kinematics.frame_tables`) or from
        Pinocchio; the errors of the platform attachment and of the loops' frames b are applied
        after, in numpy. ``by_pinocchio`` asks for Pinocchio's frames even with the kernels.
        """
        kernels = None if by_pinocchio else acceleration.kernels()
        if kernels is not None:
            if perturbation is not None and perturbation.table is not None:
                table, which = perturbation.table, np.arange(len(q), dtype=np.int64)
            else:
                table, which = self._chain.frame_tables.placements, np.zeros(len(q), dtype=np.int64)
            h, padded_all = self._chain.frame_tables.evaluate(kernels, q, idx, table, which)
        else:
            h, padded_all = self._frames_by_pinocchio(q, idx, perturbation)
        n_limbs = len(self.models)
        placements, padded = h[:n_limbs], padded_all[:n_limbs]
        jacobians, loop_frames = [], []
        at = n_limbs  # the loop frames follow the platform frames: a, b of each loop, limb by limb
        for i, limb in enumerate(self.mechanism.limbs):
            jac = padded[i, :, :, : limb.nq]
            attach = perturbation.attach[i] if perturbation is not None else None
            if attach is not None:
                placements[i], jac[...] = moved(placements[i], jac, attach[idx])
            jacobians.append(jac)
            frames = []
            for n, lp in enumerate(limb.loops):
                ha, hb = h[at], h[at + 1]
                ja, jb = padded_all[at, :, :, : limb.nq], padded_all[at + 1, :, :, : limb.nq]
                at += 2
                delta = perturbation.loops[i][n] if perturbation is not None else None
                if delta is not None:
                    hb, jb = moved(hb, jb, delta[idx])
                if attach is not None and lp.frame_a in limb.attach_frames:
                    ha, ja = moved(ha, ja, attach[idx])
                frames.append((ha, hb, ja, jb))
            loop_frames.append(frames)
        return Evaluation(placements, jacobians, loop_frames, padded)

    def _frames_by_pinocchio(
        self, q: np.ndarray, idx: np.ndarray, perturbation: Perturbation | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The frames in the kernels' order by Pinocchio: (F, b, 4, 4) and (F, b, 6, w).

        The per-pose loop is the numpy path's hot spot: Pinocchio's functions bound once, each
        limb's joint values sliced once, the pose's model picked up front, and a limb without
        internal loops (the usual case) reads its platform frame alone.
        """
        n_frames = len(self.fids) + 2 * sum(len(limb.loops) for limb in self.mechanism.limbs)
        h = np.empty((n_frames, len(idx), 4, 4))
        padded = np.zeros((n_frames, len(idx), 6, self._width))
        joint_jacobians, frame_placement = pin.computeJointJacobians, pin.updateFramePlacement
        frame_jacobian, local = pin.getFrameJacobian, pin.LOCAL
        at = len(self.models)
        for i, (model, data, fid, cols, limb) in enumerate(
            zip(self.models, self.datas, self.fids, self._cols, self.mechanism.limbs, strict=True)
        ):
            q_limb = q[idx, cols]
            if perturbation is None or perturbation.models is None:
                models = [model] * len(idx)
            else:
                models = [perturbation.models[i][k] for k in idx]
            hs: list[np.ndarray] = []
            js: list[np.ndarray] = []
            lf: list[list[np.ndarray]] = [[] for _ in range(4 * len(limb.loops))]
            if not limb.loops:
                add_h, add_j = hs.append, js.append
                for m, qk in zip(models, q_limb, strict=True):
                    joint_jacobians(m, data, qk)
                    add_h(frame_placement(m, data, fid).homogeneous)
                    add_j(frame_jacobian(m, data, fid, local))
            else:
                for m, qk in zip(models, q_limb, strict=True):
                    joint_jacobians(m, data, qk)
                    hs.append(frame_placement(m, data, fid).homogeneous)
                    js.append(frame_jacobian(m, data, fid, local))
                    for n, lp in enumerate(limb.loops):
                        for side, f in enumerate((lp.frame_a, lp.frame_b)):
                            lf[4 * n + side].append(frame_placement(m, data, f).homogeneous)
                            lf[4 * n + 2 + side].append(frame_jacobian(m, data, f, local))
            h[i] = hs
            padded[i, :, :, : limb.nq] = js
            for n in range(len(limb.loops)):
                for side in range(2):
                    h[at + side] = lf[4 * n + side]
                    padded[at + side, :, :, : limb.nq] = lf[4 * n + 2 + side]
                at += 2
        return h, padded


def one(perturbation: Perturbation | None, k: int) -> Perturbation | None:
    """The perturbation of problem ``k`` alone (as problem 0)."""
    if perturbation is None:
        return None
    return Perturbation(
        None if perturbation.models is None else [[models[k]] for models in perturbation.models],
        None if perturbation.table is None else perturbation.table[k : k + 1],
        None if perturbation.joint_eps is None else perturbation.joint_eps[k : k + 1],
        [None if a is None else a[k : k + 1] for a in perturbation.attach],
        [[None if d is None else d[k : k + 1] for d in loops] for loops in perturbation.loops],
    )


def moved(h: np.ndarray, jac: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frames ``h`` (b, 4, 4) and their LOCAL Jacobians (b, 6, k) moved by ``delta`` (b, 4, 4), local."""
    return h @ delta, se3_batch.act_inverse(delta[:, :3, :3], delta[:, :3, 3], jac)
