"""The general form of a closed-loop mechanism: one kinematic tree, loop constraints, actuators, a task.

A :class:`LoopTree` is what Pinocchio 4's constraint API, MJCF ``<equality>``, the
example-parallel-robots URDF + YAML convention and the urdfdom ``<constraint>`` proposal all
describe: one ``pin.Model`` (a tree of 1-DOF revolute and prismatic joints from the base, frame K),
any number of loops between any two of its frames (``6d``: the frames coincide; ``3d``: their
origins coincide), the actuated joints, and a task frame anywhere in the tree with its task rows
(:class:`PointTask`: the position of a point of that frame, optionally in a plane).

Error parameters (the ``urdf`` set of a tree, raw layout of :attr:`LoopTree.n_raw`): each joint
placement ``jointPlacements[j] · exp6(ε_j)`` (6 per joint, in the joint's frame), then each
:class:`ErrorFrame` (a fixed frame's placement error, 6, e.g. a platform attachment or a tool
length), then each loop's closure error (its frame b's placement ``oMb · exp6(ε)``, 6; a ``3d``
loop uses the 3 translations), then one zero offset per joint ``q_actual = q + δq``.

A mechanism given as limbs (:class:`~pkmtol.model.mechanism.Mechanism`) is one such tree
(:func:`pkmtol.model.tree_from_limbs.tree_from_mechanism`): the limbs under one root, one ``6d``
loop per limb after the first between the platform frames, the limbs' internal loops.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import ClosedLoopError, InvalidArgumentError
from pkmtol.model.limb import LOOP_KINDS, LimbLoop, joint_kind

COMPONENTS = ("dx", "dy", "dz", "rx", "ry", "rz")


@dataclass(frozen=True)
class ErrorFrame:
    """A placement error of a fixed frame, ``oMF · exp6(ε)`` (6 raw errors, ε in F's axes).

    Attributes:
        name: Used in parameter names (``<name>.dx`` …).
        frame: Frame id of F in the tree.
        moves: Frame ids that move rigidly with F's error (F itself included when it matters).
    """

    name: str
    frame: int
    moves: tuple[int, ...]


class TaskRows:
    """What a task adds to the solve and the error model (the interface a new task implements).

    ``rows`` equations ``residual(h, targets)`` (b, rows) with Jacobian ``jacobian(h, world)``
    (b, rows, k) from the task frame's placements ``h`` (b, 4, 4) and spatial motions ``world``
    (b, 6, k); ``of_twist(lever)`` (b, 3, 6) maps the platform's K' twist to the task error;
    ``position(h)`` is the task point (b, 3), ``projection()`` the part of its error that counts.
    :class:`PointTask` is the position of a point (optionally in a plane); a task of position and
    tool-axis direction (issue 27) is another subclass. The compiled rows run for :class:`PointTask`
    only; any other task takes the numpy rows.
    """

    rows = 3
    point_m: np.ndarray

    def projection(self) -> np.ndarray:
        """Shape (3, 3): the part of the task point's error that counts."""
        raise NotImplementedError

    def position(self, h: np.ndarray) -> np.ndarray:
        """The task point in K (b, 3) [m]."""
        raise NotImplementedError

    def residual(self, h: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """Task residual (b, rows)."""
        raise NotImplementedError

    def jacobian(self, h: np.ndarray, world: np.ndarray) -> np.ndarray:
        """Task rows' Jacobian (b, rows, k)."""
        raise NotImplementedError

    def of_twist(self, lever_m: np.ndarray) -> np.ndarray:
        """Shape (b, 3, 6): the task error per K' twist at the platform frame's origin."""
        raise NotImplementedError


@dataclass(frozen=True)
class PointTask(TaskRows):
    """Task rows: the position of the point ``point_m`` of the task frame (3 rows, in K).

    Attributes:
        point_m: The point in the task frame, shape (3,) [m].
        normal: For a planar task, the unit normal (3,) in K of the plane the point moves in: the
            error that counts is the in-plane part. None: the position in space.

    The inverse kinematics keeps three position rows for both (as the limb path does); the
    error model projects them (:meth:`projection`).
    """

    point_m: np.ndarray
    normal: np.ndarray | None = None

    rows = 3

    def __post_init__(self) -> None:
        point = values.within_length("PointTask.point_m", values.vector("PointTask.point_m", self.point_m, 3))
        object.__setattr__(self, "point_m", point)
        if self.normal is not None:
            n = values.vector("PointTask.normal", self.normal, 3)
            if abs(float(np.linalg.norm(n)) - 1.0) > 1e-6:
                raise InvalidArgumentError("PointTask.normal", self.normal, "expected a unit vector")
            object.__setattr__(self, "normal", n)

    def projection(self) -> np.ndarray:
        """Shape (3, 3): ``I``, or ``I − n nᵀ`` for a planar task."""
        if self.normal is None:
            return np.eye(3)
        n = np.asarray(self.normal, dtype=float)
        return np.eye(3) - np.outer(n, n)

    def position(self, h: np.ndarray) -> np.ndarray:
        """The point in K (b, 3) for task-frame placements ``h`` (b, 4, 4) [m]."""
        h = values.array_of_shape("h", h, (None, 4, 4), finite=False)
        return h[:, :3, :3] @ self.point_m + h[:, :3, 3]

    def residual(self, h: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """Task residual (b, 3): the point minus its target [m]."""
        p = self.position(h)
        return p - values.array_of_shape("targets", targets, (len(p), 3), finite=False)

    def jacobian(self, h: np.ndarray, world: np.ndarray) -> np.ndarray:
        """Shape (b, 3, k): the point's velocity per unit of ``k`` variables.

        Args:
            h: Shape (b, 4, 4): task-frame placements.
            world: Shape (b, 6, k): the task frame's spatial (world, ``[v_O; ω]``) motion per variable.
        """
        p = self.position(h)
        world = values.array_of_shape("world", world, (len(p), 6, None), finite=False)
        return world[:, :3] - _cross_rows(p, world[:, 3:])

    def of_twist(self, lever_m: np.ndarray) -> np.ndarray:
        """Shape (b, 3, 6): the task error per K' twist of the task frame's origin (lever (b, 3) in K).

        ``(I − n nᵀ) [I  −[l×]]`` (the projection for a planar task).
        """
        lever_m = values.array_of_shape("lever_m", lever_m, (None, 3), finite=False)
        b = len(lever_m)
        out = np.zeros((b, 3, 6))
        out[:, :, :3] = np.eye(3)
        out[:, :, 3:] = -_skew(lever_m)
        return self.projection() @ out


@dataclass(frozen=True, eq=False)
class LoopTree:
    """A mechanism as one Pinocchio tree with loop constraints (the general formulation).

    Attributes:
        name: Mechanism name.
        model: The tree; 1-DOF revolute or prismatic joints only (``nq == nv``).
        loops: The loop constraints (frame ids in ``model``); frame b carries the closure error.
        actuated: Indices into ``q`` of the actuated joints.
        task_frame: Frame id of the task frame (any frame of the tree).
        task: The task rows (a :class:`TaskRows`: :class:`PointTask`).
        platform_frame: A frame on the platform body: the body whose removal splits the mechanism
            into its limbs (the actuation-wrench choice, docs/theory.md). Default: the task frame.
        home: Joint values near which every loop closes (nq,) [rad or m].
        loop_moves: Per loop, the frames its closure error moves (frame b first); default ``(b,)``.
        error_frames: Fixed-frame placement errors (:class:`ErrorFrame`).
        joint_labels: Per joint, the name used in parameter names (default the model's names).
        loop_labels: Per loop, the name used in parameter names (default the loop's name).
        groups: Optional joint groups (tuples of q indices) that replace the limbs found from the
            topology (:attr:`limbs`); the tree built from a limb mechanism passes its limbs.
    """

    name: str
    model: pin.Model
    loops: tuple[LimbLoop, ...]
    actuated: tuple[int, ...]
    task_frame: int
    task: TaskRows
    platform_frame: int = -1
    home: np.ndarray = field(default_factory=lambda: np.zeros(0))
    loop_moves: tuple[tuple[int, ...], ...] = ()
    error_frames: tuple[ErrorFrame, ...] = ()
    joint_labels: tuple[str, ...] = ()
    loop_labels: tuple[str, ...] = ()
    groups: tuple[tuple[int, ...], ...] | None = None

    def __post_init__(self) -> None:
        """Fill the defaults and check the structure (ClosedLoopError naming the culprit)."""
        values.text("name", self.name)
        if not isinstance(self.model, pin.Model):
            raise InvalidArgumentError("model", self.model, "expected a pinocchio.Model (one tree)")
        m = self.model
        for j in range(1, m.njoints):
            if m.joints[j].nq != 1 or joint_kind(m.joints[j].shortname()) == "?":
                raise ClosedLoopError(
                    self.name,
                    m.names[j],
                    f"joint '{m.names[j]}' is of type {m.joints[j].shortname()}; pkmtol takes 1-DOF "
                    "revolute or prismatic joints (write a ball joint as three revolutes or as a '3d' loop)",
                )
        nf = len(m.frames)
        for what, f in (("task frame", self.task_frame), ("platform frame", self.platform_frame)):
            if not -1 <= int(f) < nf or (what == "task frame" and f < 0):
                raise InvalidArgumentError(what, f, f"expected a frame id of the model (0 … {nf - 1})")
        if self.platform_frame < 0:
            object.__setattr__(self, "platform_frame", int(self.task_frame))
        for lp in self.loops:
            if lp.kind not in LOOP_KINDS:
                raise ClosedLoopError(
                    self.name, lp.name, f"loop '{lp.name}': unknown type {lp.kind!r}; use '6d' or '3d'"
                )
            for f in (lp.frame_a, lp.frame_b):
                if not 0 <= f < nf:
                    raise ClosedLoopError(
                        self.name, lp.name, f"loop '{lp.name}': frame id {f} is not in the model"
                    )
            if m.frames[lp.frame_a].parentJoint == m.frames[lp.frame_b].parentJoint:
                raise ClosedLoopError(
                    self.name,
                    lp.name,
                    f"loop '{lp.name}': '{lp.frame_names[0]}' and '{lp.frame_names[1]}' are on the same "
                    "body, so the loop closes no joint; put the two frames on the two bodies it joins",
                )
        for a in self.actuated:
            if not 0 <= a < m.nq:
                raise InvalidArgumentError("actuated", a, f"expected joint indices 0 … {m.nq - 1}")
        if not self.loop_moves:
            object.__setattr__(self, "loop_moves", tuple((lp.frame_b,) for lp in self.loops))
        if len(self.loop_moves) != len(self.loops):
            raise InvalidArgumentError("loop_moves", self.loop_moves, "need one tuple of frames per loop")
        if not self.joint_labels:
            object.__setattr__(self, "joint_labels", tuple(m.names[1:]))
        if not self.loop_labels:
            object.__setattr__(self, "loop_labels", tuple(lp.name for lp in self.loops))
        home = np.zeros(m.nq) if np.size(self.home) == 0 else np.asarray(self.home, dtype=float)
        if home.shape != (m.nq,) or not np.all(np.isfinite(home)):
            raise InvalidArgumentError("home", self.home, f"expected {m.nq} finite joint values")
        object.__setattr__(self, "home", home)
        if not isinstance(self.task, TaskRows):
            raise InvalidArgumentError(
                "task", self.task, "expected task rows (pkmtol.model.loop_tree.PointTask)"
            )

    # --- sizes and layout -----------------------------------------------------------------

    @property
    def nq(self) -> int:
        """Number of joints of the tree."""
        return int(self.model.nq)

    @property
    def n_raw(self) -> int:
        """Raw errors: 6 per joint placement, per error frame and per loop, then one offset per joint."""
        return 6 * (self.nq + len(self.error_frames) + len(self.loops)) + self.nq

    def raw_block(self, kind: str, k: int) -> slice:
        """The raw columns of joint placement, error frame or loop ``k`` (``kind``: joint/frame/loop)."""
        sizes = {"joint": self.nq, "frame": len(self.error_frames), "loop": len(self.loops)}
        k = values.index("k", k, sizes[values.choice("kind", kind, sizes)])
        start = {"joint": 0, "frame": self.nq, "loop": self.nq + len(self.error_frames)}[kind]
        return slice(6 * (start + k), 6 * (start + k) + 6)

    @property
    def offset_start(self) -> int:
        """First raw column of the joint offsets."""
        return 6 * (self.nq + len(self.error_frames) + len(self.loops))

    @property
    def passive(self) -> tuple[int, ...]:
        """Indices of the passive joints."""
        return tuple(i for i in range(self.nq) if i not in self.actuated)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in q order."""
        return tuple(self.model.names[1:])

    @property
    def joint_kinds(self) -> tuple[str, ...]:
        """``"R"`` or ``"P"`` per joint."""
        return tuple(joint_kind(self.model.joints[j].shortname()) for j in range(1, self.model.njoints))

    @property
    def loop_rows(self) -> int:
        """Number of loop-closure equations."""
        return sum(lp.rows for lp in self.loops)

    # --- topology -------------------------------------------------------------------------

    def support(self, frame: int) -> np.ndarray:
        """Shape (nq,): True for each joint that moves ``frame`` (its path from the root)."""
        return self._tables[0][values.index("frame", frame, self.model.nframes)]

    def moved_by(self, frame: int) -> np.ndarray:
        """Shape (n_raw,): True for each raw error that moves ``frame``."""
        return self._tables[1][values.index("frame", frame, self.model.nframes)]

    @cached_property
    def _tables(self) -> tuple[np.ndarray, np.ndarray]:
        """Per frame: its supporting joints (F, nq) and the raw errors that move it (F, n_raw)."""
        m = self.model
        nf = len(m.frames)
        sup = np.zeros((nf, self.nq), dtype=bool)
        for f in range(nf):
            j = int(m.frames[f].parentJoint)
            while j > 0:
                sup[f, j - 1] = True
                j = int(m.parents[j])
        mov = np.zeros((nf, self.n_raw), dtype=bool)
        mov[:, : 6 * self.nq] = np.repeat(sup, 6, axis=1)
        mov[:, self.offset_start :] = sup
        for k, ef in enumerate(self.error_frames):
            mov[list(ef.moves), self.raw_block("frame", k)] = True
        for k, moves in enumerate(self.loop_moves):
            mov[list(moves), self.raw_block("loop", k)] = True
        sup.setflags(write=False)
        mov.setflags(write=False)
        return sup, mov

    @cached_property
    def limbs(self) -> tuple[TreeLimb, ...]:
        """The mechanism's limbs: the connected parts once the base and the platform body are removed.

        Bodies are Pinocchio's joints (0 the base); a joint joins its parent body and its own, a
        loop the bodies of its two frames. Each part holds the joints and loops it touches; a part
        that does not reach the base is a tool chain on the platform (``reaches_base`` False).
        With :attr:`groups`, each group of joints is a limb (and holds the loops its joints touch).
        """
        return _limbs(self)


@dataclass(frozen=True)
class TreeLimb:
    """One limb of a :class:`LoopTree` (a connected part of the mechanism between base and platform).

    Attributes:
        joints: Its joints (q indices, ascending).
        loops: Its loops (indices into ``LoopTree.loops``).
        holds_platform: Whether the tree path from the base to the platform body runs through it.
        reaches_base: Whether it touches the base (False: a chain that hangs on the platform only).
    """

    joints: tuple[int, ...]
    loops: tuple[int, ...]
    holds_platform: bool
    reaches_base: bool


def _limbs(tree: LoopTree) -> tuple[TreeLimb, ...]:
    m = tree.model
    pbody = int(m.frames[tree.platform_frame].parentJoint)
    body_of = [int(f.parentJoint) for f in m.frames]
    loop_edges = [(body_of[lp.frame_a], body_of[lp.frame_b]) for lp in tree.loops]
    path = set(np.flatnonzero(tree.support(tree.platform_frame)).tolist())
    if tree.groups is not None:
        out = []
        for g in tree.groups:
            bodies = {j + 1 for j in g} - {pbody}
            lps = tuple(k for k, (a, b) in enumerate(loop_edges) if a in bodies or b in bodies)
            reaches = any(int(m.parents[j + 1]) == 0 for j in g) or any(0 in loop_edges[k] for k in lps)
            out.append(TreeLimb(tuple(sorted(g)), lps, bool(path & set(g)), reaches))
        return tuple(out)
    parent = list(range(m.njoints))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    removed = {0, pbody}
    edges = [("joint", j - 1, int(m.parents[j]), j) for j in range(1, m.njoints)]
    edges += [("loop", k, a, b) for k, (a, b) in enumerate(loop_edges)]
    for _, _, a, b in edges:
        if a not in removed and b not in removed:
            parent[find(a)] = find(b)
    groups: dict[int, dict[str, list[int]]] = {}
    for kind, k, a, b in edges:
        inner = [x for x in (a, b) if x not in removed]
        key = find(inner[0]) if inner else -1 - len(groups)  # an edge from base to platform: its own
        entry = groups.setdefault(key, {"joint": [], "loop": [], "base": []})
        entry[kind].append(k)
        if 0 in (a, b):
            entry["base"].append(1)
    out = []
    for entry in groups.values():
        js = tuple(sorted(entry["joint"]))
        out.append(TreeLimb(js, tuple(sorted(entry["loop"])), bool(path & set(js)), bool(entry["base"])))
    out.sort(key=lambda limb: (not limb.holds_platform, min(limb.joints, default=10**9)))
    return tuple(out)


def frame_named(model: pin.Model, name: str, what: str, source: str = "") -> int:
    """Id of the frame ``name`` (a body frame before a fixed joint of the same name), or ClosedLoopError.

    ``source`` (a file or the model) is named in the error.
    """
    ids = [k for k, f in enumerate(model.frames) if f.name == name]
    if not ids:
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        frames = ", ".join(links[:12]) + (f", … ({len(links)} links)" if len(links) > 12 else "")
        raise ClosedLoopError(
            source or model.name, name, f"{what}: no frame '{name}' in the tree (links: {frames})"
        )
    body = [k for k in ids if model.frames[k].type == pin.FrameType.BODY]
    return (body or ids)[0]


def make_loops(
    model: pin.Model, loops: Sequence[tuple[str, str, str, str]], source: str = ""
) -> tuple[LimbLoop, ...]:
    """Loops ``(name, frame a, frame b, kind)`` by frame names, checked (ClosedLoopError on a bad one)."""
    out = []
    seen: set[str] = set()
    for name, fa, fb, kind in loops:
        if not name or name in seen:
            raise ClosedLoopError(
                source or model.name,
                name,
                f"loop '{name}': the name is empty or used twice; name each loop once",
            )
        seen.add(name)
        if kind not in LOOP_KINDS:
            raise ClosedLoopError(
                source or model.name, name, f"loop '{name}': unknown type {kind!r}; use '6d' or '3d'"
            )
        a = frame_named(model, fa, f"loop '{name}'", source)
        b = frame_named(model, fb, f"loop '{name}'", source)
        out.append(LimbLoop(name, a, b, kind, (fa, fb)))
    return tuple(out)


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(len(v))
    x, y, w = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([z, -w, y, w, z, -x, -y, x, z], axis=1).reshape(-1, 3, 3)


def _cross_rows(p: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``p × w`` column by column: p (b, 3), w (b, 3, k)."""
    return np.stack(
        [
            p[:, 1, None] * w[:, 2] - p[:, 2, None] * w[:, 1],
            p[:, 2, None] * w[:, 0] - p[:, 0, None] * w[:, 2],
            p[:, 0, None] * w[:, 1] - p[:, 1, None] * w[:, 0],
        ],
        axis=1,
    )
