"""Linear maps of a calibration at a list of poses: platform twist, actuation, measured target rows.

At pose ``k`` (nominal closed chain, all arrays in K', SI units), the pose error twist of the
platform with the actuator *commands* held is ``$_k = T_k δ`` (``Separation.twist_map``: every
parameter, actuator zero offsets included), and a change of the commands moves it by
``A_k Δu`` (``Separation.actuation_map``). A tracker target fixed at ``t`` in the platform frame
sits at ``l = R_k t`` from O' in K; its position error is ``[I, −[l]×] $_k``. Stacking the rows of
every target over the calibration poses gives the identification Jacobian ``H`` (DESIGN.md,
"Compensation and calibration").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pkmtol.error_model.compensation import skew_batch
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.tool_sweep import ToolSweep


@dataclass(frozen=True, eq=False)
class PoseMaps:
    """The linear error model at ``m`` poses, as arrays (``n`` parameters, ``f`` actuators).

    Attributes:
        points_m: Shape (m, 3): nominal position of the reference point P in K [m].
        rotations: Shape (m, 3, 3): nominal platform orientation ``R_k`` (platform → K).
        q: Shape (m, Σ nq): nominal joint values of every limb [rad or m].
        commands: Shape (m, f): nominal actuator commands (the actuated entries of ``q``).
        twist: Shape (m, 6, n): ``T_k``, platform twist per unit parameter at held commands.
        actuation: Shape (m, 6, f): ``A_k``, platform twist per unit command change.
        reference_point_m: Shape (3,): P in the platform frame [m].
        task_projection: Shape (3, 3): what of P's displacement the task counts
            (``Mechanism.task_projection``: ``I``, or the projection onto a planar task's plane).
        stations: Shape (m,): the instrument station of each pose (a ballbar circle, a probed
            sphere; None: all 0).
        groups: Shape (m,): poses a plan takes together (a ballbar circle; None: each its own).
        task_rows: Shape (m, r, 6): the rows of the task error in the twist at the reference
            point, for a hybrid machine (the TCP position and the tool axis across its target:
            ``ToolSeparation.task_rows``; the "platform" of these maps is then the TCP frame);
            None: P's position through :attr:`task_projection`.
        measured_twist: Shape (m, 6, n): the twist of the body the instrument's targets sit on,
            when it is not the platform's: a hybrid's spindle (``[calibration] tracker_on =
            "nose"``), the TCP frame's twist without the tool's own errors; None: :attr:`twist`.
    """

    points_m: np.ndarray
    rotations: np.ndarray
    q: np.ndarray
    commands: np.ndarray
    twist: np.ndarray
    actuation: np.ndarray
    reference_point_m: np.ndarray
    task_projection: np.ndarray = field(default_factory=lambda: np.eye(3))
    stations: np.ndarray | None = None
    groups: np.ndarray | None = None
    task_rows: np.ndarray | None = None
    measured_twist: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.points_m.shape[0])

    def subset(self, index: np.ndarray) -> PoseMaps:
        """The maps at the poses ``index`` (in that order)."""
        idx = np.asarray(index, dtype=int)
        return PoseMaps(
            points_m=self.points_m[idx],
            rotations=self.rotations[idx],
            q=self.q[idx],
            commands=self.commands[idx],
            twist=self.twist[idx],
            actuation=self.actuation[idx],
            reference_point_m=self.reference_point_m,
            task_projection=self.task_projection,
            stations=None if self.stations is None else self.stations[idx],
            groups=None if self.groups is None else self.groups[idx],
            task_rows=None if self.task_rows is None else self.task_rows[idx],
            measured_twist=None if self.measured_twist is None else self.measured_twist[idx],
        )

    @property
    def measurement_twist(self) -> np.ndarray:
        """Shape (m, 6, n): the twist the instrument reads (:attr:`measured_twist`, else :attr:`twist`)."""
        return self.twist if self.measured_twist is None else self.measured_twist

    @property
    def station_index(self) -> np.ndarray:
        """The station of every pose (m,) (zeros when none was set)."""
        return (
            np.zeros(len(self), dtype=int) if self.stations is None else np.asarray(self.stations, dtype=int)
        )

    @property
    def group_index(self) -> np.ndarray:
        """The plan group of every pose (m,) (each pose its own when none was set)."""
        return np.arange(len(self)) if self.groups is None else np.asarray(self.groups, dtype=int)

    @property
    def origins_m(self) -> np.ndarray:
        """Shape (m, 3): the platform point O' in K [m] (``P − R_k p``)."""
        return self.points_m - np.einsum("kab,b->ka", self.rotations, self.reference_point_m)

    def point_rows(self, targets_m: np.ndarray) -> np.ndarray:
        """Position-error operators of targets fixed on the platform, shape (m, 3·t, 6).

        Args:
            targets_m: Shape (t, 3): target positions in the platform frame [m].

        Row block ``j`` of pose ``k`` is ``[I, −[R_k t_j]×]``: it maps the platform twist at O' to
        the position error of target ``j`` in K.
        """
        targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
        levers = np.einsum("kab,tb->kta", self.rotations, targets)  # (m, t, 3)
        m, t = levers.shape[:2]
        rows = np.zeros((m, t, 3, 6))
        rows[:, :, :, :3] = np.eye(3)
        rows[:, :, :, 3:] = -skew_batch(levers)
        return rows.reshape(m, 3 * t, 6)

    def measurement_rows(self, targets_m: np.ndarray) -> np.ndarray:
        """Target position errors per unit parameter at held commands, shape (m, 3·t, n).

        The targets move with :attr:`measurement_twist` (a hybrid's spindle, or the platform).
        """
        return np.einsum("kij,kjn->kin", self.point_rows(targets_m), self.measurement_twist)

    def position_map(self) -> np.ndarray:
        """P's position error per unit parameter at held commands (``J_total``), shape (m, 3, n).

        The task's part of it (:attr:`task_projection`), as ``J_total``.
        """
        rows = self.point_rows(self.reference_point_m[None, :])
        return self.task_projection @ np.einsum("kij,kjn->kin", rows, self.twist)

    def position_actuation(self) -> np.ndarray:
        """P's position change (the task's part) per unit command change, shape (m, 3, f)."""
        rows = self.task_projection @ self.point_rows(self.reference_point_m[None, :])
        return np.einsum("kij,kjf->kif", rows, self.actuation)

    def task_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """The task error per unit parameter (m, r, n) and per unit command change (m, r, f).

        P's position (:meth:`position_map`, :meth:`position_actuation`), or a hybrid's task
        (:attr:`task_rows`: the TCP position and the tool axis) at held commands.
        """
        if self.task_rows is None:
            return self.position_map(), self.position_actuation()
        return (
            np.einsum("kra,kan->krn", self.task_rows, self.twist),
            np.einsum("kra,kaf->krf", self.task_rows, self.actuation),
        )


def pose_maps(
    grid: Sweep,
    actuated_idx: np.ndarray,
    reference_point_m: np.ndarray,
    task_projection: np.ndarray | None = None,
) -> PoseMaps:
    """The maps of every pose of a sweep.

    Args:
        grid: Separations at the poses (:func:`pkmtol.error_model.sweep.sweep`).
        actuated_idx: Indices of the actuated joints in the concatenated q
            (``ClosedChain.actuated_idx``).
        reference_point_m: P in the platform frame, shape (3,) [m].
        task_projection: ``Mechanism.task_projection`` (default ``I``: the position task).
    """
    if isinstance(grid, ToolSweep):
        return _tool_pose_maps(grid, actuated_idx)
    seps = grid.separations
    q = np.array([p.q_all for p in grid.poses])
    act = [s.actuation_map for s in seps]
    if any(a is None for a in act):  # pragma: no cover - separate() always sets it
        raise ValueError("separations without an actuation map")
    return PoseMaps(
        points_m=np.array([p.p_m for p in grid.poses]),
        rotations=np.array([p.oMp.rotation for p in grid.poses]),
        q=q,
        commands=q[:, np.asarray(actuated_idx, dtype=int)],
        twist=np.array([s.twist_map for s in seps]),
        actuation=np.array(act),
        reference_point_m=np.asarray(reference_point_m, dtype=float),
        task_projection=np.eye(3) if task_projection is None else np.asarray(task_projection, dtype=float),
    )


def _tool_pose_maps(grid: ToolSweep, actuated_idx: np.ndarray) -> PoseMaps:
    """A hybrid's maps: the TCP frame as the "platform", the whole machine's joints and actuators.

    ``q`` is the module's joints then the tool chain's, ``commands`` the module's actuators
    (``actuated_idx``) then the wrist's; ``twist`` and ``actuation`` are the TCP's
    (``ToolSeparation.twist_map`` A and ``actuation_map`` B); the task rows are the TCP position
    and, with a free wrist, the tool axis across its target (a locked wrist: the position only).
    A tracker on the spindle nose (``ToolSweep.tracker_on``) reads the spindle's twist: the TCP's
    without the TCP frame's own errors.
    """
    hp = grid.hybrid_poses
    qm = np.array([h.module.q_all for h in hp])
    qt = np.array([h.q_tool for h in hp])
    act = np.asarray(actuated_idx, dtype=int)
    rows = np.array([s.task_rows for s in grid.separations])  # type: ignore[attr-defined]
    twist = np.array([s.twist_map for s in grid.separations])
    frame = np.array([s.frame_map for s in grid.separations])  # type: ignore[attr-defined]
    return PoseMaps(
        points_m=np.array([h.tcp_m for h in hp]),
        rotations=np.array([h.oMt.rotation for h in hp]),
        q=np.hstack([qm, qt]),
        commands=np.hstack([qm[:, act], qt[:, list(grid.tool_actuated)]]),
        twist=twist,
        actuation=np.array([s.actuation_map for s in grid.separations]),
        reference_point_m=np.zeros(3),
        task_rows=rows if grid.axes is not None else rows[:, :3],
        measured_twist=twist - frame if grid.tracker_on == "nose" else None,
    )
