"""Closed-chain kinematics on Pinocchio: inverse (task → all joints) and forward (actuators → pose).

Unknowns are the joint values of every limb. Closure equations make every limb's platform frame
coincide with limb 0's: ``r_i = log6(oMp_0⁻¹ · oMp_i) = 0`` (6 each, in limb 0's platform frame),
and close every internal loop of a limb (:mod:`pkmtol.kinematics.loops`: 6 rows for a ``6d`` loop,
3 for a ``3d`` one), in limb order after the platform closures.
The inverse problem adds the task ``oMp_0 · P − target = 0`` (3, in K) and frees every joint; the
forward problem frees only the passive joints. Newton's method with the exact Jacobian
(``Jlog6`` and Pinocchio's frame Jacobians) converges quadratically; over-determined systems
(over-constrained mechanisms) are solved in the least-squares sense.

Geometric errors enter through :func:`perturbed_limb_models`: joint placements
``jointPlacements[j] · exp6(ε_j)``, the platform attachment ``placement · exp6(ε_e)`` and joint
zero offsets ``q_actual = q + δq`` (DESIGN.md, "Geometric error parameters"), and each internal loop's frame b
placement ``· exp6(ε_loop)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import (
    ConvergenceError,
    InvalidArgumentError,
    JointLimitError,
    LoopMismatchError,
    MobilityError,
    PlatformMismatchError,
    SingularPoseError,
    UnreachableTargetError,
)
from pkmtol.kinematics.frame_tables import FrameTables
from pkmtol.kinematics.loops import frame_placements, loop_gaps, loop_layout, loop_rows
from pkmtol.kinematics.mobility import Mobility, count_mobility
from pkmtol.model.mechanism import Mechanism

#: Closure/task residual at which Newton stops [m, rad].
TOLERANCE = 1e-13
#: Condition number of the closure Jacobian above which a pose is called singular.
SINGULAR_CONDITION = 1e8
#: Residual below which a non-converged solve ends *at* a singular pose (larger: no solution) [m, rad].
SINGULAR_RESIDUAL = 1e-6
MAX_ITERATIONS = 40


@dataclass(frozen=True, eq=False)
class Pose:
    """A closed-chain configuration.

    Attributes:
        q: Joint values of each limb, shape (nq_i,) each [rad or m].
        oMp: Platform placement in K (limb 0's platform frame), ``pin.SE3``.
        p_m: Position of the reference point P in K, shape (3,) [m].
        residual: Norm of the closure (and task) residual at the solution [m, rad].
        condition: Condition number of the closure(+task) Jacobian at the solution (the batched
            solver stores its upper bound ``‖A‖_F ‖A⁻¹‖_F``, docs/theory.md).
        tangent: Shape (Σ nq_i, 3): ``∂q/∂P`` at an inverse solution (the task columns of the
            inverse Jacobian), for a first-order guess at a nearby target; None if not known.
    """

    q: tuple[np.ndarray, ...]
    oMp: pin.SE3
    p_m: np.ndarray
    residual: float
    condition: float
    tangent: np.ndarray | None = None

    @property
    def q_all(self) -> np.ndarray:
        """All joint values concatenated in limb order, shape (Σ nq_i,)."""
        return np.concatenate(self.q)


class ClosedChain:
    """Solver workspace for one mechanism (one ``pin.Data`` per limb; not thread-safe).

    Args:
        mechanism: The mechanism.
        models: Optional replacement limb models (e.g. perturbed), same structure as the limbs'.
        check_limits: Check URDF joint limits of every solution.
    """

    def __init__(
        self,
        mechanism: Mechanism,
        models: Sequence[pin.Model] | None = None,
        check_limits: bool = True,
    ) -> None:
        values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism (pkmtol.load_mechanism)")
        if models is not None:
            models = values.instances("models", models, pin.Model, "pin.Model", len(mechanism.limbs))
            for k, (m, lb) in enumerate(zip(models, mechanism.limbs, strict=True)):
                if m.nq != lb.nq or m.nframes <= lb.platform_frame:
                    raise InvalidArgumentError(f"models[{k}]", m, f"expected limb '{lb.name}' (nq {lb.nq})")
        values.flag("check_limits", check_limits)
        self.mechanism = mechanism
        self.models = list(models) if models is not None else [lb.model for lb in mechanism.limbs]
        self.datas = [m.createData() for m in self.models]
        self.fids = [lb.platform_frame for lb in mechanism.limbs]
        self.sizes = [lb.nq for lb in mechanism.limbs]
        self.offsets = np.cumsum([0] + self.sizes)
        self.p_ref = np.asarray(mechanism.reference_point_m, dtype=float)
        self._skew_p = pin.skew(self.p_ref)
        self.check_limits = check_limits
        self.actuated_idx = np.array(
            [self.offsets[i] + a for i, lb in enumerate(mechanism.limbs) for a in lb.actuated], dtype=int
        )
        self.lower = np.concatenate([m.lowerPositionLimit for m in self.models])
        self.upper = np.concatenate([m.upperPositionLimit for m in self.models])
        # per limb: (loop, its rows) for each internal loop, after the platform closures
        self.loop_blocks, n_rows = loop_layout(mechanism.limbs, 6 * (len(self.models) - 1))
        self.n_equations = n_rows
        self._jac = np.zeros((n_rows + 3, int(self.offsets[-1])))
        # per limb: model, data, platform frame, its columns in q, its closure rows (limb 0: none)
        self._blocks = [
            (m, d, fid, slice(int(self.offsets[i]), int(self.offsets[i + 1])), slice(6 * (i - 1), 6 * i))
            for i, (m, d, fid) in enumerate(zip(self.models, self.datas, self.fids, strict=True))
        ]
        self._res = np.zeros(n_rows + 3)
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # (q, Jacobian) of last inverse
        self._failed_q: np.ndarray | None = None  # last iterate of a solve that did not converge

    # --- public ---------------------------------------------------------------------------

    @cached_property
    def frame_tables(self) -> FrameTables:
        """Joint and frame tables of :attr:`models` for the compiled kernels (made on first use).

        The frames: every limb's platform frame, then each internal loop's frames a and b, limb
        by limb (the order of :class:`pkmtol.kinematics.batch_frames.BatchFrames`).
        """
        frames = [(i, fid) for i, fid in enumerate(self.fids)] + [
            (i, f)
            for i, limb in enumerate(self.mechanism.limbs)
            for lp in limb.loops
            for f in (lp.frame_a, lp.frame_b)
        ]
        return FrameTables.of(self.models, frames)

    def home(self) -> np.ndarray:
        """Home configuration refined to exact closure, shape (Σ nq,).

        The actuators stay at their ``home`` values; the passive joints are solved.

        Raises:
            MobilityError: the closure fails because the actuators are too few, too many or do not
                determine the pose (counted by :meth:`mobility`; it names the actuators needed).
            PlatformMismatchError: the limbs cannot be closed near ``home``.
        """
        q0 = np.concatenate([lb.home for lb in self.mechanism.limbs])
        free = np.ones(q0.size, dtype=bool)
        free[self.actuated_idx] = False
        try:
            q, _, _ = self._newton(q0, free, None, "home closure")
        except (SingularPoseError, ConvergenceError) as err:
            problems = self.mobility().problems  # too few or misplaced actuators: say so
            if problems:
                raise MobilityError("; ".join(problems)) from err
            if isinstance(err, ConvergenceError):
                raise self._home_mismatch(q0) from err
            mismatch = self._home_mismatch(q0)
            if max(mismatch.distance_m, mismatch.angle_rad) > 1e-9:
                raise mismatch from err
            raise SingularPoseError(
                "the closure Jacobian at the home configuration (actuators held)", err.condition
            ) from err
        return q

    def mobility(self) -> Mobility:
        """The mechanism's mobility and what its actuators leave free, near ``home`` (no joint held).

        See :mod:`pkmtol.kinematics.mobility`; its ``problems`` name the actuators needed.
        """
        mech = self.mechanism
        names = [f"{lb.name}.{j}" for lb in mech.limbs for j in lb.joint_names]
        task_dof = None if mech.tool is not None else (3 if mech.task_normal is None else 2)
        q0 = np.concatenate([lb.home for lb in mech.limbs])
        return count_mobility(
            lambda q: self._evaluate(q, None), q0, names, [int(i) for i in self.actuated_idx], task_dof
        )

    def _home_mismatch(self, q0: np.ndarray) -> PlatformMismatchError:
        """The largest gap at ``q0``: a limb's platform frame, or an internal loop."""
        worst = self.worst_limb(q0)
        loops = self.worst_loop(q0)
        if loops is not None and max(loops[3], loops[4]) > max(worst[2], worst[3]):
            return LoopMismatchError(*loops)
        return PlatformMismatchError(*worst)

    def inverse(self, target_m: np.ndarray, q0: np.ndarray | None = None) -> Pose:
        """All joint values and the platform pose that put P at ``target_m``.

        Args:
            target_m: Position of P in K, shape (3,) [m].
            q0: Initial guess (Σ nq,) (default: refined home).

        Raises:
            UnreachableTargetError: Newton does not converge (target outside the workspace).
            JointLimitError: the solution violates a URDF joint limit.
            SingularPoseError: the closure Jacobian is singular at the solution.
        """
        target = values.vector("target_m", target_m, 3)
        q0 = self.home() if q0 is None else self._joints("q0", q0)
        free = np.ones(q0.size, dtype=bool)
        try:
            q, cond, res = self._newton(q0, free, target, "inverse kinematics")
        except ConvergenceError as err:
            failed = self._failed_q
            limb = self.worst_limb(failed)[0] if failed is not None and np.isfinite(failed).all() else None
            raise UnreachableTargetError(
                target,
                "the closure equations have no solution near the initial guess "
                f"({err.residual:.2g} left; the largest closure gap is at this limb)",
                limb=limb,
            ) from err
        except SingularPoseError as err:
            raise SingularPoseError(err.what, err.condition, target) from err
        self._check_limits(q, target)
        return self._pose(q, cond, res)

    def forward(
        self,
        q_actuated: np.ndarray,
        q0: np.ndarray,
        offsets: np.ndarray | None = None,
    ) -> Pose:
        """Platform pose and passive joints for given actuator values.

        Args:
            q_actuated: Actuator readings, in the order of ``actuated_idx`` [rad or m].
            q0: Initial guess for all joints (Σ nq,).
            offsets: Joint zero offsets δq (Σ nq,): the actual joint value is reading + δq.
                Only the actuated entries matter (a passive offset relabels a passive joint).

        Returns:
            The pose; ``q`` holds the *actual* joint values.
        """
        q = self._joints("q0", q0).copy()
        q[self.actuated_idx] = values.vector("q_actuated", q_actuated, self.actuated_idx.size)
        if offsets is not None:
            q[self.actuated_idx] += self._joints("offsets", offsets)[self.actuated_idx]
        if self.check_limits:
            self._check_commands(q_actuated, q)
        free = np.ones(q.size, dtype=bool)
        free[self.actuated_idx] = False
        q, cond, res = self._newton(q, free, None, "forward kinematics")
        pose = self._pose(q, cond, res)
        self._check_limits(q, pose.p_m)
        return pose

    def platform_placements(self, q: np.ndarray) -> list[pin.SE3]:
        """Each limb's platform placement in K at joint values ``q`` (Σ nq,)."""
        q = self._joints("q", q)
        out = []
        for i, (m, d) in enumerate(zip(self.models, self.datas, strict=True)):
            pin.framesForwardKinematics(m, d, q[self.offsets[i] : self.offsets[i + 1]])
            out.append(d.oMf[self.fids[i]].copy())
        return out

    # --- internals ------------------------------------------------------------------------

    def _pose(self, q: np.ndarray, cond: float, residual: float) -> Pose:
        """Pose from the kinematics left in ``self.datas`` by the last evaluation at ``q``."""
        oMp = self.datas[0].oMf[self.fids[0]].copy()
        qs = tuple(q[self.offsets[i] : self.offsets[i + 1]].copy() for i in range(len(self.models)))
        return Pose(q=qs, oMp=oMp, p_m=oMp.act(self.p_ref), residual=residual, condition=cond)

    def predict(self, pose: Pose, target_m: np.ndarray) -> np.ndarray:
        """First-order guess of the joints that put P at ``target_m``, from a solved ``pose``.

        Uses the closure+task Jacobian of the last inverse solve when ``pose`` is that solution
        (free), otherwise evaluates it: ``A Δq = [0; Δp]``.
        """
        values.instance("pose", pose, Pose, "a Pose (ClosedChain.inverse)")
        target = values.vector("target_m", target_m, 3)
        q = self._joints("pose.q", pose.q_all)
        if self._last is not None and np.array_equal(self._last[0], q):
            a = self._last[1]
        else:
            a = self._evaluate(q, pose.p_m)[1].copy()
        rhs = np.zeros(a.shape[0])
        rhs[-3:] = target - pose.p_m
        try:
            return q + np.linalg.solve(a, rhs)
        except np.linalg.LinAlgError:
            return q

    def _evaluate(self, q: np.ndarray, target: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian (all columns) of closure (+ task) at ``q``.

        Only the blocks of limb ``i`` and limb 0 are ever written; the rest of the Jacobian
        buffer stays zero from construction.
        """
        jac, res = self._jac, self._res
        placements, jacs = [], []
        for (m, d, fid, cols, _), loops in zip(self._blocks, self.loop_blocks, strict=True):
            pin.computeJointJacobians(m, d, q[cols])  # and the joint placements oMi
            placements.append(pin.updateFramePlacement(m, d, fid))
            jacs.append(pin.getFrameJacobian(m, d, fid, pin.LOCAL))
            for lp, rows in loops:
                oma, omb, ja, jb = frame_placements(m, d, lp)
                res[rows], jac[rows, cols], _ = loop_rows(lp, oma, omb, ja, jb)
        m0 = placements[0]
        j0 = jacs[0]
        c0 = self._blocks[0][3]
        for (_, _, _, cols, rows), mi, ji in zip(self._blocks[1:], placements[1:], jacs[1:], strict=True):
            e = m0.actInv(mi)
            res[rows] = pin.log6(e).vector
            jl = pin.Jlog6(e)
            jac[rows, cols] = jl @ ji
            jac[rows, c0] = -(jl @ e.toActionMatrixInverse()) @ j0
        n = self.n_equations
        if target is None:
            return res[:n], jac[:n]
        p = m0.act(self.p_ref)
        res[n:] = p - target
        rot = m0.rotation
        jac[n:, c0] = rot @ (j0[:3] - self._skew_p @ j0[3:])
        return res, jac

    def _newton(
        self, q0: np.ndarray, free: np.ndarray, target: np.ndarray | None, what: str
    ) -> tuple[np.ndarray, float, float]:
        """Newton's method on the free joints; returns (q, condition number, residual norm)."""
        q = np.array(q0, dtype=float)
        res_norm = prev_norm = np.inf
        for iteration in range(MAX_ITERATIONS):
            res, jac = self._evaluate(q, target)
            a = jac[:, free]
            if not (np.isfinite(res).all() and np.isfinite(a).all()):  # overflow: no solution to refine
                raise ConvergenceError(f"{what} (the closure equations overflowed)", np.inf, iteration)
            res_norm = float(np.max(np.abs(res)))
            # converged, or stalled at round-off level
            if res_norm < TOLERANCE or (res_norm < 1e-11 and res_norm >= prev_norm):
                s = np.linalg.svd(a, compute_uv=False)
                cond = float(s[0] / s[-1]) if s[-1] > 0 else np.inf
                if a.shape[0] < a.shape[1] or cond > SINGULAR_CONDITION:
                    raise SingularPoseError(f"the {what} Jacobian", cond)
                if target is not None:
                    self._last = (q.copy(), a.copy())
                return q, cond, float(np.linalg.norm(res))
            if a.shape[0] == a.shape[1]:
                try:
                    step = np.linalg.solve(a, res)
                except np.linalg.LinAlgError:
                    step = np.linalg.lstsq(a, res, rcond=None)[0]
            else:
                step = np.linalg.lstsq(a, res, rcond=None)[0]
            # limit huge steps far from the solution (keeps Newton on the same assembly branch)
            big = np.max(np.abs(step))
            if big > 0.5:
                step *= 0.5 / big
            q[free] -= step
            prev_norm = res_norm
        self._failed_q = q.copy()
        s = np.linalg.svd(self._evaluate(q, target)[1][:, free], compute_uv=False)
        cond = float(s[0] / s[-1]) if s[-1] > 0 else np.inf
        if cond > SINGULAR_CONDITION and res_norm < SINGULAR_RESIDUAL:
            raise SingularPoseError(f"the {what} Jacobian", cond)
        raise ConvergenceError(what, res_norm, MAX_ITERATIONS)

    def _joints(self, name: str, q: Any) -> np.ndarray:
        """``q`` checked as finite values of every joint, shape (Σ nq,)."""
        return values.vector(name, q, int(self.offsets[-1]))

    def _check_commands(self, q_actuated: Any, q: np.ndarray) -> None:
        """Refuse actuator values (readings + offsets, in ``q``) outside their URDF limits."""
        for k, i in enumerate(self.actuated_idx):
            if not self.lower[i] - 1e-12 <= q[i] <= self.upper[i] + 1e-12:
                limb = int(np.searchsorted(self.offsets, i, side="right") - 1)
                joint = self.mechanism.limbs[limb].joint_names[i - int(self.offsets[limb])]
                raise InvalidArgumentError(
                    "q_actuated",
                    q_actuated,
                    f"entry {k}, actuator '{joint}' of limb '{self.mechanism.limbs[limb].name}', would be at "
                    f"{q[i]:.6g} [rad or m], outside its limits [{self.lower[i]:.6g}, {self.upper[i]:.6g}]; "
                    "command values within the URDF limits (or build the chain with check_limits=False)",
                )

    def _check_limits(self, q: np.ndarray, target: np.ndarray) -> None:
        if self.check_limits:
            err = self.limit_violation(q, target)
            if err is not None:
                raise err

    def limit_violation(self, q: np.ndarray, target: np.ndarray) -> JointLimitError | None:
        """The error for the first joint of ``q`` (Σ nq,) outside its URDF limits, or None.

        Args:
            q: All joint values [rad or m].
            target: The target of P the solution was for, shape (3,) [m] (named in the error).
        """
        q = self._joints("q", q)
        target = values.vector("target", target, 3)
        bad = np.flatnonzero((q < self.lower - 1e-12) | (q > self.upper + 1e-12))
        if not bad.size:
            return None
        k = int(bad[0])
        i = int(np.searchsorted(self.offsets, k, side="right") - 1)
        limb = self.mechanism.limbs[i]
        j = k - int(self.offsets[i])
        return JointLimitError(
            target,
            limb.name,
            limb.joint_names[j],
            float(q[k]),
            float(self.lower[k]),
            float(self.upper[k]),
        )

    def worst_loop(self, q: np.ndarray) -> tuple[str, str, tuple[str, str], float, float] | None:
        """The internal loop with the largest gap at ``q`` (Σ nq,), None without loops.

        Returns:
            ``(limb, loop, (frame a, frame b), translation gap [m], rotation gap [rad])``.
        """
        q = self._joints("q", q)
        worst: tuple[str, str, tuple[str, str], float, float] | None = None
        for i, (limb, m) in enumerate(zip(self.mechanism.limbs, self.models, strict=True)):
            for lp, dist, ang in loop_gaps(limb, m, q[self.offsets[i] : self.offsets[i + 1]]):
                if worst is None or dist + ang > worst[3] + worst[4]:
                    worst = (limb.name, lp.name, lp.frame_names, dist, ang)
        return worst

    def worst_limb(self, q: np.ndarray) -> tuple[str, str, float, float]:
        """The limb whose platform frame is furthest from limb 0's at ``q`` (Σ nq,).

        Returns:
            ``(limb, limb 0, translation gap [m], rotation gap [rad])``.
        """
        oMp = self.platform_placements(self._joints("q", q))
        worst = (self.mechanism.limbs[0].name, self.mechanism.limbs[0].name, 0.0, 0.0)
        best = -1.0
        for lb, m in zip(self.mechanism.limbs[1:], oMp[1:], strict=True):
            err = pin.log6(oMp[0].inverse() * m).vector
            size = float(np.linalg.norm(err))
            if size > best:
                best = size
                worst = (
                    lb.name,
                    self.mechanism.limbs[0].name,
                    float(np.linalg.norm(err[:3])),
                    float(np.linalg.norm(err[3:])),
                )
        return worst
