"""Inverse kinematics of a hybrid machine: the parallel module's closed chain, the tool chain on its platform.

The unknowns are the module's task point P (3) and the actuated wrist joints (w = 0 or 2); the
equations are the TCP position (3) and, with two wrist actuators, the tool axis across the target
axis (2 rows: ``Q* a`` with ``Q*`` two unit rows orthogonal to the target axis ``a*``; the spin
about the axis is free). Each evaluation solves the module at P with its own solver
(:meth:`ClosedChain.inverse`, or :meth:`BatchChain.inverse` for many poses, warm-started by the
tangent step ``q + ∂q/∂P ΔP``), then the tool chain's frame kinematics. The Jacobian is exact:
the platform twist per unit ΔP is ``J_0 ∂q_0/∂P`` (limb 0's platform-frame Jacobian and the
module's tangent), moved to the TCP by ``Ad(pMt⁻¹)``, beside the tool chain's frame Jacobian;
Newton's method on it converges quadratically (docs/hybrid.md, "Inverse kinematics").
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import (
    InvalidArgumentError,
    InvalidRequestError,
    JointLimitError,
    KinematicsError,
    SingularPoseError,
    UnreachableTargetError,
)
from pkmtol.kinematics.batch import BatchChain
from pkmtol.kinematics.closed_chain import SINGULAR_CONDITION, ClosedChain, Pose
from pkmtol.kinematics.hybrid_pose import (
    STEP_LIMIT_JOINT,
    STEP_LIMIT_M,
    HybridPose,
    StackedPoses,
    cross_columns,
    exp3_many,
    limited_many,
    solve_many,
    task_rows,
    task_rows_many,
)
from pkmtol.kinematics.tool_chain import (
    ToolKinematics,
    across_many,
    orthonormal_across,
    tool_frames,
    world_axes,
)
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.tool import TOOL, Tool

#: Task residual at which the outer Newton stops [m, rad].
TOLERANCE = 1e-12
MAX_ITERATIONS = 30
#: Quasi-Newton steps of the rigid predictor (:meth:`HybridChain._predict_many`).
PREDICTOR_ITERATIONS = 3


class HybridChain:
    """Solver of a hybrid machine's task (per pose and batched; not thread-safe).

    Args:
        mechanism: A mechanism with a tool chain (``mechanism.tool``).
        chain: The module's per-pose solver to use (default: a new one); its models may be
            perturbed.
        tool_model: The tool chain's model to use (default: the nominal one).
        check_limits: Check the tool chain's joint limits at every solution (the module's are
            checked by its own solver).
    """

    def __init__(
        self,
        mechanism: Mechanism,
        chain: ClosedChain | None = None,
        tool_model: pin.Model | None = None,
        check_limits: bool = True,
    ) -> None:
        values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism with a [tool] chain")
        if mechanism.tool is None:
            raise InvalidRequestError(
                f"mechanism '{mechanism.name}' has no tool chain; add a [tool] table (docs/hybrid.md)"
            )
        values.optional(values.instance, "chain", chain, ClosedChain, "a ClosedChain of this mechanism")
        values.optional(values.instance, "tool_model", tool_model, pin.Model, "pin.Model (the tool chain's)")
        if tool_model is not None and tool_model.nq != mechanism.tool.nq:
            raise InvalidArgumentError("tool_model", tool_model, f"expected nq {mechanism.tool.nq}")
        values.flag("check_limits", check_limits)
        self.mechanism = mechanism
        self.tool: Tool = mechanism.tool
        self.chain = chain or ClosedChain(mechanism)
        self.batch = BatchChain(mechanism, chain=self.chain)
        self.tool_model = tool_model if tool_model is not None else self.tool.model
        self.tool_data = self.tool_model.createData()
        self.actuated = list(self.tool.actuated)
        self.rows = 3 + len(self.actuated)
        self.check_limits = check_limits
        self._lower = np.asarray(self.tool_model.lowerPositionLimit, dtype=float)
        self._upper = np.asarray(self.tool_model.upperPositionLimit, dtype=float)
        self._nq0 = mechanism.limbs[0].nq
        self.kinematics = ToolKinematics(self.tool, self.tool_model)
        self.wrist_offset_m = self._decoupling()

    # --- one pose -----------------------------------------------------------------------

    def home(self) -> HybridPose:
        """The machine at the module's refined home and the tool chain's ``home`` values."""
        pose = self.chain.inverse(self._module_home_p())
        return self._assemble(pose, self._tangent(pose), self.tool.home.copy())

    def _module_home_p(self) -> np.ndarray:
        q = self.chain.home()
        oMp = self.chain.platform_placements(q)[0]
        return np.asarray(oMp.act(self.chain.p_ref), dtype=float)

    def evaluate(self, pose: Pose, q_tool: np.ndarray) -> HybridPose:
        """The machine at a module pose and tool joints (residual and condition left at 0)."""
        values.instance("pose", pose, Pose, "a Pose of the module (ClosedChain.inverse)")
        return self._assemble(pose, self._tangent(pose), self._tool_q("q_tool", q_tool))

    def _tool_q(self, name: str, q: object) -> np.ndarray:
        """``q`` checked as finite values of the tool chain's joints, shape (nq_t,)."""
        return values.vector(name, q, self.tool.nq)

    def inverse(
        self, tcp_m: np.ndarray, axis: np.ndarray | None = None, guess: HybridPose | None = None
    ) -> HybridPose:
        """The module pose and wrist joints that put the TCP at ``tcp_m`` with the tool along ``axis``.

        Args:
            tcp_m: Shape (3,): TCP target in K [m].
            axis: Shape (3,): target tool axis in K (unit; two wrist actuators); None for a locked
                wrist (the TCP position only).
            guess: A solved pose to start from (default: :meth:`home`).

        Raises:
            UnreachableTargetError: no solution near the guess (the module's error when its
                task point is out of reach).
            JointLimitError: a tool joint beyond its URDF limits at the solution.
            SingularPoseError: the task Jacobian is singular at the solution.
        """
        target = values.within_length("tcp_m", values.vector("tcp_m", tcp_m, 3))
        across = self._across(axis)
        values.optional(values.instance, "guess", guess, HybridPose, "a solved HybridPose (HybridChain.home)")
        cur = guess if guess is not None else self.home()
        q_tool = cur.q_tool.copy()
        if self.wrist_offset_m is not None and across is not None:  # a decoupled wrist: P from the TCP
            p_w = target - self.wrist_offset_m * np.asarray(axis, dtype=float) / np.linalg.norm(
                np.asarray(axis)
            )
            try:
                pose = self.chain.inverse(p_w, cur.module.q_all + cur.tangent @ (p_w - cur.module.p_m))
            except KinematicsError as err:
                raise UnreachableTargetError(
                    target, f"the module's task point P = {np.round(p_w, 6).tolist()} m fails: {err}"
                ) from err
            q_tool = cur.q_tool.copy()
            q_tool[self.actuated] = self._wrist_many(pose.oMp.rotation[None], across[None], cur.q_tool[None])[
                0
            ]
            cur = self._assemble(pose, self._tangent(pose), q_tool)
        for _ in range(MAX_ITERATIONS):
            res, jac = task_rows(cur.twist_jacobian, cur.oMt, target, across)
            size = float(np.max(np.abs(res)))
            if size < TOLERANCE:
                return self._finish(cur, jac, size, target)
            step = _limited(np.linalg.lstsq(jac, -res, rcond=None)[0])
            p_new = cur.module.p_m + step[:3]
            q_tool = cur.q_tool.copy()
            q_tool[self.actuated] += step[3:]
            guess_q = cur.module.q_all + cur.tangent @ step[:3]
            try:
                pose = self.chain.inverse(p_new, guess_q)
            except KinematicsError as err:
                raise UnreachableTargetError(
                    target, f"the module's task point P = {np.round(p_new, 6).tolist()} m fails: {err}"
                ) from err
            cur = self._assemble(pose, self._tangent(pose), q_tool)
        raise UnreachableTargetError(
            target, f"the TCP task does not converge in {MAX_ITERATIONS} iterations ({size:.2g} left)", TOOL
        )

    def forward(
        self,
        u_module: np.ndarray,
        q_tool: np.ndarray,
        module_guess: np.ndarray,
        module_offsets: np.ndarray | None = None,
        tool_offsets: np.ndarray | None = None,
    ) -> tuple[Pose, pin.SE3]:
        """The TCP placement for given commands (this solver's models, e.g. perturbed ones).

        Args:
            u_module: The module's actuator readings (in ``chain.actuated_idx`` order).
            q_tool: Shape (nq_t,): the tool chain's commands (actuated) and set values (locked).
            module_guess: Shape (N,): initial guess of the module's joints.
            module_offsets: Shape (N,): the module's joint zero offsets (see
                :meth:`ClosedChain.forward`).
            tool_offsets: Shape (nq_t,): the tool chain's zero offsets (actual = command + δq).

        Returns:
            ``(module pose, oMt)``: the module's actual pose and the TCP placement in K.
        """
        q = self._tool_q("q_tool", q_tool)
        if tool_offsets is not None:
            q = q + self._tool_q("tool_offsets", tool_offsets)
        pose = self.chain.forward(u_module, module_guess, module_offsets)
        pMt, _ = tool_frames(self.tool, self.tool_model, self.tool_data, q)
        oMt = pose.oMp * pMt
        beyond = self.limit_violation(q, oMt.translation)  # a tool joint outside its limits (as inverse)
        if beyond is not None:
            raise beyond
        return pose, oMt

    def _finish(self, cur: HybridPose, jac: np.ndarray, size: float, target: np.ndarray) -> HybridPose:
        s = np.linalg.svd(jac, compute_uv=False)
        cond = float(s[0] / s[-1]) if s[-1] > 0 else np.inf
        if cond > SINGULAR_CONDITION:
            raise SingularPoseError("the hybrid task Jacobian (module + wrist)", cond, target)
        err = self.limit_violation(cur.q_tool, target)
        if err is not None:
            raise err
        return HybridPose(cur.module, cur.q_tool, cur.oMt, size, cond, cur.twist_jacobian, cur.tangent)

    def _decoupling(self) -> float | None:
        """``d`` when the tool axis passes through P, ``d`` before the TCP, at every wrist position.

        That is a wrist whose axes meet at P with the TCP on the spindle axis (else None). Then
        the module's task point is ``P = t* − d a*`` for a target (t*, a*), independent of the
        wrist joints: one module solve and a wrist-only solve reach it (kinematic decoupling, as
        for a spherical wrist).
        """
        if len(self.actuated) != 2:
            return None
        rng = np.random.default_rng(0)
        lo = np.where(np.isfinite(self._lower), self._lower, -np.pi)
        hi = np.where(np.isfinite(self._upper), self._upper, np.pi)
        q = rng.uniform(lo, hi, (8, self.tool.nq))
        q[:, list(self.tool.locked)] = self.tool.home[list(self.tool.locked)]
        rot, pos, _ = self.kinematics.frames(q)
        r = pos - self.chain.p_ref
        a = rot[:, :, 2]
        along = (r * a).sum(axis=1)
        across = np.linalg.norm(r - along[:, None] * a, axis=1)
        if across.max() > 1e-12 or np.ptp(along) > 1e-12 or abs(along[0]) < 1e-9:
            return None
        return float(along.mean())

    def _wrist_many(self, rot_p: np.ndarray, across: np.ndarray, q_tool: np.ndarray) -> np.ndarray:
        """The actuated wrist joints (b, 2) that turn the tool axis onto the targets, platforms fixed.

        Newton's method on ``Q* (R_p R_t(q) e_z) = 0`` (tool chain only), from ``q_tool`` (b, nq_t).
        """
        act = self.actuated
        q = np.array(q_tool, dtype=float)
        if not len(q):  # every module solve of the batch failed
            return q[:, act]
        for _ in range(MAX_ITERATIONS):
            rt, _, jt = self.kinematics.frames(q)
            rot = rot_p @ rt
            a = rot[:, :, 2]
            res = np.einsum("bij,bj->bi", across, a)
            if np.abs(res).max() < 1e-14:
                break
            w = rot @ jt[:, 3:][:, :, act]  # (b, 3, 2): the axis's angular velocity per joint (K)
            jac = np.einsum("bij,bjk->bik", across, cross_columns(w, a))  # −Q* (a × ω)
            step = solve_many(jac, -res)
            big = np.abs(step).max(axis=1) / STEP_LIMIT_JOINT
            q[:, act] += step / np.maximum(big, 1.0)[:, None]
        return q[:, act]

    def _predict_many(
        self,
        st: StackedPoses,
        targets: np.ndarray,
        across: np.ndarray | None,
        iterations: int = PREDICTOR_ITERATIONS,
    ) -> tuple[np.ndarray, np.ndarray]:
        """First guesses of P and the tool joints for new targets, off the solved poses ``st``.

        The module's platform is moved rigidly and to first order in ΔP (O' by its velocity, the
        orientation by ``exp3`` of its angular velocity per ΔP, both from the module's tangent), the
        tool chain exactly; this surrogate is solved by a few quasi-Newton steps (no module
        solve). Against the plain tangent step, it keeps the large second-order terms of the lever
        from O' to the TCP turning with the platform and the wrist.
        """
        act = self.actuated
        l0 = st.pos - st.pos_p  # O' → TCP (K)
        w_per_p = st.twist[:, 3:, :3]  # (b, 3, 3) platform angular velocity per ΔP (K)
        v_per_p = st.twist[:, :3, :3] - cross_columns(w_per_p, l0)  # + l0 × ω
        dp = np.zeros((len(st.p), 3))
        qt = st.qt.copy()
        for _ in range(iterations):
            theta = np.einsum("bij,bj->bi", w_per_p, dp)
            rp = exp3_many(theta) @ st.rot_p
            op = st.pos_p + np.einsum("bij,bj->bi", v_per_p, dp)
            rt, pt, jt = self.kinematics.frames(qt)
            rot = rp @ rt
            pos = op + np.einsum("bij,bj->bi", rp, pt)
            lever = pos - op
            twist = np.empty_like(st.twist)
            twist[:, :3, :3] = v_per_p + cross_columns(w_per_p, lever)  # − lever × ω
            twist[:, 3:, :3] = w_per_p
            twist[:, :3, 3:] = rot @ jt[:, :3][:, :, act]
            twist[:, 3:, 3:] = rot @ jt[:, 3:][:, :, act]
            res, jac = task_rows_many(twist, rot, pos, targets, across)
            step = limited_many(solve_many(jac, -res))
            dp += step[:, :3]
            qt[:, act] += step[:, 3:]
            if np.abs(step).max() < 1e-12:
                break
        return st.p + dp, qt

    def _finish_many(self, st, jac, size, done, active, targets, out) -> None:  # noqa: ANN001 - internal
        """:meth:`_finish` of the converged rows ``done`` of a batch (one stacked SVD), into ``out``."""
        rows = np.flatnonzero(done)
        sv = np.linalg.svd(jac[rows], compute_uv=False)
        with np.errstate(divide="ignore"):
            cond = np.where(sv[:, -1] > 0, sv[:, 0] / sv[:, -1], np.inf)
        qt = st.qt[rows]
        outside = ((qt < self._lower - 1e-12) | (qt > self._upper + 1e-12)).any(axis=1) & self.check_limits
        for r, pos in enumerate(rows):
            k = int(active[pos])
            if cond[r] > SINGULAR_CONDITION:
                out[k] = SingularPoseError(
                    "the hybrid task Jacobian (module + wrist)", float(cond[r]), targets[k]
                )
            elif outside[r]:
                out[k] = self.limit_violation(qt[r], targets[k])
            else:
                out[k] = st.pose(int(pos), float(size[pos]), float(cond[r]))

    def limit_violation(self, q_tool: np.ndarray, target: np.ndarray) -> JointLimitError | None:
        """The error for the first tool joint outside its URDF limits, or None."""
        q_tool = self._tool_q("q_tool", q_tool)
        values.vector("target", target, 3)
        if not self.check_limits:
            return None
        bad = np.flatnonzero((q_tool < self._lower - 1e-12) | (q_tool > self._upper + 1e-12))
        if not bad.size:
            return None
        k = int(bad[0])
        return JointLimitError(
            target,
            TOOL,
            self.tool.joint_names[k],
            float(q_tool[k]),
            float(self._lower[k]),
            float(self._upper[k]),
        )

    def _tangent(self, pose: Pose) -> np.ndarray:
        """The module's ``∂q/∂P`` (N, 3) at a pose (the exact linear step of its own predictor)."""
        if pose.tangent is not None:
            return pose.tangent
        q = pose.q_all
        return np.column_stack([self.chain.predict(pose, pose.p_m + e) - q for e in np.eye(3)])

    def _assemble(self, pose: Pose, tangent: np.ndarray, q_tool: np.ndarray) -> HybridPose:
        m0 = self.chain.models[0]
        d0 = self.chain.datas[0]
        j0 = pin.computeFrameJacobian(m0, d0, pose.q[0], self.chain.fids[0], pin.LOCAL)
        return self._assemble_from(pose, j0, tangent, q_tool)

    def _assemble_from(
        self, pose: Pose, j0: np.ndarray, tangent: np.ndarray, q_tool: np.ndarray
    ) -> HybridPose:
        pMt, jt = tool_frames(self.tool, self.tool_model, self.tool_data, q_tool)
        oMt = pose.oMp * pMt
        platform = j0 @ tangent[: self._nq0]  # (6, 3): platform twist (its frame) per unit ΔP
        local = np.hstack([pMt.toActionMatrixInverse() @ platform, jt[:, self.actuated]])
        twist = world_axes(oMt.rotation, local)
        return HybridPose(pose, q_tool, oMt, 0.0, 0.0, twist, tangent)

    def _across(self, axis: np.ndarray | None) -> np.ndarray | None:
        if not self.actuated:
            if axis is not None:
                raise InvalidRequestError(
                    "the wrist is locked (no actuated tool joint): the task is the TCP position; "
                    "give no tool axis"
                )
            return None
        if axis is None:
            raise InvalidRequestError("a machine with two wrist actuators needs a target tool axis")
        a = values.vector("axis", axis, 3)
        a = a / max(float(np.max(np.abs(a))), 1e-300)  # a direction: 1e308 entries do not overflow
        n = float(np.linalg.norm(a))
        if not n > 1e-12:
            raise InvalidRequestError(f"the target tool axis must be a non-zero vector, got {a.tolist()}")
        return orthonormal_across(a / n)

    # --- many poses ---------------------------------------------------------------------

    def inverse_many(
        self, tcp_m: np.ndarray, axes: np.ndarray | None, guesses: list[HybridPose]
    ) -> list[HybridPose | KinematicsError]:
        """:meth:`inverse` of B targets together, the module solved by :meth:`BatchChain.inverse`.

        The same Newton iterations as :meth:`inverse`, stacked over the targets (the tool chain by
        :class:`~pkmtol.kinematics.tool_chain.ToolKinematics`, the 5 × 5 steps by one stacked
        solve); a target leaves the batch when it converges.

        Args:
            tcp_m: Shape (B, 3): TCP targets [m].
            axes: Shape (B, 3): target tool axes (None for a locked wrist).
            guesses: B solved poses to start from (e.g. solved neighbours).

        Returns:
            Per target: its pose, or the error :meth:`inverse` raises for it.
        """
        targets = values.within_length("tcp_m", values.array_of_shape("tcp_m", tcp_m, (None, 3)))
        b = len(targets)
        values.instances("guesses", guesses, HybridPose, "solved HybridPose", b)
        if not b:
            return []
        if axes is None:
            self._across(None)
            across = None
        else:
            a = values.array_of_shape("axes", axes, (b, 3))
            a = a / np.maximum(np.abs(a).max(axis=1, keepdims=True), 1e-300)
            if not np.all(np.linalg.norm(a, axis=1) > 1e-12):
                raise InvalidArgumentError("axes", axes, "every tool axis must be a non-zero vector")
            if not self.actuated:
                self._across(a[0])
            across = across_many(a / np.linalg.norm(a, axis=1, keepdims=True))
        st = StackedPoses.of(guesses)
        out: list[HybridPose | KinematicsError | None] = [None] * b
        active = np.arange(b)
        act = self.actuated
        first = True
        if self.wrist_offset_m is not None and across is not None:  # a decoupled wrist: P from the TCP
            a_unit = np.asarray(axes, dtype=float).reshape(b, 3)
            p_w = targets - self.wrist_offset_m * a_unit / np.linalg.norm(a_unit, axis=1, keepdims=True)
            guess = st.qm + np.einsum("bnk,bk->bn", st.tangent, p_w - st.p)
            sols = self.batch.inverse(p_w, guess)
            for pos in np.flatnonzero(~sols.ok):
                out[pos] = UnreachableTargetError(
                    targets[pos],
                    f"the module's task point P = {np.round(p_w[pos], 6).tolist()} m fails: "
                    f"{sols.errors[pos]}",
                )
            idx = np.flatnonzero(sols.ok)
            # the wrist from the guesses' tangent step (their task Jacobian), then its own Newton
            res0, jac0 = task_rows_many(st.twist, st.rot, st.pos, targets, across)
            qt = st.qt.copy()
            qt[:, act] += limited_many(solve_many(jac0, -res0))[:, 3:]
            qt = qt[idx]
            qt[:, act] = self._wrist_many(sols.rotation[idx], across[idx], qt)
            rt, pt, jt = self.kinematics.frames(qt)
            st = StackedPoses.from_solutions(sols, idx, qt, rt, pt, jt, act, self._nq0)
            active, first = idx, False
        for _ in range(MAX_ITERATIONS + 1):
            res, jac = task_rows_many(
                st.twist, st.rot, st.pos, targets[active], None if across is None else across[active]
            )
            size = np.abs(res).max(axis=1)
            done = size < TOLERANCE
            if done.any():
                self._finish_many(st, jac, size, done, active, targets, out)
            keep = ~done
            if not keep.any():
                break
            st, res, jac, active = st.take(keep), res[keep], jac[keep], active[keep]
            if first:  # from the guesses: the rigid predictor (the wrist and the lever exact)
                p_new, qt_new = self._predict_many(
                    st, targets[active], None if across is None else across[active]
                )
                step = np.hstack([p_new - st.p, qt_new[:, act] - st.qt[:, act]])
                first = False
            else:
                step = limited_many(solve_many(jac, -res))
                p_new = st.p + step[:, :3]
                qt_new = st.qt.copy()
                qt_new[:, act] += step[:, 3:]
            guess = st.qm + np.einsum("bnk,bk->bn", st.tangent, step[:, :3])
            sols = self.batch.inverse(p_new, guess)
            ok = sols.ok
            for pos in np.flatnonzero(~ok):
                k = int(active[pos])
                out[k] = UnreachableTargetError(
                    targets[k],
                    f"the module's task point P = {np.round(p_new[pos], 6).tolist()} m fails: "
                    f"{sols.errors[pos]}",
                )
            idx = np.flatnonzero(ok)
            active = active[idx]
            if not idx.size:
                break
            rt, pt, jt = self.kinematics.frames(qt_new[idx])
            st = StackedPoses.from_solutions(sols, idx, qt_new[idx], rt, pt, jt, act, self._nq0)
        for k in range(b):
            if out[k] is None:
                out[k] = UnreachableTargetError(
                    targets[k], f"the TCP task does not converge in {MAX_ITERATIONS} iterations", TOOL
                )
        return [o for o in out if o is not None]


def _limited(step: np.ndarray) -> np.ndarray:
    """A Newton step scaled down to :data:`STEP_LIMIT_M` on P and :data:`STEP_LIMIT_JOINT` on the wrist."""
    big = max(
        float(np.max(np.abs(step[:3]))) / STEP_LIMIT_M,
        float(np.max(np.abs(step[3:]), initial=0.0)) / STEP_LIMIT_JOINT,
    )
    return step / big if big > 1.0 else step


def task_grid(mechanism: Mechanism) -> tuple[np.ndarray, np.ndarray | None]:
    """A hybrid's task grid: every TCP point of ``task_space`` with every tool axis of the cone.

    Returns:
        ``(tcp (m, 3) [m], axes (m, 3) or None)``: point-major (all axes of point 0, then of
        point 1, …); None for a locked wrist.
    """
    points = mechanism.task_space.grid()
    if mechanism.tool_directions is None:
        return points, None
    dirs = mechanism.tool_directions.grid()
    return np.repeat(points, len(dirs), axis=0), np.tile(dirs, (len(points), 1))
