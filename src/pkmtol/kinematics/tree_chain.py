"""Closed-chain kinematics of a :class:`~pkmtol.model.loop_tree.LoopTree`: Newton on the tree's joint vector.

Unknowns: every joint of the tree, ``q`` (n). Equations: each loop's closure, then (inverse
problems) the task rows. With spatial twists (:mod:`pkmtol.kinematics.tree_frames`; ``T_f`` the
spatial Jacobian of frame f, the columns of the joints that move it):

    6d:   r = log6(oMa⁻¹ oMb)   ∂r = Jlog6(E) Ad(oMb⁻¹) (T_b − T_a)          (frame a's residual)
    3d:   r = p_b − p_a         ∂r = [I −[p_b×]] T_b − [I −[p_a×]] T_a      (K)
    task: r = oMt · P − target  ∂r = [I −[p×]] T_t                          (K)

the same equations as the limb path's (:class:`~pkmtol.kinematics.closed_chain.ClosedChain`, whose
platform closures are ``6d`` loops between platform frames). :class:`TreeBatch` solves ``B``
problems in lockstep (the kinematics stacked over the poses, stacked LU / QR steps), with the limb
path's stopping rule (1e-13, or a stall below 1e-11), step limit (0.5), iteration cap (40),
condition bound (``κ_F``, SVD above 1e8) and errors; :class:`TreeChain` is its per-pose face.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import (
    ConvergenceError,
    InvalidArgumentError,
    JointLimitError,
    KinematicsError,
    LoopMismatchError,
    SingularPoseError,
    UnreachableTargetError,
)
from pkmtol.kinematics import se3_batch
from pkmtol.kinematics.closed_chain import (
    MAX_ITERATIONS,
    SINGULAR_CONDITION,
    SINGULAR_RESIDUAL,
    TOLERANCE,
    Pose,
)
from pkmtol.kinematics.solutions import Solutions
from pkmtol.kinematics.stacked_solve import condition_bound, exact_condition, newton_steps
from pkmtol.kinematics.tree_frames import (
    TreePoses,
    TreeTables,
    adjoint_inverse,
    forward,
    point_rows,
    tree_kernel,
)
from pkmtol.model.loop_tree import LoopTree, PointTask

#: No task rows (forward problems), for the compiled rows.
_NO_TARGETS = np.zeros((0, 3))


class TreeBatch:
    """Batched closed-chain solver of a :class:`LoopTree` (not thread-safe).

    Args:
        tree: The mechanism.
        check_limits: Check the joint limits of every solution, and the actuators' commands of
            :meth:`forward` (as :class:`ClosedChain` does).
    """

    def __init__(self, tree: LoopTree, check_limits: bool = True) -> None:
        values.instance("tree", tree, LoopTree, "a pkmtol LoopTree")
        values.flag("check_limits", check_limits)
        self.tree = tree
        self.tables = TreeTables.of(tree)
        self.n_joints = tree.nq
        self.actuated_idx = np.array(tree.actuated, dtype=int)
        self.lower = np.asarray(tree.model.lowerPositionLimit, dtype=float)
        self.upper = np.asarray(tree.model.upperPositionLimit, dtype=float)
        self.check_limits = check_limits
        self._masks = [(tree.support(lp.frame_a), tree.support(lp.frame_b)) for lp in tree.loops]
        self._task_mask = tree.support(tree.task_frame)
        rows, start = [], 0
        for lp in tree.loops:
            rows.append(slice(start, start + lp.rows))
            start += lp.rows
        self.loop_slices = rows
        self.n_equations = start
        frames = tree.model.frames
        self._k_args = (
            np.array([lp.kind == "6d" for lp in tree.loops], dtype=bool),
            np.array([int(frames[lp.frame_a].parentJoint) - 1 for lp in tree.loops], dtype=np.int64),
            np.array([frames[lp.frame_a].placement.homogeneous for lp in tree.loops]).reshape(-1, 4, 4),
            np.array([int(frames[lp.frame_b].parentJoint) - 1 for lp in tree.loops], dtype=np.int64),
            np.array([frames[lp.frame_b].placement.homogeneous for lp in tree.loops]).reshape(-1, 4, 4),
            np.array([m[0] for m in self._masks], dtype=bool).reshape(-1, tree.nq),
            np.array([m[1] for m in self._masks], dtype=bool).reshape(-1, tree.nq),
            np.array([sl.start for sl in rows] + [start], dtype=np.int64),
            int(frames[tree.task_frame].parentJoint) - 1,
            frames[tree.task_frame].placement.homogeneous,
            self._task_mask,
            np.asarray(tree.task.point_m, dtype=float),
        )
        self.chain = TreeChain(self)

    # --- public ---------------------------------------------------------------------------

    def inverse(self, targets_m: np.ndarray, guesses: np.ndarray) -> Solutions:
        """Joint values that put the task point at each target.

        Args:
            targets_m: Shape (B, 3): targets of the task point in K [m].
            guesses: Shape (B, n): initial guesses.

        Returns:
            The solutions (``rotation``/``translation``: the platform frame's placement, ``p_m``
            the task point, ``jacobians`` the task frame's LOCAL Jacobian); a problem's error
            is an :class:`UnreachableTargetError`, :class:`JointLimitError` or :class:`SingularPoseError`.
        """
        targets = values.within_length("targets_m", values.array_of_shape("targets_m", targets_m, (None, 3)))
        q0 = values.array_of_shape("guesses", guesses, (len(targets), self.n_joints)).copy()
        sols = self._newton(q0, np.ones(self.n_joints, dtype=bool), targets, "inverse kinematics")
        errors = list(sols.errors)
        outside = np.asarray(
            ((sols.q < self.lower - 1e-12) | (sols.q > self.upper + 1e-12)).any(axis=1)
        ).tolist()
        bad_rows = [bool(x) and self.check_limits for x in outside]
        for k, err in enumerate(errors):
            if isinstance(err, ConvergenceError):
                errors[k] = UnreachableTargetError(
                    targets[k],
                    "the loop and task equations have no solution near the initial guess "
                    f"({err.residual:.2g} left; the largest gap is at loop "
                    f"'{self.worst_loop(sols.q[k])[1]}')",
                )
            elif isinstance(err, SingularPoseError):
                errors[k] = SingularPoseError(err.what, err.condition, targets[k])
            elif err is None and bad_rows[k]:
                errors[k] = self.limit_violation(sols.q[k], targets[k])
        return replace(sols, errors=tuple(errors))

    def forward(
        self, q_actuated: np.ndarray, guesses: np.ndarray, offsets: np.ndarray | None = None
    ) -> Solutions:
        """Poses for given actuator readings (actual value = reading + offset; passive joints solved).

        Args:
            q_actuated: Shape (B, f): actuator readings, in the order of ``tree.actuated``.
            guesses: Shape (B, n): initial guesses for all joints.
            offsets: Shape (B, n): joint zero offsets (only the actuated entries matter).

        Returns:
            The solutions; a problem's error is a :class:`ConvergenceError`,
            :class:`SingularPoseError` or, with ``check_limits``, a :class:`JointLimitError` (a
            passive joint beyond its limits at the solution), as for :meth:`inverse`.

        Raises:
            InvalidArgumentError: with ``check_limits``, an actuator (reading + offset) outside its
                limits (as :meth:`ClosedChain.forward`; names the problem and the actuator).
        """
        q = values.array_of_shape("guesses", guesses, (None, self.n_joints)).copy()
        act = self.actuated_idx
        u = values.array_of_shape("q_actuated", q_actuated, (len(q), act.size))
        q[:, act] = u
        if offsets is not None:
            q[:, act] += values.array_of_shape("offsets", offsets, q.shape)[:, act]
        if self.check_limits:
            self._check_commands(q_actuated, q)
        free = np.ones(self.n_joints, dtype=bool)
        free[self.actuated_idx] = False
        sols = self._newton(q, free, None, "forward kinematics")
        if not self.check_limits:
            return sols
        errors = list(sols.errors)
        for k, err in enumerate(errors):
            if err is None:
                errors[k] = self.limit_violation(sols.q[k], sols.p_m[k])
        return replace(sols, errors=tuple(errors))

    def _check_commands(self, q_actuated: object, q: np.ndarray) -> None:
        """Refuse actuator values (readings + offsets, in ``q`` (B, n)) outside their limits."""
        act = self.actuated_idx
        outside = (q[:, act] < self.lower[act] - 1e-12) | (q[:, act] > self.upper[act] + 1e-12)
        if not outside.any():
            return
        b, k = (int(x) for x in np.argwhere(outside)[0])
        i = int(act[k])
        where = f"row {b}, entry {k}" if len(q) > 1 else f"entry {k}"
        raise InvalidArgumentError(
            "q_actuated",
            q_actuated,
            f"{where}, actuator '{self.tree.joint_names[i]}' of '{self.tree.name}', would be at "
            f"{q[b, i]:.6g} [rad or m], outside its limits [{self.lower[i]:.6g}, {self.upper[i]:.6g}]; "
            "command values within the URDF limits (or build the solver with check_limits=False)",
        )

    def predict(self, sols: Solutions, index: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
        """First-order guesses for ``targets_m`` from solved problems ``index``: ``q + A⁻¹[0; Δp]``."""
        values.instance("sols", sols, Solutions, "the Solutions of TreeBatch.inverse")
        index = values.indices("index", index, len(sols.q))
        dp = values.array_of_shape("targets_m", targets_m, (len(index), 3)) - sols.p_m[index]
        return sols.q[index] + (sols.system_inverse[index][:, :, -3:] @ dp[:, :, None])[:, :, 0]

    def system(self, q: np.ndarray, targets: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, TreePoses]:
        """Residuals (b, rows), Jacobians (b, rows, n) and the kinematics at ``q`` (b, n)."""
        q = values.array_of_shape("q", q, (None, self.n_joints), finite=False)  # Newton iterates
        targets = values.optional(values.array_of_shape, "targets", targets, (len(q), 3), finite=False)
        poses = forward(self.tables, q)
        b = len(poses.joint)
        rows = self.n_equations + (self.tree.task.rows if targets is not None else 0)
        res = np.empty((b, rows))
        jac = np.zeros((b, rows, self.n_joints))
        kernel = tree_kernel()
        if kernel is not None and type(self.tree.task) is PointTask:
            near = np.zeros(b, dtype=bool)
            kernel.tree_system(
                poses.joint,
                poses.columns,
                *self._k_args,
                _NO_TARGETS if targets is None else targets,
                res,
                jac,
                near,
            )
            for k in np.flatnonzero(near):  # a loop near a half turn: the numpy rows (Pinocchio's log6)
                one = forward(self.tables, q[k][None])
                for lp, sl, (ma, mb) in zip(self.tree.loops, self.loop_slices, self._masks, strict=True):
                    ha, hb = one.frame(self.tree, lp.frame_a), one.frame(self.tree, lp.frame_b)
                    r_k, j_k = loop_rows_world(lp.kind, ha, hb, one.columns, ma, mb)
                    res[k, sl], jac[k, sl] = r_k[0], j_k[0]
            return res, jac, poses
        for lp, sl, (ma, mb) in zip(self.tree.loops, self.loop_slices, self._masks, strict=True):
            ha, hb = poses.frame(self.tree, lp.frame_a), poses.frame(self.tree, lp.frame_b)
            res[:, sl], jac[:, sl] = loop_rows_world(lp.kind, ha, hb, poses.columns, ma, mb)
        if targets is not None:
            ht = poses.frame(self.tree, self.tree.task_frame)
            n = self.n_equations
            res[:, n:] = self.tree.task.residual(ht, targets)
            jac[:, n:] = self.tree.task.jacobian(ht, poses.columns * self._task_mask)
        return res, jac, poses

    def worst_loop(self, q: np.ndarray) -> tuple[str, str, tuple[str, str], float, float]:
        """The loop with the largest gap at ``q`` (n,): ``(mechanism, loop, frames, gap [m], [rad])``."""
        q = values.array_of_shape("q", q, (self.n_joints,), finite=False)  # a diverged solve: its gaps
        poses = forward(self.tables, q[None])
        worst = (self.tree.name, "-", ("", ""), 0.0, 0.0)
        for lp in self.tree.loops:
            ha, hb = poses.frame(self.tree, lp.frame_a)[0], poses.frame(self.tree, lp.frame_b)[0]
            dist = float(np.linalg.norm(hb[:3, 3] - ha[:3, 3]))
            ang = float(np.linalg.norm(pin.log3(ha[:3, :3].T @ hb[:3, :3]))) if lp.kind == "6d" else 0.0
            if dist + ang > worst[3] + worst[4] or worst[1] == "-":
                worst = (self.tree.name, lp.name, lp.frame_names, dist, ang)
        return worst

    def limit_violation(self, q: np.ndarray, target: np.ndarray) -> JointLimitError | None:
        """The error for the first joint of ``q`` outside its limits, or None."""
        q = values.vector("q", q, self.n_joints)
        target = values.vector("target", target, 3)
        bad = np.flatnonzero((q < self.lower - 1e-12) | (q > self.upper + 1e-12))
        if not bad.size:
            return None
        k = int(bad[0])
        return JointLimitError(
            target,
            self.tree.name,
            self.tree.joint_names[k],
            float(q[k]),
            float(self.lower[k]),
            float(self.upper[k]),
        )

    # --- internals ------------------------------------------------------------------------

    def _newton(self, q0: np.ndarray, free: np.ndarray, targets: np.ndarray | None, what: str) -> Solutions:
        """Lockstep Newton on the free joints (the rules of ``ClosedChain._newton``)."""
        count = len(q0)
        q = q0.copy()
        rows = self.n_equations + (self.tree.task.rows if targets is not None else 0)
        n_free = int(free.sum())
        system = np.zeros((count, rows, n_free))
        residual = np.full(count, np.nan)
        done_h = np.zeros((count, 4, 4))  # the task frame's placement
        done_p = np.zeros((count, 4, 4))  # the platform frame's
        errors: list[KinematicsError | None] = [None] * count
        prev = np.full(count, np.inf)
        active = np.arange(count)
        solved: list[np.ndarray] = []
        for _ in range(MAX_ITERATIONS if count else 0):
            res, jac, poses = self.system(q[active], None if targets is None else targets[active])
            a = jac[:, :, free]
            norm = np.abs(res).max(axis=1, initial=0.0)
            bad = ~(np.isfinite(norm) & np.isfinite(a).all(axis=(1, 2)))
            conv = (norm < TOLERANCE) | ((norm < 1e-11) & (norm >= prev[active]))
            if conv.any():
                idx = active[conv]
                done_h[idx] = poses.frame(self.tree, self.tree.task_frame)[conv]
                done_p[idx] = poses.frame(self.tree, self.tree.platform_frame)[conv]
                system[idx] = a[conv]
                residual[idx] = np.linalg.norm(res[conv], axis=1)
                solved.append(idx)
            for k in active[bad & ~conv]:
                errors[int(k)] = ConvergenceError(f"{what} (the equations overflowed)", float("inf"), 0)
            keep = ~conv & ~bad
            active, a, res, norm = active[keep], a[keep], res[keep], norm[keep]
            if not active.size:
                break
            step = newton_steps(a, res, compiled=True)
            big = np.abs(step).max(axis=1, initial=0.0)
            step *= np.where(big > 0.5, 0.5 / np.where(big > 0.5, big, 1.0), 1.0)[:, None]
            sub = q[active]
            sub[:, free] -= step
            q[active] = sub
            prev[active] = norm
        for k in active:
            res_k, jac_k, _ = self.system(q[k][None], None if targets is None else targets[k][None])
            cond_k = exact_condition(jac_k[0][:, free])
            if cond_k > SINGULAR_CONDITION and prev[k] < SINGULAR_RESIDUAL:
                errors[int(k)] = SingularPoseError(f"the {what} Jacobian", cond_k)
            else:
                errors[int(k)] = ConvergenceError(what, float(prev[k]), MAX_ITERATIONS)
        idx = np.concatenate(solved) if solved else np.zeros(0, dtype=int)
        condition = np.full(count, np.nan)
        inverse = np.full((count, n_free, rows), np.nan)
        if idx.size:
            cond, inv = condition_bound(system[idx])
            condition[idx], inverse[idx] = cond, inv
            for pos, k in enumerate(idx):
                if rows < n_free or cond[pos] > SINGULAR_CONDITION:
                    exact = exact_condition(system[k])
                    condition[k] = exact
                    if rows < n_free or exact > SINGULAR_CONDITION:
                        errors[int(k)] = SingularPoseError(f"the {what} Jacobian", exact)
        for k in np.flatnonzero(np.isnan(residual)):
            last = forward(self.tables, q[k][None])
            done_h[k] = last.frame(self.tree, self.tree.task_frame)[0]
            done_p[k] = last.frame(self.tree, self.tree.platform_frame)[0]
        r, t = done_p[:, :3, :3], done_p[:, :3, 3]
        local = self._task_local(q)
        return Solutions(
            q=q,
            rotation=r,
            translation=t,
            p_m=self.tree.task.position(done_h),
            residual=residual,
            condition=condition,
            jacobians=(local,),
            system=system,
            system_inverse=inverse,
            errors=tuple(errors),
            limb_offsets=(0, self.n_joints),
            task=targets is not None,
        )

    def _task_local(self, q: np.ndarray) -> np.ndarray:
        """LOCAL Jacobians (b, 6, n) of the task frame."""
        poses = forward(self.tables, q)
        h = poses.frame(self.tree, self.tree.task_frame)
        return adjoint_inverse(h) @ (poses.columns * self._task_mask)


class TreeChain:
    """Per-pose solves of a :class:`LoopTree` (each a batch of one of :class:`TreeBatch`).

    Args:
        batch: The batch solver whose workspaces it shares (or a tree: one is made).
    """

    def __init__(self, batch: TreeBatch | LoopTree) -> None:
        values.instance("batch", batch, (TreeBatch, LoopTree), "a TreeBatch or a LoopTree")
        self.batch = batch if isinstance(batch, TreeBatch) else TreeBatch(batch)
        self.tree = self.batch.tree

    def home(self) -> np.ndarray:
        """``tree.home`` refined to exact closure with the actuators held (n,).

        Raises:
            LoopMismatchError: a loop cannot be closed near ``home`` (names the loop and its gap).
        """
        home = self.tree.home
        sols = self.batch.forward(home[self.batch.actuated_idx][None], home[None])
        if sols.errors[0] is not None:
            _, loop, frames, dist, ang = self.batch.worst_loop(home)
            raise LoopMismatchError(self.tree.name, loop, frames, dist, ang) from sols.errors[0]
        return sols.q[0]

    def inverse(self, target_m: np.ndarray, q0: np.ndarray | None = None) -> Pose:
        """All joint values that put the task point at ``target_m`` (3,) [m] (errors as the batch's)."""
        target = values.vector("target_m", target_m, 3)
        start = self.home() if q0 is None else values.vector("q0", q0, self.batch.n_joints)
        return self.batch.inverse(target[None], start[None]).pose(0)

    def forward(self, q_actuated: np.ndarray, q0: np.ndarray, offsets: np.ndarray | None = None) -> Pose:
        """The pose for actuator readings ``q_actuated`` (f,) from the guess ``q0`` (n,)."""
        n = self.batch.n_joints
        off = None if offsets is None else values.vector("offsets", offsets, n)[None]
        u = values.vector("q_actuated", q_actuated, self.batch.actuated_idx.size)
        guess = values.vector("q0", q0, n)[None]
        if self.batch.check_limits:  # the error quotes the caller's (f,) commands, not a batch of one
            q = guess.copy()
            q[0, self.batch.actuated_idx] = u + (0.0 if off is None else off[0, self.batch.actuated_idx])
            self.batch._check_commands(q_actuated, q)
        return self.batch.forward(u[None], guess, off).pose(0)


def loop_rows_world(
    kind: str, ha: np.ndarray, hb: np.ndarray, columns: np.ndarray, ma: np.ndarray, mb: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """One loop's residual (b, rows) and Jacobian (b, rows, k) from spatial columns.

    Args:
        kind: ``"6d"`` or ``"3d"``.
        ha: Shape (b, 4, 4): placements of frame a.
        hb: Shape (b, 4, 4): placements of frame b.
        columns: Shape (b, 6, k): spatial twist per unit of ``k`` variables (joints or errors).
        ma: Shape (k,): which variables move frame a.
        mb: Shape (k,): which variables move frame b.
    """
    if kind == "3d":
        jb = point_rows(hb[:, :3, 3], columns * mb)
        ja = point_rows(ha[:, :3, 3], columns * ma)
        return hb[:, :3, 3] - ha[:, :3, 3], jb - ja
    ra, pa = ha[:, :3, :3], ha[:, :3, 3]
    rat = np.swapaxes(ra, 1, 2)
    re = rat @ hb[:, :3, :3]
    pe = (rat @ (hb[:, :3, 3] - pa)[:, :, None])[:, :, 0]
    nu, jl, near = se3_batch.log6_and_jacobian(re, pe)
    for k in np.flatnonzero(near):  # near a half turn: Pinocchio's log6
        e = pin.SE3(ha[k]).actInv(pin.SE3(hb[k]))
        nu[k], jl[k] = pin.log6(e).vector, pin.Jlog6(e)
    diff = columns * (mb.astype(float) - ma.astype(float))
    return nu, (jl @ adjoint_inverse(hb)) @ diff


def perturbed_tree(tree: LoopTree, raw: np.ndarray) -> tuple[LoopTree, np.ndarray]:
    """The tree of a machine with raw errors ``raw`` (n_raw,), and its joint offsets (n,).

    Joint placements become ``jointPlacements[j] · exp6(ε_j)``; an error frame's or a loop's error
    ``ε`` moves each frame g it moves (on the same body as its frame F) to ``F · exp6(ε) · F⁻¹ · g``.
    """
    raw = np.asarray(raw, dtype=float).reshape(tree.n_raw)
    model = pin.Model(tree.model)
    for j in range(tree.nq):
        blk = raw[tree.raw_block("joint", j)]
        model.jointPlacements[j + 1] = model.jointPlacements[j + 1] * pin.exp6(blk)
    moves = [(ef.frame, ef.moves, raw[tree.raw_block("frame", k)]) for k, ef in enumerate(tree.error_frames)]
    moves += [
        (lp.frame_b, mv, raw[tree.raw_block("loop", k)])
        for k, (lp, mv) in enumerate(zip(tree.loops, tree.loop_moves, strict=True))
    ]
    for fid, frames, eps in moves:
        if not np.any(eps):
            continue
        pf = tree.model.frames[fid].placement
        change = pf * pin.exp6(eps) * pf.inverse()
        for g in frames:
            f = model.frames[g]
            f.placement = change * tree.model.frames[g].placement
            model.frames[g] = f
    return replace(tree, model=model), raw[tree.offset_start :].copy()
