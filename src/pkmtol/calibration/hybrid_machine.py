"""A hybrid machine with given errors for the calibration: the module and the tool chain, exact.

The calibration's :class:`~pkmtol.calibration.machine.Machine` of a mechanism with a ``[tool]``
chain (``Machine(...)`` returns this class for it). Its joints are the module's then the tool
chain's (``q`` of :func:`pkmtol.calibration.maps.pose_maps` for a hybrid), its commands the
module's actuators then the wrist's, and its "platform" is the TCP frame: ``forward_many`` gives
the TCP's placement, ``inverse_many`` the commands that put the TCP at a target with the tool
along the target axis (the axis of the nominal machine at the guess, so the controller aims at
the pose the task asked for). Errors: the module's part of ``delta`` perturbs the limbs, the tool
part the tool chain's placements and zero offsets (as :mod:`pkmtol.error_model.tool_exact`).
Commands are readings: a joint's actual value is its reading plus its zero offset; a locked wrist
joint sits at its set value (``Tool.home``) plus its offset. With ``[calibration] tracker_on =
"nose"`` the tracker's targets sit on the spindle: ``forward_many``'s frame is then the TCP frame
without the tool's own errors (the targets in the TCP frame, the nose at ``(0, 0, −L)``), and its
``task_*`` fields are the TCP's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.tool_chain import HybridParameterSet
from pkmtol.error_model.tool_sweep import tracker_on
from pkmtol.exceptions import InvalidRequestError, KinematicsError
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.kinematics.hybrid import HybridChain, HybridPose
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.kinematics.tool_chain import ToolKinematics, perturbed_tool_model, split_tool_eps
from pkmtol.model.mechanism import Mechanism

#: The nominal solvers of the mechanisms seen (the controller's target axes come from them).
_NOMINAL: dict[int, tuple[Mechanism, HybridChain]] = {}
#: How many requests of :func:`nominal_poses` are kept.
_POSES_KEPT = 8
_POSES: dict[tuple[int, tuple[int, ...], bytes], tuple[Mechanism, tuple[HybridPose, ...]]] = {}


@dataclass(frozen=True, eq=False)
class HybridSolutions:
    """Solved poses of a hybrid machine, ``B`` problems (the fields of ``Solutions`` the calibration reads).

    Attributes:
        q: Shape (B, N + nq_t): actual joint values, the module's then the tool chain's.
        rotation: Shape (B, 3, 3): the orientation in K of the frame the tracker's targets sit on:
            the TCP frame, or with the tracker on the spindle nose the spindle's frame at the TCP
            (the TCP frame without the tool's own errors).
        translation: Shape (B, 3): that frame's origin in K [m].
        errors: Per problem, the error that stopped it (None: solved).
        task_translation: Shape (B, 3): the TCP in K [m] (None: :attr:`translation`).
        task_rotation: Shape (B, 3, 3): the TCP frame's orientation (None: :attr:`rotation`).
    """

    q: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    errors: tuple[KinematicsError | None, ...]
    task_translation: np.ndarray | None = None
    task_rotation: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.task_translation is None:
            object.__setattr__(self, "task_translation", self.translation)
        if self.task_rotation is None:
            object.__setattr__(self, "task_rotation", self.rotation)

    @property
    def p_m(self) -> np.ndarray:
        """Shape (B, 3): the TCP in K [m] (the task point)."""
        assert self.task_translation is not None
        return self.task_translation

    @property
    def ok(self) -> np.ndarray:
        """Shape (B,): which problems were solved."""
        return np.array([e is None for e in self.errors], dtype=bool)


class HybridMachine:
    """The hybrid machine perturbed by ``delta`` (n,) of a :class:`HybridParameterSet`.

    Raises:
        InvalidRequestError: ``pset`` lacks the tool chain's parameters.
    """

    def __init__(self, mechanism: Mechanism, pset: ParameterSet, delta: np.ndarray) -> None:
        if mechanism.tool is None or not isinstance(pset, HybridParameterSet):
            raise InvalidRequestError(
                f"'{mechanism.name}': a hybrid machine's calibration needs its parameter set with the "
                "tool chain's parameters (pkmtol.error_model.task.machine_parameter_set)"
            )
        self.mechanism = mechanism
        self.pset = pset
        self.tool = mechanism.tool
        self.delta = np.asarray(delta, dtype=float).copy()
        eps, module_offsets = pset.module_set().perturbation(self.delta[: pset.module_count], mechanism)
        t_eps, tool_offsets = split_tool_eps(pset.tool_raw(self.delta), self.tool)
        module = ClosedChain(mechanism, models=perturbed_limb_models(mechanism, eps), check_limits=False)
        tool_model = perturbed_tool_model(self.tool, t_eps)
        self.chain = HybridChain(mechanism, module, tool_model, check_limits=False)
        self.kinematics = ToolKinematics(self.tool, tool_model)
        # with the tracker on the spindle nose, its targets do not see the TCP frame's own errors
        on_nose = tracker_on(mechanism) == "nose"
        self._spindle = self._spindle_frame(t_eps[self.tool.nq]) if on_nose else None
        self.nq_module = int(module_offsets.size)
        self.module_actuated = np.asarray(module.actuated_idx, dtype=int)
        self.tool_actuated = list(self.tool.actuated)
        self.offsets = np.concatenate([module_offsets, tool_offsets])
        self.actuated_idx = np.concatenate(
            [self.module_actuated, self.nq_module + np.asarray(self.tool_actuated, dtype=int)]
        )

    def _spindle_frame(self, eps_tcp: np.ndarray) -> pin.SE3:
        """The spindle's frame at the TCP relative to the TCP frame: ``exp6(ε_t)⁻¹ exp6(ε_t − ε_tool)``.

        ``ε_t`` is the TCP frame's whole placement error, ``ε_tool`` the part of the tool's own
        parameters (``tool.*``); the rest (a D–H wrist's nose-link errors) moves the spindle too.
        """
        pset = self.pset
        assert isinstance(pset, HybridParameterSet)
        own = np.array([pset.sub_assembly(i) == "tool" for i in range(len(pset))])
        eps_tool = split_tool_eps(pset.tool_raw(np.where(own, self.delta, 0.0)), self.tool)[0][self.tool.nq]
        eps = np.asarray(eps_tcp, dtype=float)
        return pin.exp6(pin.Motion(eps)).inverse() * pin.exp6(pin.Motion(eps - eps_tool))

    def forward_many(self, commands: np.ndarray, q0: np.ndarray) -> HybridSolutions:
        """The TCP placements at readings ``commands`` (B, f + w), guesses ``q0`` (B, N + nq_t).

        A problem the module cannot solve has its error in ``errors`` (nothing raised).
        """
        u = np.atleast_2d(np.asarray(commands, dtype=float))
        guess = np.atleast_2d(np.asarray(q0, dtype=float))
        f, n0 = self.module_actuated.size, self.nq_module
        offsets = np.broadcast_to(self.offsets[:n0], (len(u), n0))
        mod = self.chain.batch.forward(u[:, :f], guess[:, :n0], offsets)
        qt = np.tile(self.tool.home, (len(u), 1))
        qt[:, self.tool_actuated] = u[:, f:]
        qt = qt + self.offsets[n0:]
        rt, pt, _ = self.kinematics.frames(qt)
        rot = np.einsum("bij,bjk->bik", mod.rotation, rt)
        pos = mod.translation + np.einsum("bij,bj->bi", mod.rotation, pt)
        q = np.hstack([mod.q, qt])
        if self._spindle is None:
            return HybridSolutions(q=q, rotation=rot, translation=pos, errors=mod.errors)
        s = self._spindle  # TCP · exp6(ε_t)⁻¹: the spindle's frame at the TCP
        return HybridSolutions(
            q=q,
            rotation=rot @ s.rotation,
            translation=pos + rot @ s.translation,
            errors=mod.errors,
            task_translation=pos,
            task_rotation=rot,
        )

    def inverse_many(self, targets_m: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, HybridSolutions]:
        """Readings (B, f + w) that put the TCP at ``targets_m`` (B, 3), the tool along the target axis.

        ``q0`` (B, N + nq_t) are nominal joint values at the targets: the nominal machine's tool
        axis there is the target axis (the spin about it is free), and its poses start the solve.
        Rows of unsolved problems are NaN; their errors are in the solutions.
        """
        targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
        q_nominal = np.atleast_2d(np.asarray(q0, dtype=float))
        nominal = nominal_poses(self.mechanism, q_nominal)
        axes = None if self.mechanism.tool_directions is None else np.array([g.axis for g in nominal])
        # the guesses: this machine's module solved at the nominal P, the wrist at its nominal joints
        # (a guess the solver takes as evaluated, so it must be this machine's own configuration)
        n0 = self.nq_module
        mod = self.chain.batch.inverse(np.array([g.module.p_m for g in nominal]), q_nominal[:, :n0])
        guesses: list[HybridPose] = []
        failed: dict[int, KinematicsError] = {}
        for k, g in enumerate(nominal):
            err = mod.errors[k]
            if err is not None:
                failed[k] = err
                guesses.append(g)
                continue
            # the batched solve's pose carries this machine's own tangent ∂q/∂P (no re-evaluation)
            guesses.append(self.chain.evaluate(mod.pose(k), q_nominal[k, n0:]))
        solved = [failed.get(k, s) for k, s in enumerate(self.chain.inverse_many(targets, axes, guesses))]
        b = len(targets)
        q = np.full((b, n0 + self.tool.nq), np.nan)
        rot = np.full((b, 3, 3), np.nan)
        pos = np.full((b, 3), np.nan)
        errors: list[KinematicsError | None] = []
        for k, s in enumerate(solved):
            if isinstance(s, HybridPose):
                q[k] = np.concatenate([s.module.q_all, s.q_tool])
                rot[k], pos[k] = s.oMt.rotation, s.oMt.translation
                errors.append(None)
            else:
                errors.append(s)
        sols = HybridSolutions(q=q, rotation=rot, translation=pos, errors=tuple(errors))
        commands = q[:, self.actuated_idx] - self.offsets[self.actuated_idx]
        return np.where(sols.ok[:, None], commands, np.nan), sols


def nominal_chain(mechanism: Mechanism) -> HybridChain:
    """The nominal machine's solver (kept per mechanism)."""
    key = id(mechanism)
    if key not in _NOMINAL or _NOMINAL[key][0] is not mechanism:
        _NOMINAL[key] = (mechanism, HybridChain(mechanism))
    return _NOMINAL[key][1]


def assembled(chain: ClosedChain, q: np.ndarray) -> Pose:
    """The module's pose at joint values ``q`` (N,) of ``chain``'s models (forward kinematics, not solved)."""
    oMp = chain.platform_placements(q)[0]
    parts = tuple(q[chain.offsets[i] : chain.offsets[i + 1]].copy() for i in range(len(chain.models)))
    return Pose(
        q=parts, oMp=oMp, p_m=np.asarray(oMp.act(chain.p_ref), dtype=float), residual=0.0, condition=0.0
    )


def nominal_poses(mechanism: Mechanism, q: np.ndarray) -> list[HybridPose]:
    """The nominal machine's poses at joint values ``q`` (B, N + nq_t) (assembled, not solved).

    The last :data:`_POSES_KEPT` requests are kept: every machine of a study or a contract check
    commands the same held-out poses, whose nominal poses (each with its module's tangent, three
    first-order solves) would otherwise be rebuilt for each machine.
    """
    rows = np.atleast_2d(np.asarray(q, dtype=float))
    key = (id(mechanism), rows.shape, rows.tobytes())
    hit = _POSES.get(key)
    if hit is not None and hit[0] is mechanism:
        return list(hit[1])
    hc = nominal_chain(mechanism)
    n0 = int(hc.chain.offsets[-1])
    poses = [hc.evaluate(assembled(hc.chain, row[:n0]), row[n0:]) for row in rows]
    if len(_POSES) >= _POSES_KEPT:
        _POSES.pop(next(iter(_POSES)))
    _POSES[key] = (mechanism, tuple(poses))
    return poses
