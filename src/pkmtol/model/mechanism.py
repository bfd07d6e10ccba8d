"""The mechanism: limbs (URDF → ``pin.Model``), actuators, platform, reference point, task space.

A mechanism folder holds ``mechanism.toml`` and one URDF per limb (``docs/mechanism-format.md``).
Every limb URDF is a serial chain of 1-DOF revolute/prismatic joints from the common base link
(frame K) to the platform link; the platform link's frame is the platform frame, and all limbs'
platform frames coincide at the ``home`` configuration given in the TOML (default: all zeros).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import (
    InvalidArgumentError,
    InvalidRequestError,
    LoopMismatchError,
    PlatformMismatchError,
    URDFError,
)
from pkmtol.model.constraint_limbs import limbs_from_constraint_models
from pkmtol.model.constraints import ConstrainedModel, constraint_models
from pkmtol.model.limb import Limb, make_limb
from pkmtol.model.loop_tree import LoopTree
from pkmtol.model.taskspace import TaskSpace, ToolDirections
from pkmtol.model.tool import Tool
from pkmtol.model.tree_from_limbs import LimbRaw, tree_from_mechanism

#: Mismatch allowed between the limbs' platform frames at ``home`` before Newton refines it.
HOME_TOLERANCE_M = 1e-3
HOME_TOLERANCE_RAD = 1e-3

DEFAULT_BETAS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


@dataclass(frozen=True, eq=False)
class Mechanism:
    """A lower-mobility parallel mechanism and its design targets.

    Attributes:
        name: Mechanism name.
        limbs: The limbs; limb 0 is the reference limb of the closure equations.
        reference_point_m: Position of the reference point P in the platform frame, shape (3,) [m].
        task_space: Where P must reach (frame K).
        target_m: Required accuracy Δλ* [m].
        betas: Reliability indices β of the allocation table.
        design_beta: The β of the design case.
        root: Folder the mechanism was loaded from (None if built in Python).
        description: Free text.
        task_normal: For a planar task (``task.kind = "planar"``), the unit normal (3,) in K of the
            plane P moves in: the accuracy index is the in-plane norm of P's error; None: the
            position of P in space.
        tool: For a hybrid machine (``task.kind = "tool"``), the serial tool chain on the
            platform (the wrist, the spindle, the TCP; :mod:`pkmtol.model.tool`); None: the
            parallel module alone, whose task point is P.
        tool_directions: The tool axes the task must reach (a cone, for a tool chain with two
            actuated wrist joints); None: the TCP position only (a locked wrist, 3-axis work).
    """

    name: str
    limbs: tuple[Limb, ...]
    reference_point_m: np.ndarray
    task_space: TaskSpace
    target_m: float = 5e-5
    betas: tuple[float, ...] = DEFAULT_BETAS
    design_beta: float = 2.0
    root: Path | None = None
    description: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    task_normal: np.ndarray | None = None
    tool: Tool | None = None
    tool_directions: ToolDirections | None = None

    @property
    def task_projection(self) -> np.ndarray:
        """Shape (3, 3): the projection of a displacement of P (in K) onto the task.

        ``I`` for the position task; ``I − n nᵀ`` for a planar task of normal ``n``: the error of P
        that counts is its in-plane part (the task's 2 coordinates, kept as a vector of K).
        """
        if self.task_normal is None:
            return np.eye(3)
        n = np.asarray(self.task_normal, dtype=float)
        return np.eye(3) - np.outer(n, n)

    def task_error(self, displacement_m: np.ndarray) -> np.ndarray:
        """A displacement of P (..., 3) in K reduced to the task (its in-plane part for a planar task) [m]."""
        d = values.array("displacement_m", displacement_m)
        if d.ndim == 0 or d.shape[-1] != 3:
            raise InvalidArgumentError("displacement_m", displacement_m, "expected shape (..., 3) [m]")
        if self.task_normal is None:
            return d
        n = np.asarray(self.task_normal, dtype=float)
        return d - (d @ n)[..., None] * n

    def __post_init__(self) -> None:
        """Check the fields (raises InvalidArgumentError naming the first wrong one)."""
        values.text("name", self.name)
        if not isinstance(self.limbs, tuple) or not all(isinstance(x, Limb) for x in self.limbs):
            raise InvalidArgumentError("limbs", self.limbs, "expected a tuple of Limb objects")
        if len(self.limbs) < 2:
            raise InvalidArgumentError(
                "limbs", f"{len(self.limbs)} limb(s)", "a parallel mechanism needs at least two limbs"
            )
        seen = set()
        for limb in self.limbs:
            if limb.name in seen:
                raise InvalidArgumentError(
                    "limbs", limb.name, "limb names must be unique (parameter names use them)"
                )
            seen.add(limb.name)
        if not isinstance(self.reference_point_m, np.ndarray):
            raise InvalidArgumentError(
                "reference_point_m", self.reference_point_m, "expected an array of 3 numbers"
            )
        values.within_length(
            "reference_point_m", values.vector("reference_point_m", self.reference_point_m, 3)
        )
        if not isinstance(self.task_space, TaskSpace):
            raise InvalidArgumentError("task_space", self.task_space, "expected a pkmtol.TaskSpace")
        values.length_m("target_m", self.target_m)
        if not isinstance(self.betas, tuple) or not self.betas:
            raise InvalidArgumentError("betas", self.betas, "expected a non-empty tuple of positive numbers")
        for b in self.betas:
            values.number("betas", b, positive=True)
        values.number("design_beta", self.design_beta, positive=True)
        if not isinstance(self.description, str):
            raise InvalidArgumentError("description", self.description, "expected a string")
        if self.task_normal is not None:
            n = values.vector("task_normal", self.task_normal, 3)
            if abs(float(np.linalg.norm(n)) - 1.0) > 1e-6:
                raise InvalidArgumentError("task_normal", self.task_normal, "expected a unit vector")
        if self.root is not None:
            values.path("root", self.root, "a folder (pathlib.Path) or None")
        if self.tool is not None and not isinstance(self.tool, Tool):
            raise InvalidArgumentError("tool", self.tool, "expected a pkmtol.model.tool.Tool (make_tool)")
        if self.tool_directions is not None and not isinstance(self.tool_directions, ToolDirections):
            raise InvalidArgumentError("tool_directions", self.tool_directions, "expected a ToolDirections")

    @property
    def n_joints(self) -> int:
        """Total number of joints over all limbs."""
        return sum(limb.nq for limb in self.limbs)

    @property
    def n_actuators(self) -> int:
        """Number of actuated joints."""
        return sum(len(limb.actuated) for limb in self.limbs)

    def limb(self, name: str) -> Limb:
        """The limb called ``name`` (InvalidArgumentError listing the limbs if there is none)."""
        for limb in self.limbs:
            if limb.name == name:
                return limb
        names = ", ".join(x.name for x in self.limbs)
        raise InvalidArgumentError("name", name, f"no such limb (limbs: {names})")

    def constraint_models(self, models: Sequence[pin.Model] | None = None) -> ConstrainedModel:
        """The mechanism as one ``pin.Model`` plus a ``FrameAnchorConstraintModel`` per loop (Pinocchio 4).

        Args:
            models: Replacement limb models (e.g. perturbed); default: the limbs'.

        See :func:`pkmtol.model.constraints.constraint_models`.
        """
        return constraint_models(self, models)

    @classmethod
    def from_models(
        cls,
        name: str,
        models: Sequence[pin.Model],
        actuated: Sequence[Sequence[str]],
        platform_frame: str,
        reference_point_m: Sequence[float],
        task_space: TaskSpace,
        limb_names: Sequence[str] | None = None,
        homes: Sequence[Sequence[float]] | None = None,
        target_m: float = 5e-5,
        betas: Sequence[float] = DEFAULT_BETAS,
        design_beta: float = 2.0,
    ) -> Mechanism:
        """Build a mechanism from ``pin.Model`` limbs a user already has.

        Args:
            name: Mechanism name.
            models: One serial ``pin.Model`` per limb, all rooted at the same base frame K.
            actuated: Per limb, names of its actuated joints (at most one each).
            platform_frame: Name of the platform frame present in every model.
            reference_point_m: P in the platform frame, shape (3,) [m].
            task_space: Task space of P in K.
            limb_names: Names of the limbs (default ``limb1`` ...).
            homes: Per limb, joint values where all platform frames coincide (default zeros).
            target_m: Δλ* [m].
            betas: β series.
            design_beta: β of the design case.
        """
        models = _sequence("models", models, pin.Model, "pinocchio.Model limbs")
        n = len(models)
        if n < 2:
            raise InvalidArgumentError(
                "models", f"{n} model(s)", "a parallel mechanism needs at least two limbs, one pin.Model each"
            )
        actuated = _per_limb(
            "actuated", actuated, n, "a list of actuated joint names per limb ([] if passive)"
        )
        act = [list(values.strings(f"actuated[{i}]", a)) for i, a in enumerate(actuated)]
        if limb_names is None:
            names = [f"limb{i + 1}" for i in range(n)]
        else:
            names = list(values.strings("limb_names", limb_names))
            if len(names) != n:
                raise InvalidArgumentError("limb_names", limb_names, f"need {n} names, one per model")
        if homes is not None:
            homes = _per_limb("homes", homes, n, "a list of joint values per limb")
        limbs = []
        for i, (lname, model) in enumerate(zip(names, models, strict=True)):
            home = None if homes is None else values.array(f"homes[{i}]", homes[i], ndim=1)
            limbs.append(make_limb(lname, model, act[i], platform_frame, home, None))
        return cls.from_limbs(name, limbs, reference_point_m, task_space, target_m, betas, design_beta)

    def loop_tree(self) -> tuple[LoopTree, LimbRaw]:
        """The mechanism as one tree with loop constraints (the general formulation), and its raw-error map.

        See :func:`pkmtol.model.tree_from_limbs.tree_from_mechanism`.
        """
        return tree_from_mechanism(self)

    @classmethod
    def from_constraint_models(
        cls,
        model: pin.Model,
        constraint_models: Sequence[Any],
        actuated: Sequence[str],
        task_frame: str,
        *,
        reference_point_m: Sequence[float] = (0.0, 0.0, 0.0),
        task_space: TaskSpace,
        name: str | None = None,
        home: Sequence[float] | np.ndarray | None = None,
        limb_names: Sequence[str] | None = None,
        target_m: float = 5e-5,
        betas: Sequence[float] = DEFAULT_BETAS,
        design_beta: float = 2.0,
    ) -> Mechanism:
        """A mechanism from a Pinocchio 4 stack: one ``pin.Model`` (a tree) and its loop constraints.

        Args:
            model: The tree; 1-DOF revolute and prismatic joints.
            constraint_models: ``pin.FrameAnchorConstraintModel`` (6D) and ``pin.PointAnchorConstraintModel``
                (3D) loops, or legacy ``pin.RigidConstraintModel`` (``CONTACT_6D``/``CONTACT_3D``).
            actuated: Names of the actuated joints.
            task_frame: The frame of the platform (its link is the platform; P is given in it).
            reference_point_m: P in that frame (3,) [m].
            task_space: Task space of P in K.
            name: Mechanism name (default ``model.name``).
            home: Joint values (nq,) where the loops close (default ``pin.neutral``).
            limb_names: Limb names, reference limb first (default ``limb1`` ...).
            target_m: Δλ* [m].
            betas: β series.
            design_beta: β of the design case.

        The stack is cut into limbs like a closed-loop URDF (docs/closed-loop.md); a stack the cut
        refuses runs on the tree (:func:`pkmtol.model.tree_inputs.tree_from_constraint_models`).

        Raises:
            ClosedLoopError (and subclasses): a constraint, joint or frame pkmtol cannot take, or a
                topology the cut into limbs refuses.
        """
        values.instance("model", model, pin.Model, "a pin.Model (the tree)")
        values.instances("constraint_models", constraint_models, object, "Pinocchio constraint models")
        values.strings("actuated", actuated)
        values.text("task_frame", task_frame)
        limbs, tree = limbs_from_constraint_models(
            model, constraint_models, actuated, task_frame, home, limb_names, name
        )
        return cls.from_limbs(tree.name, limbs, reference_point_m, task_space, target_m, betas, design_beta)

    @classmethod
    def from_limbs(
        cls,
        name: str,
        limbs: Sequence[Limb],
        reference_point_m: Sequence[float] | np.ndarray,
        task_space: TaskSpace,
        target_m: float = 5e-5,
        betas: Sequence[float] = DEFAULT_BETAS,
        design_beta: float = 2.0,
        root: Path | None = None,
        description: str = "",
        extra: dict[str, Any] | None = None,
        check_home_closure: bool = True,
        task_normal: Sequence[float] | np.ndarray | None = None,
    ) -> Mechanism:
        """A mechanism from validated limbs, checked: one common root link, closed at ``home``.

        Every constructor of pkmtol (TOML, ``pin.Model`` limbs, closed-loop tree) ends here.
        ``check_home_closure=False`` leaves the ``home`` check to the caller (a design variant
        whose dimensions moved the platform frames apart at the nominal ``home``). ``task_normal``
        makes the task planar (see :attr:`task_normal`; normalised here).

        Raises:
            URDFError: the limbs start from different root links.
            PlatformMismatchError: the platform frames do not coincide at ``home``.
        """
        limbs = _sequence("limbs", limbs, Limb, "Limb objects")
        betas_arr = values.array("betas", betas, ndim=1)
        if extra is not None and not isinstance(extra, dict):
            raise InvalidArgumentError("extra", extra, "expected a dict")
        mech = cls(
            name=name,
            limbs=tuple(limbs),
            reference_point_m=values.vector("reference_point_m", reference_point_m, 3),
            task_space=task_space,
            target_m=values.length_m("target_m", target_m),
            betas=tuple(float(b) for b in betas_arr),
            design_beta=values.number("design_beta", design_beta, positive=True),
            root=None if root is None else values.path("root", root, "a folder (str or pathlib.Path)"),
            description=description,
            extra=dict(extra or {}),
            task_normal=None if task_normal is None else _unit(task_normal),
        )
        check_root_links(mech)
        if check_home_closure:
            check_home(mech)
        return mech


def _unit(v: Sequence[float] | np.ndarray) -> np.ndarray:
    n = values.vector("task_normal", v, 3)
    n = n / max(float(np.max(np.abs(n))), 1e-300)  # 1e308 entries do not overflow the norm
    norm = float(np.linalg.norm(n))
    if not np.isfinite(norm) or norm < 1e-12:
        raise InvalidRequestError(f"the normal of a planar task must be a non-zero vector, got {n.tolist()}")
    return n / norm


def _sequence(name: str, items: Any, kind: type, what: str) -> list[Any]:
    """``items`` as a list of ``kind`` objects, or InvalidArgumentError naming ``name``."""
    if isinstance(items, str | bytes) or not isinstance(items, Sequence):
        raise InvalidArgumentError(name, items, f"expected a list of {what}")
    for i, item in enumerate(items):
        if not isinstance(item, kind):
            raise InvalidArgumentError(f"{name}[{i}]", item, f"expected one of the {what}")
    return list(items)


def _per_limb(name: str, items: Any, n: int, what: str) -> list[Any]:
    """``items`` as a list of ``n`` entries (one per limb), or InvalidArgumentError naming ``name``."""
    if isinstance(items, str | bytes) or not isinstance(items, Sequence):
        raise InvalidArgumentError(name, items, f"expected {what}")
    if len(items) != n:
        raise InvalidArgumentError(name, f"{len(items)} entries", f"need {n}, one per limb ({what})")
    return list(items)


def check_home(mech: Mechanism) -> None:
    """Raise PlatformMismatchError if the platform frames do not coincide at ``home``.

    Raises:
        LoopMismatchError: an internal loop of a limb is open at ``home``.
        PlatformMismatchError: a limb's platform frame is away from limb 0's.
    """
    for limb in mech.limbs:
        if not limb.loops:
            continue
        data = limb.model.createData()
        pin.framesForwardKinematics(limb.model, data, limb.home)
        for lp in limb.loops:
            oma, omb = data.oMf[lp.frame_a], data.oMf[lp.frame_b]
            dist = float(np.linalg.norm(omb.translation - oma.translation))
            ang = float(np.linalg.norm(pin.log3(oma.rotation.T @ omb.rotation))) if lp.kind == "6d" else 0.0
            if dist > HOME_TOLERANCE_M or ang > HOME_TOLERANCE_RAD:
                raise LoopMismatchError(limb.name, lp.name, lp.frame_names, dist, ang)
    ref = mech.limbs[0]
    m0 = _platform_placement(ref, ref.home)
    for limb in mech.limbs[1:]:
        mi = _platform_placement(limb, limb.home)
        err = pin.log6(m0.inverse() * mi).vector
        dist, ang = float(np.linalg.norm(mi.translation - m0.translation)), float(np.linalg.norm(err[3:]))
        if dist > HOME_TOLERANCE_M or ang > HOME_TOLERANCE_RAD:
            raise PlatformMismatchError(limb.name, ref.name, dist, ang)


def _platform_placement(limb: Limb, q: np.ndarray) -> pin.SE3:
    data = limb.model.createData()
    pin.framesForwardKinematics(limb.model, data, q)
    return data.oMf[limb.platform_frame].copy()


def check_root_links(mech: Mechanism) -> None:
    """Raise URDFError unless every limb starts from the same root link (the base frame K)."""
    roots = [_root_link(lb.model) for lb in mech.limbs]
    for lb, root in zip(mech.limbs[1:], roots[1:], strict=True):
        if root != roots[0]:
            raise URDFError(
                lb.name,
                lb.urdf_path,
                f"its root link is '{root}' but limb '{mech.limbs[0].name}' starts at '{roots[0]}'; "
                "every limb must start from the same base link (frame K)",
            )


def _root_link(model: pin.Model) -> str:
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint == 0:
            return str(f.name)
    return "universe"
