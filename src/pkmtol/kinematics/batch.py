"""Many independent closed-chain solves at once: Newton in lockstep, the work stacked over the poses.

:class:`BatchChain` solves ``B`` inverse (task → joints) or forward (actuators → pose) problems of
one mechanism together. Each Newton iteration reads every limb's platform frame for all poses
(:class:`~pkmtol.kinematics.batch_frames.BatchFrames`: compiled kernels, or Pinocchio once per pose
and limb on a reused ``Data``), then does the rest for all poses in one go: the closure residual
``log6(oMp_0⁻¹ oMp_i)`` and its Jacobian (:mod:`pkmtol.kinematics.se3_batch`, or compiled pose by
pose), the Jacobian assembly and a stacked LU solve (least squares by stacked QR for
over-constrained mechanisms). Poses leave the batch when they converge. The equations, tolerances,
step limit and error rules are those of :class:`pkmtol.kinematics.closed_chain.ClosedChain`, so a
pose gets the same solution (to the Newton tolerance) and the same error as with
``ClosedChain.inverse``/``forward``.

Conditioning: instead of an SVD per solve, the converged Jacobian's condition number is bounded by
``κ_F = ‖A‖_F ‖A⁻¹‖_F`` (``κ₂ ≤ κ_F ≤ n κ₂``; for an over-determined ``A``, ``√κ_F(AᵀA)``) from one
stacked inverse. Only a pose whose bound exceeds ``SINGULAR_CONDITION`` gets the SVD, so a pose is
called singular exactly when ``ClosedChain`` calls it singular; ``Solutions.condition`` holds the
bound.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pinocchio as pin

from pkmtol.exceptions import (
    ConvergenceError,
    KinematicsError,
    SingularPoseError,
    UnreachableTargetError,
)
from pkmtol.kinematics import acceleration, se3_batch
from pkmtol.kinematics.batch_frames import BatchFrames, Evaluation, LoopFrames, Perturbation, one
from pkmtol.kinematics.closed_chain import (
    MAX_ITERATIONS,
    SINGULAR_CONDITION,
    SINGULAR_RESIDUAL,
    TOLERANCE,
    ClosedChain,
)
from pkmtol.kinematics.loops import loop_rows_many
from pkmtol.kinematics.solutions import Solutions
from pkmtol.kinematics.stacked_solve import condition_bound, exact_condition, newton_steps
from pkmtol.model.mechanism import Mechanism

#: No task rows (forward problems), for the compiled closure rows.
_NO_TARGETS = np.zeros((0, 3))


class BatchChain:
    """Batched closed-chain solver of one mechanism (not thread-safe: the workspaces are reused).

    Args:
        mechanism: The mechanism.
        models: Optional replacement limb models (e.g. perturbed), same structure as the limbs'.
        check_limits: Check URDF joint limits of every inverse solution.
        chain: A per-pose solver of the mechanism whose models, datas and limit check to share
            (``models`` and ``check_limits`` are then ignored).
    """

    def __init__(
        self,
        mechanism: Mechanism,
        models: Sequence[pin.Model] | None = None,
        check_limits: bool = True,
        chain: ClosedChain | None = None,
    ) -> None:
        self.chain = chain or ClosedChain(mechanism, models=models, check_limits=check_limits)
        self.mechanism = mechanism
        self.models = self.chain.models
        self.datas = self.chain.datas
        self.fids = self.chain.fids
        self.offsets = self.chain.offsets
        self.actuated_idx = self.chain.actuated_idx
        self.n_joints = int(self.offsets[-1])
        self.p_ref = self.chain.p_ref
        self._n_closure = self.chain.n_equations  # platform closures, then internal loops
        self._skew_p = pin.skew(self.p_ref)
        self._cols = [slice(int(a), int(b)) for a, b in zip(self.offsets[:-1], self.offsets[1:], strict=True)]
        self._offsets = np.asarray(self.offsets, dtype=np.int64)
        self.frames = BatchFrames(self.chain)

    # --- public ---------------------------------------------------------------------------

    def inverse(self, targets_m: np.ndarray, guesses: np.ndarray) -> Solutions:
        """Joint values that put P at each target (same equations as :meth:`ClosedChain.inverse`).

        Args:
            targets_m: Shape (B, 3): positions of P in K [m].
            guesses: Shape (B, N): initial guesses.

        Returns:
            The solutions; a problem's error is an :class:`UnreachableTargetError`,
            :class:`JointLimitError` or :class:`SingularPoseError` naming its target.
        """
        targets = np.asarray(targets_m, dtype=float).reshape(-1, 3)
        q0 = np.array(guesses, dtype=float).reshape(len(targets), self.n_joints)
        free = np.ones(self.n_joints, dtype=bool)
        sols = self._newton(q0, free, targets, None, "inverse kinematics")
        errors = list(sols.errors)
        outside = (sols.q < self.chain.lower - 1e-12) | (sols.q > self.chain.upper + 1e-12)
        bad = np.asarray(outside.any(axis=1) & self.chain.check_limits, dtype=bool)
        for k, err in enumerate(errors):
            if isinstance(err, ConvergenceError):
                limb = self.chain.worst_limb(sols.q[k])[0]
                errors[k] = UnreachableTargetError(
                    targets[k],
                    "the closure equations have no solution near the initial guess "
                    f"({err.residual:.2g} left; the largest closure gap is at this limb)",
                    limb=limb,
                )
            elif isinstance(err, SingularPoseError):
                errors[k] = SingularPoseError(err.what, err.condition, targets[k])
            elif err is None and bad[k]:
                errors[k] = self.chain.limit_violation(sols.q[k], targets[k])
        return replace(sols, errors=tuple(errors))

    def forward(
        self,
        q_actuated: np.ndarray,
        guesses: np.ndarray,
        offsets: np.ndarray | None = None,
        eps: Sequence[np.ndarray] | None = None,
    ) -> Solutions:
        """Platform poses for given actuator values (same equations as :meth:`ClosedChain.forward`).

        Args:
            q_actuated: Shape (B, f): actuator readings, in the order of ``actuated_idx``.
            guesses: Shape (B, N): initial guesses for all joints.
            offsets: Shape (B, N): joint zero offsets δq (actual = reading + δq; only the
                actuated entries matter).
            eps: Per limb, shape (B, nq_i + 1, 6): joint-origin errors then the platform
                attachment error of each problem's mechanism (as for
                :func:`pkmtol.kinematics.perturbation.perturbed_limb_models`); None: nominal.

        Returns:
            The solutions (``q`` holds actual joint values); a problem's error is a
            :class:`ConvergenceError` or :class:`SingularPoseError` whose text names the problem.
        """
        q = np.array(guesses, dtype=float).reshape(-1, self.n_joints)
        q[:, self.actuated_idx] = np.asarray(q_actuated, dtype=float).reshape(len(q), -1)
        if offsets is not None:
            q[:, self.actuated_idx] += np.asarray(offsets, dtype=float).reshape(len(q), -1)[
                :, self.actuated_idx
            ]
        free = np.ones(self.n_joints, dtype=bool)
        free[self.actuated_idx] = False
        perturbation = self.frames.perturb(eps, len(q)) if eps is not None else None
        return self._newton(q, free, None, perturbation, "forward kinematics")

    def predict(self, sols: Solutions, index: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
        """First-order guesses (len(index), N) for ``targets_m`` from solved inverse problems ``index``.

        ``q + A⁻¹ [0; Δp]`` with ``A`` the closure + task Jacobian at the solution (as
        :meth:`ClosedChain.predict`).
        """
        index = np.asarray(index, dtype=int)
        dp = np.asarray(targets_m, dtype=float).reshape(-1, 3) - sols.p_m[index]
        step = sols.system_inverse[index][:, :, -3:] @ dp[:, :, None]
        return sols.q[index] + step[:, :, 0]

    # --- internals ------------------------------------------------------------------------

    def _system(
        self, frames: Evaluation, targets: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals (b, rows), Jacobians (b, rows, N) and a near-half-turn mask (b,) at ``frames``.

        The closure rows of every limb pair are computed together: ``e_i = oMp_0⁻¹ oMp_i``,
        ``r_i = log6(e_i)``, ``∂r_i/∂q_i = Jlog6(e_i) J_i`` and ``∂r_i/∂q_0 = −Jlog6(e_i) e_i⁻¹·J_0``;
        then each internal loop's rows (:func:`pkmtol.kinematics.loops.loop_rows_many`). With numba
        (:mod:`pkmtol.kinematics.jit_kernels`) the platform and task rows are computed pose by pose
        in compiled code from the zero-padded Jacobians ``frames.padded``.
        """
        placements, jacobians, loop_frames, padded = frames
        b = len(placements[0])
        n = self._n_closure
        pairs = len(placements) - 1
        rows = n + (3 if targets is not None else 0)
        res = np.empty((b, rows))
        jac = np.zeros((b, rows, self.n_joints))
        kernels = acceleration.kernels()
        if kernels is not None:
            near_pi = np.zeros(b, dtype=bool)
            kernels.closure_rows(
                placements,
                padded,
                self._offsets,
                self.p_ref,
                _NO_TARGETS if targets is None else targets,
                n,
                res,
                jac,
                near_pi,
            )
            self._loop_rows(loop_frames, res, jac)
            return res, jac, near_pi
        h = placements  # (L, b, 4, 4)
        r0, p0 = h[0, :, :3, :3], h[0, :, :3, 3]
        r0t = np.swapaxes(r0, 1, 2)
        j0 = jacobians[0]
        c0 = self._cols[0]
        if pairs:
            re = (r0t[None] @ h[1:, :, :3, :3]).reshape(-1, 3, 3)  # (pairs·b, 3, 3)
            pe = (r0t[None] @ (h[1:, :, :3, 3] - p0[None])[..., None]).reshape(-1, 3)
            nu, jl, near = se3_batch.log6_and_jacobian(re, pe)
            n6 = 6 * pairs
            res[:, :n6] = nu.reshape(pairs, b, 6).transpose(1, 0, 2).reshape(b, n6)
            j0_all = np.broadcast_to(j0, (pairs,) + j0.shape).reshape(-1, 6, j0.shape[2])
            d0 = -(jl @ se3_batch.act_inverse(re, pe, j0_all))
            jac[:, :n6, c0] = d0.reshape(pairs, b, 6, -1).transpose(1, 0, 2, 3).reshape(b, n6, -1)
            jl = jl.reshape(pairs, b, 6, 6)
            for i in range(1, pairs + 1):
                jac[:, 6 * (i - 1) : 6 * i, self._cols[i]] = jl[i - 1] @ jacobians[i]
            near_pi = np.asarray(near.reshape(pairs, b).any(axis=0), dtype=bool)
        else:
            near_pi = np.zeros(b, dtype=bool)
        self._loop_rows(loop_frames, res, jac)
        if targets is not None:
            res[:, n:] = (r0 @ self.p_ref) + p0 - targets
            jac[:, n:, c0] = r0 @ (j0[:, :3] - self._skew_p @ j0[:, 3:])
        return res, jac, near_pi

    def _loop_rows(self, loop_frames: list[list[LoopFrames]], res: np.ndarray, jac: np.ndarray) -> None:
        """Each internal loop's rows into ``res`` and ``jac`` (:func:`loop_rows_many`)."""
        for blocks, frames, cols in zip(self.chain.loop_blocks, loop_frames, self._cols, strict=True):
            for (lp, lrows), (ha, hb, ja, jb) in zip(blocks, frames, strict=True):
                res[:, lrows], jac[:, lrows, cols] = loop_rows_many(lp, ha, hb, ja, jb)

    def _pinocchio_rows(
        self,
        placements: np.ndarray,
        jacobians: list[np.ndarray],
        k: int,
        res: np.ndarray,
        jac: np.ndarray,
    ) -> None:
        """Closure rows of problem ``k`` by Pinocchio (a rotation near a half turn)."""
        m0 = pin.SE3(placements[0][k])
        j0 = jacobians[0][k]
        for i in range(1, len(placements)):
            e = m0.actInv(pin.SE3(placements[i][k]))
            sl = slice(6 * (i - 1), 6 * i)
            res[k, sl] = pin.log6(e).vector
            jl = pin.Jlog6(e)
            jac[k, sl, self._cols[i]] = jl @ jacobians[i][k]
            jac[k, sl, self._cols[0]] = -(jl @ e.toActionMatrixInverse()) @ j0

    def _newton(
        self,
        q0: np.ndarray,
        free: np.ndarray,
        targets: np.ndarray | None,
        perturbation: Perturbation | None,
        what: str,
    ) -> Solutions:
        """Lockstep Newton on the free joints of every problem (``ClosedChain._newton``'s rules).

        The figures a failed problem reports follow every rounding of the kinematics: a solve that
        runs out of iterations made Newton wander, and the condition number of a singular Jacobian
        is round-off over round-off. With the compiled kernels a failed problem is therefore solved
        once more with the per-pose solver's numerics (Pinocchio's kinematics, LAPACK's steps), so
        that its error says what the per-pose solver says.
        """
        sols = self._lockstep(q0, free, targets, perturbation, what, False, None)
        failed = np.flatnonzero(~sols.ok)
        if not failed.size or acceleration.kernels() is None:
            return sols
        again = self._lockstep(
            q0[failed],
            free,
            None if targets is None else targets[failed],
            self.frames.slots_of(perturbation, failed),
            what,
            True,
            failed,
        )
        return sols.with_rows(failed, again)

    def _lockstep(
        self,
        q0: np.ndarray,
        free: np.ndarray,
        targets: np.ndarray | None,
        perturbation: Perturbation | None,
        what: str,
        as_per_pose: bool,
        numbers: np.ndarray | None,
    ) -> Solutions:
        """Newton in lockstep.

        ``as_per_pose``: with the per-pose solver's numerics (Pinocchio's frames, LAPACK's steps);
        ``numbers``: the problems' numbers in messages (default their positions).
        """
        count = len(q0)
        q = q0.copy()
        rows = self._n_closure + (3 if targets is not None else 0)
        n_free = int(free.sum())
        all_free = n_free == len(free)
        done_h = [np.zeros((count, 4, 4)) for _ in self.models]
        done_j = [np.zeros((count, 6, lb.nq)) for lb in self.mechanism.limbs]
        system = np.zeros((count, rows, n_free))
        residual = np.full(count, np.nan)
        errors: list[KinematicsError | None] = [None] * count
        prev = np.full(count, np.inf)
        active = np.arange(count)
        converged_any: list[np.ndarray] = []
        for _ in range(MAX_ITERATIONS if count else 0):
            frames = self.frames.evaluate(q, active, perturbation, as_per_pose)
            placements, jacobians = frames.placements, frames.jacobians
            res, jac, near_pi = self._system(frames, None if targets is None else targets[active])
            for k in np.flatnonzero(near_pi):
                self._pinocchio_rows(placements, jacobians, int(k), res, jac)
            a = jac if all_free else jac[:, :, free]
            norm = np.abs(res).max(axis=1)
            conv = (norm < TOLERANCE) | ((norm < 1e-11) & (norm >= prev[active]))
            if conv.any():
                idx = active[conv]
                for i in range(len(self.models)):
                    done_h[i][idx] = placements[i][conv]
                    done_j[i][idx] = jacobians[i][conv]
                system[idx] = a[conv]
                residual[idx] = np.linalg.norm(res[conv], axis=1)
                converged_any.append(idx)
                keep = ~conv
                active, a, res, norm = active[keep], a[keep], res[keep], norm[keep]
                if not active.size:
                    break
            step = newton_steps(a, res, compiled=not as_per_pose)
            big = np.abs(step).max(axis=1)
            scale = np.where(big > 0.5, 0.5 / np.where(big > 0.5, big, 1.0), 1.0)
            step *= scale[:, None]
            if all_free:
                q[active] -= step
            else:
                sub = q[active]
                sub[:, free] -= step
                q[active] = sub
            prev[active] = norm
        # problems still active ran out of iterations
        number = np.arange(count) if numbers is None else numbers
        for k in active:
            target = targets[k] if targets is not None else None
            errors[int(k)] = self._failure(
                q[k],
                free,
                target,
                one(perturbation, int(k)),
                int(number[k]),
                float(prev[k]),
                what,
                as_per_pose,
            )
        solved = np.concatenate(converged_any) if converged_any else np.zeros(0, dtype=int)
        condition = np.full(count, np.nan)
        inverse = np.full((count, n_free, rows), np.nan)
        if solved.size:
            cond, inv = condition_bound(system[solved])
            condition[solved] = cond
            inverse[solved] = inv
            for pos, k in enumerate(solved):
                if rows < n_free or cond[pos] > SINGULAR_CONDITION:
                    exact = exact_condition(system[k])
                    condition[k] = exact
                    if rows < n_free or exact > SINGULAR_CONDITION:
                        errors[int(k)] = SingularPoseError(_what(what, int(number[k]), targets), exact)
        r0 = done_h[0][:, :3, :3]
        p0 = done_h[0][:, :3, 3]
        for k in active:  # failed: report the last iterate's platform pose
            h = self.frames.evaluate(
                q[k][None], np.zeros(1, dtype=int), one(perturbation, int(k)), as_per_pose
            )
            r0[k], p0[k] = h.placements[0][0][:3, :3], h.placements[0][0][:3, 3]
        return Solutions(
            q=q,
            rotation=r0,
            translation=p0,
            p_m=(r0 @ self.p_ref) + p0,
            residual=residual,
            condition=condition,
            jacobians=tuple(done_j),
            system=system,
            system_inverse=inverse,
            errors=tuple(errors),
            limb_offsets=tuple(int(o) for o in self.offsets),
            task=targets is not None,
        )

    def _failure(
        self,
        q: np.ndarray,
        free: np.ndarray,
        target: np.ndarray | None,
        perturbation: Perturbation | None,
        number: int,
        norm: float,
        what: str,
        as_per_pose: bool,
    ) -> KinematicsError:
        """The error of problem ``number`` that ran out of iterations (``ClosedChain._newton``'s rule).

        ``perturbation`` is the problem's alone (:func:`_one`); ``norm`` is the residual of the
        last iterate checked; the condition is that of the Jacobian after the last step, as in the
        per-pose solver.
        """
        frames = self.frames.evaluate(q[None], np.zeros(1, dtype=int), perturbation, as_per_pose)
        res, jac, _ = self._system(frames, None if target is None else target[None])
        self._pinocchio_rows(frames.placements, frames.jacobians, 0, res, jac)
        cond = exact_condition(jac[0][:, free])
        label = what if target is not None else f"{what} (problem {number})"
        if cond > SINGULAR_CONDITION and norm < SINGULAR_RESIDUAL:
            return SingularPoseError(f"the {label} Jacobian", cond)
        return ConvergenceError(label, norm, MAX_ITERATIONS)


def _what(what: str, k: int, targets: np.ndarray | None) -> str:
    """The matrix a singular error names; forward problems are numbered (inverse ones have a target)."""
    return f"the {what} Jacobian" if targets is not None else f"the {what} Jacobian (problem {k})"
