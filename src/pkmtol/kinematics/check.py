"""Checking a mechanism: structure, mobility, constraints, reachability and conditioning.

:func:`check_mechanism` is what ``pkmtol check robots/<robot>`` prints: for each limb its joints
and the number of constraint wrenches it exerts on the platform; the mobility of the closed chain;
and, walking the task-space grid with inverse kinematics (each point warm-started from the previous
solution), which points are reachable, the joint ranges used, and the worst conditioning. The
actuation is counted first (:mod:`pkmtol.kinematics.mobility`): with too few, too many or misplaced
actuators the report says how many are needed and solves nothing else.

Ranks are numerical (SVD, singular values below :data:`RANK_TOLERANCE` times the largest count as
zero) and evaluated at the home configuration refined to exact closure. Jacobians mix metres and
radians, so their condition numbers depend on that choice of units; they are for comparing poses of
one mechanism, not mechanisms with each other.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from pkmtol.exceptions import InvalidArgumentError, KinematicsError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.hybrid import HybridChain, task_grid
from pkmtol.kinematics.hybrid_continuation import hybrid_continuation
from pkmtol.kinematics.loops import frame_placements, loop_rows
from pkmtol.model.limb import Limb
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.tool import TOOL

#: Singular values below this fraction of the largest count as zero in rank decisions.
RANK_TOLERANCE = 1e-9


@dataclass(frozen=True)
class JointReport:
    """One joint of a limb.

    Attributes:
        name: Joint name.
        kind: ``"R"`` (revolute) or ``"P"`` (prismatic).
        actuated: Whether the joint is actuated.
        lower: Lower limit from the URDF [rad or m].
        upper: Upper limit from the URDF [rad or m].
        grid_min: Smallest value over the reachable task-space points [rad or m] (nan if none).
        grid_max: Largest value over the reachable task-space points [rad or m] (nan if none).

    """

    name: str
    kind: str
    actuated: bool
    lower: float
    upper: float
    grid_min: float
    grid_max: float


@dataclass(frozen=True)
class LimbReport:
    """One limb: its joints and the constraints it puts on the platform.

    Attributes:
        name: Limb name.
        urdf_path: Source URDF (None for a limb built from a ``pin.Model``).
        joints: The joints, base to platform.
        twist_rank: Rank of the limb's joint twists (its platform-frame Jacobian, shape (6, nq);
            for a limb with internal loops, the motions that keep them closed) at home.
        constraint_count: Number of independent constraint wrenches, ``6 - twist_rank``.

    """

    name: str
    urdf_path: Path | None
    joints: tuple[JointReport, ...]
    twist_rank: int
    constraint_count: int


@dataclass(frozen=True)
class PointReport:
    """Inverse kinematics at one task-space point.

    Attributes:
        target_m: Target position of P in K, shape (3,) [m].
        error: Why the point failed (the pkmtol error message), None if it is reachable.
        q: All joint values at the solution (Σ nq,) [rad or m]; None if unreachable.
        inverse_condition: Condition number of the inverse-kinematics Jacobian (closure and task
            rows, all joints); nan if unreachable.
        forward_condition: Condition number of the forward-kinematics Jacobian (closure rows,
            passive joints; the actuators held); nan if unreachable.

    """

    target_m: np.ndarray
    error: str | None
    q: np.ndarray | None
    inverse_condition: float
    forward_condition: float

    @property
    def reachable(self) -> bool:
        """Whether inverse kinematics succeeded here (within limits, not singular)."""
        return self.error is None


@dataclass(frozen=True)
class CheckReport:
    """Everything ``pkmtol check`` reports about a mechanism.

    Attributes:
        mechanism: The mechanism checked.
        limbs: Per-limb reports, in limb order.
        home_q: Home configuration refined to exact closure (Σ nq,) [rad or m].
        closure_rank: Rank of the closure Jacobian (shape (6(L-1), Σ nq)) at home.
        points: One report per task-space grid point, in grid order (a hybrid: per target of
            its TCP task, the TCP position in ``target_m``).
        tool: A hybrid's tool chain (its joints and the ranges they use over the task grid;
            ``twist_rank`` is the rank of its TCP Jacobian at home), None for a parallel module.
        actuation: What is wrong with the actuation, counted before the home solve
            (:mod:`pkmtol.kinematics.mobility`); when not empty, the home pose and the grid are
            not solved (``points`` is empty, ``home_q`` the TOML's home, ``closure_rank`` counted
            with every joint free).
    """

    mechanism: Mechanism
    limbs: tuple[LimbReport, ...]
    home_q: np.ndarray
    closure_rank: int
    points: tuple[PointReport, ...]
    tool: LimbReport | None = None
    actuation: tuple[str, ...] = ()

    @property
    def n_joints(self) -> int:
        """Total number of joints."""
        return self.mechanism.n_joints

    @property
    def mobility(self) -> int:
        """Mobility ``f`` = joints − rank of the closure Jacobian at home."""
        return self.n_joints - self.closure_rank

    @property
    def n_reachable(self) -> int:
        """Number of reachable task-space points."""
        return sum(p.reachable for p in self.points)

    @property
    def unreachable(self) -> tuple[PointReport, ...]:
        """The points where inverse kinematics failed."""
        return tuple(p for p in self.points if not p.reachable)

    def worst(self, which: str) -> PointReport | None:
        """Return the reachable point with the largest ``"inverse"``/``"forward"`` condition."""
        ok = [p for p in self.points if p.reachable]
        if not ok:
            return None
        return max(ok, key=lambda p: float(getattr(p, f"{which}_condition")))

    @property
    def problems(self) -> tuple[str, ...]:
        """What stops the mechanism from being used as described (empty when all is well)."""
        out = list(self.actuation)
        if self.actuation:
            return tuple(out)
        if self.unreachable:
            out.append(f"{len(self.unreachable)} of {len(self.points)} task-space points are not reachable")
        if self.mobility != self.mechanism.n_actuators:
            out.append(
                f"mobility {self.mobility} differs from the {self.mechanism.n_actuators} "
                "actuators: the actuators do not determine the pose"
            )
        return tuple(out)


def check_mechanism(mechanism: Mechanism, progress: bool = False) -> CheckReport:
    """Check a mechanism at home and over its task-space grid.

    Args:
        mechanism: The mechanism (already validated by loading).
        progress: Show a progress bar over the grid points (on stderr).

    Returns:
        The report; unreachable points are recorded in it, not raised.

    Raises:
        PlatformMismatchError: the limbs cannot be closed at home.

    """
    if not isinstance(mechanism, Mechanism):
        raise InvalidArgumentError("mechanism", mechanism, "expected a pkmtol.Mechanism (load_mechanism)")
    chain = ClosedChain(mechanism)
    mobility = chain.mobility()  # before the home solve, which holds the actuators
    if mobility.problems:
        return _actuation_report(mechanism, chain, mobility.closure_rank, mobility.problems)
    home_q = chain.home()
    closure_jacobian = chain._evaluate(home_q, None)[1]
    closure_rank = _rank(closure_jacobian)
    passive = np.ones(home_q.size, dtype=bool)
    passive[chain.actuated_idx] = False

    points = []
    q_prev = home_q
    grid = mechanism.task_space.grid() if mechanism.tool is None else np.zeros((0, 3))
    for target in tqdm(grid, desc="check", unit="point", disable=not progress, leave=False):
        point = _solve_point(chain, target, q_prev, home_q, passive)
        if point.q is not None:
            q_prev = point.q
        points.append(point)
    tool = None
    if mechanism.tool is not None:  # a hybrid: its TCP task, the wrist's joints beside the limbs'
        points, tool = _hybrid_points(mechanism, chain, passive)

    reached = [p.q for p in points if p.q is not None]
    q_min = np.min(reached, axis=0) if reached else np.full(home_q.size, np.nan)
    q_max = np.max(reached, axis=0) if reached else np.full(home_q.size, np.nan)
    limbs = _limb_reports(mechanism, chain, home_q, q_min, q_max)
    return CheckReport(mechanism, limbs, home_q, closure_rank, tuple(points), tool)


def _actuation_report(
    mechanism: Mechanism, chain: ClosedChain, closure_rank: int, problems: tuple[str, ...]
) -> CheckReport:
    """The report of a mechanism whose actuation is wrong: structure only, at the TOML's home."""
    home_q = np.concatenate([lb.home for lb in mechanism.limbs])
    unsolved = np.full(home_q.size, np.nan)  # no grid was solved: no joint ranges to report
    limbs = _limb_reports(mechanism, chain, home_q, unsolved, unsolved)
    return CheckReport(mechanism, limbs, home_q, closure_rank, (), None, problems)


def _limb_reports(
    mechanism: Mechanism, chain: ClosedChain, home_q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray
) -> tuple[LimbReport, ...]:
    """Each limb's joints (limits, the grid's range ``q_min``–``q_max``) and its rank at ``home_q``."""
    limbs = []
    for i, limb in enumerate(mechanism.limbs):
        k0 = int(chain.offsets[i])
        joints = tuple(
            JointReport(
                name=name,
                kind=kind,
                actuated=j in limb.actuated,
                lower=float(limb.model.lowerPositionLimit[j]),
                upper=float(limb.model.upperPositionLimit[j]),
                grid_min=float(q_min[k0 + j]),
                grid_max=float(q_max[k0 + j]),
            )
            for j, (name, kind) in enumerate(zip(limb.joint_names, limb.joint_kinds, strict=True))
        )
        rank = _rank(limb_twists(limb, home_q[k0 : k0 + limb.nq]))
        limbs.append(LimbReport(limb.name, limb.urdf_path, joints, rank, 6 - rank))
    return tuple(limbs)


def _hybrid_points(
    mechanism: Mechanism, chain: ClosedChain, passive: np.ndarray
) -> tuple[list[PointReport], LimbReport]:
    """A hybrid's task grid solved by continuation: one report per target, and the tool chain's."""
    tool = mechanism.tool
    assert tool is not None
    hc = HybridChain(mechanism, chain)
    tcp, axes = task_grid(mechanism)
    points, q_tool = [], []
    for k, sol in enumerate(hybrid_continuation(hc, tcp, axes)):
        if isinstance(sol, KinematicsError):
            points.append(PointReport(tcp[k].copy(), str(sol), None, np.nan, np.nan))
            continue
        q = sol.module.q_all
        forward = _condition(chain._evaluate(q, None)[1][:, passive])
        points.append(PointReport(tcp[k].copy(), None, q, sol.condition, forward))
        q_tool.append(sol.q_tool)
    lo = np.min(q_tool, axis=0) if q_tool else np.full(tool.nq, np.nan)
    hi = np.max(q_tool, axis=0) if q_tool else np.full(tool.nq, np.nan)
    joints = tuple(
        JointReport(
            name=name,
            kind=kind,
            actuated=j in tool.actuated,
            lower=float(tool.model.lowerPositionLimit[j]),
            upper=float(tool.model.upperPositionLimit[j]),
            grid_min=float(lo[j]),
            grid_max=float(hi[j]),
        )
        for j, (name, kind) in enumerate(zip(tool.joint_names, tool.joint_kinds, strict=True))
    )
    data = tool.model.createData()
    jt = pin.computeFrameJacobian(tool.model, data, tool.home, tool.tcp_frame, pin.LOCAL)
    rank = _rank(jt)
    return points, LimbReport(TOOL, tool.urdf_path, joints, rank, 6 - rank)


def limb_twists(limb: Limb, q: np.ndarray) -> np.ndarray:
    """The platform motions of a limb at ``q`` (nq,): its LOCAL frame Jacobian, shape (6, nq).

    For a limb with internal loops, the motions that keep its loops closed: ``J_P Z`` with ``Z`` an
    orthonormal basis of the null space of the loops' Jacobian (6, nq − rank).
    """
    model, data = limb.model, limb.model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacement(model, data, limb.platform_frame)
    jp = pin.getFrameJacobian(model, data, limb.platform_frame, pin.LOCAL)
    if not limb.loops:
        return np.array(jp)
    c = np.vstack([loop_rows(lp, *frame_placements(model, data, lp))[1] for lp in limb.loops])
    _, s, vt = np.linalg.svd(c)
    rank = int(np.sum(s > RANK_TOLERANCE * s[0])) if s.size and s[0] > 0 else 0
    return np.array(jp @ vt[rank:].T)


def _solve_point(
    chain: ClosedChain,
    target: np.ndarray,
    q_prev: np.ndarray,
    home_q: np.ndarray,
    passive: np.ndarray,
) -> PointReport:
    """Inverse kinematics from ``q_prev``, retried from home if that fails."""
    starts = [q_prev] if q_prev is home_q else [q_prev, home_q]
    for q0 in starts:
        try:
            pose = chain.inverse(target, q0)
        except KinematicsError as err:
            error = str(err)
            continue
        q = pose.q_all
        forward = _condition(chain._evaluate(q, None)[1][:, passive])
        return PointReport(target.copy(), None, q, pose.condition, forward)
    return PointReport(target.copy(), error, None, np.nan, np.nan)


def _rank(matrix: np.ndarray) -> int:
    s = np.linalg.svd(matrix, compute_uv=False)
    return int(np.sum(s > RANK_TOLERANCE * s[0])) if s.size and s[0] > 0 else 0


def _condition(matrix: np.ndarray) -> float:
    s = np.linalg.svd(matrix, compute_uv=False)
    if matrix.shape[0] < matrix.shape[1] or s[-1] <= 0:
        return float("inf")
    return float(s[0] / s[-1])
