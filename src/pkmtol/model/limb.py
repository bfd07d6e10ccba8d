"""A limb: 1-DOF joints from the base (frame K) to the platform; a serial chain, or a tree closed by loops."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError, UnknownJointError, URDFError
from pkmtol.model.dh import DHTable

#: Loop kinds: ``"6d"`` (two frames coincide) and ``"3d"`` (two points coincide).
LOOP_KINDS = ("6d", "3d")


@dataclass(frozen=True)
class LimbLoop:
    """An internal loop of a limb: two frames of the limb's tree that coincide when it is closed.

    Attributes:
        name: Loop name, used in parameter names (``<limb>.<loop>.<component>``).
        frame_a: Frame id of the first side in the limb's model.
        frame_b: Frame id of the second side; its placement error ``frame_b · exp6(ε)`` is the
            loop's closure error.
        kind: ``"6d"`` (the frames coincide in position and orientation) or ``"3d"`` (their
            origins coincide).
        frame_names: ``(frame_a, frame_b)`` names.
    """

    name: str
    frame_a: int
    frame_b: int
    kind: str
    frame_names: tuple[str, str] = ("", "")

    @property
    def rows(self) -> int:
        """Number of closure equations: 6 (``6d``) or 3 (``3d``)."""
        return 6 if self.kind == "6d" else 3


@dataclass(frozen=True, eq=False)
class Limb:
    """One limb from the base (frame K) to the platform.

    A limb is a serial chain, or a tree whose extra branches close by internal ``loops`` (a
    parallelogram forearm, a four-bar): every moving joint then lies on the path from the base to
    the platform frame or to a loop frame.

    Attributes:
        name: Limb name, used in parameter names (``<limb>.<joint>.<component>``).
        model: Pinocchio model of the limb; ``nq == nv`` (1-DOF joints only).
        platform_frame: Frame id of the platform link in ``model``.
        actuated: Indices (into this limb's q) of actuated joints (at most one).
        home: Home joint values (nq,) [rad or m].
        urdf_path: Source URDF (None if built from a ``pin.Model``).
        attach_name: Name of the fixed joint that attaches the platform (for parameter names).
        dh: Optional D–H table (enables the ``dh`` error-parameter set).
        visual_model: Optional ``pin.GeometryModel`` of the visuals (for the viewer).
        loops: The internal loops (empty for a serial limb).
    """

    name: str
    model: pin.Model
    platform_frame: int
    actuated: tuple[int, ...]
    home: np.ndarray
    urdf_path: Path | None = None
    attach_name: str = "platform_attach"
    dh: DHTable | None = None
    visual_model: Any = None
    loops: tuple[LimbLoop, ...] = ()

    @property
    def nq(self) -> int:
        """Number of joints of the limb."""
        return int(self.model.nq)

    @property
    def n_origins(self) -> int:
        """Origin errors of the limb: its joints, the platform attachment, then one per loop."""
        return self.nq + 1 + len(self.loops)

    @property
    def n_raw(self) -> int:
        """Raw errors of the limb: 6 per origin error, then one zero offset per joint."""
        return 6 * self.n_origins + self.nq

    @cached_property
    def attach_frames(self) -> frozenset[int]:
        """Frame ids that the platform-attachment error moves: the platform frame and its attach frame.

        A loop side on one of them moves with it.
        """
        ids = {self.platform_frame}
        ids.update(k for k, f in enumerate(self.model.frames) if f.name == self.attach_name)
        return frozenset(ids)

    @property
    def loop_rows(self) -> int:
        """Number of internal-loop closure equations."""
        return sum(lp.rows for lp in self.loops)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in q order."""
        return tuple(self.model.names[1:])

    @property
    def passive(self) -> tuple[int, ...]:
        """Indices of the passive joints."""
        return tuple(i for i in range(self.nq) if i not in self.actuated)

    @property
    def joint_kinds(self) -> tuple[str, ...]:
        """``"R"`` or ``"P"`` per joint, read from the Pinocchio joint type."""
        return tuple(joint_kind(self.model.joints[j].shortname()) for j in range(1, self.model.njoints))


def frame_id(model: pin.Model, name: str) -> int:
    """Id of the frame ``name`` (a link's body frame when a fixed joint has the same name)."""
    ids = [k for k, f in enumerate(model.frames) if f.name == name]
    body = [k for k in ids if model.frames[k].type == pin.FrameType.BODY]
    return (body or ids)[0]


def _check_joint_numbers(model: pin.Model, j: int, kind: str, limb: str, path: Path | None) -> None:
    """Unit axis, finite origin and limits (``lower ≤ upper``) of joint ``j``, else URDFError."""
    joint = model.joints[j]
    jdata = joint.createData()
    joint.calc(jdata, np.zeros(1))
    s = np.asarray(jdata.S).reshape(6)
    axis = s[3:] if kind == "R" else s[:3]
    jname = model.names[j]
    if not np.all(np.isfinite(s)) or abs(float(np.linalg.norm(axis)) - 1.0) > 1e-6:
        raise URDFError(
            limb,
            path,
            f"joint '{jname}': its axis {np.round(axis, 9).tolist()} is not a unit vector; give it a "
            "direction of length 1 (e.g. 0 0 1)",
        )
    placement = model.jointPlacements[j]
    if not (np.all(np.isfinite(placement.translation)) and np.all(np.isfinite(placement.rotation))):
        raise URDFError(limb, path, f"joint '{jname}': its origin is not finite (nan or inf)")
    lo, hi = float(model.lowerPositionLimit[j - 1]), float(model.upperPositionLimit[j - 1])
    if np.isnan(lo) or np.isnan(hi) or lo > hi:
        raise URDFError(
            limb, path, f"joint '{jname}': its limits [{lo:g}, {hi:g}] are not a range lower ≤ upper"
        )


def joint_kind(shortname: str) -> str:
    """``"R"`` (bounded revolute), ``"P"`` (prismatic) or ``"?"`` for a Pinocchio joint short name."""
    if shortname.startswith("JointModelR") and "Unbounded" not in shortname and "RUB" not in shortname:
        return "R"
    if shortname.startswith("JointModelP"):
        return "P"
    return "?"


def make_limb(
    name: str,
    model: pin.Model,
    actuated: list[str],
    platform_link: str,
    home: Sequence[float] | np.ndarray | None,
    path: Path | None,
    dh: DHTable | None = None,
    visual_model: Any = None,
    loops: Sequence[tuple[str, str, str, str]] = (),
) -> Limb:
    """Validate a limb model and wrap it.

    Checked: every joint is a 1-DOF revolute or prismatic joint with a unit axis, finite origin
    and limits; the chain does not branch (unless ``loops`` are given: then every joint lies on a
    path to the platform or a loop frame); the platform link is at its end; the actuated names
    exist (at most one); ``home`` has one finite value per joint; the loops are well formed.

    Args:
        name: Limb name.
        model: The limb's ``pin.Model``: a serial chain, or a tree when ``loops`` are given.
        actuated: Names of its actuated joints (at most one).
        platform_link: Name of the platform frame in ``model``.
        home: Joint values where the limb's platform frame meets the others' and its loops close.
        path: Source file (for messages).
        dh: Optional D–H table (serial limbs only).
        visual_model: Optional visuals.
        loops: Internal loops ``(name, frame_a, frame_b, kind)`` with ``kind`` ``"6d"`` or ``"3d"``.

    Raises:
        URDFError: a joint that is not 1-DOF or has bad numbers, a branch without loops, a joint on
            no path to the platform or a loop frame, a bad loop, or a wrong ``home``.
        UnknownJointError: an actuated joint is not in the model.
        InvalidArgumentError: a name or ``model`` of the wrong type.
    """
    values.text("limb name", name)
    if not isinstance(model, pin.Model):
        raise InvalidArgumentError(f"model of limb '{name}'", model, "expected a pinocchio.Model")
    actuated = list(values.strings(f"actuated joints of limb '{name}'", actuated))
    values.text("platform frame", platform_link)
    if model.njoints < 2:
        raise URDFError(name, path, "the limb has no moving joint (a limb needs at least one)")
    for j in range(1, model.njoints):
        kind = joint_kind(model.joints[j].shortname())
        if kind == "?" or model.joints[j].nq != 1:
            raise URDFError(
                name,
                path,
                f"joint '{model.names[j]}' is of type {model.joints[j].shortname()}; pkmtol "
                "takes 1-DOF revolute or prismatic joints only (write a continuous joint as "
                "revolute with wide limits, a universal or spherical joint as 2 or 3 revolutes)",
            )
        if model.parents[j] != j - 1 and not loops:
            raise URDFError(
                name,
                path,
                f"joint '{model.names[j]}' branches: a limb without internal loops must be a serial "
                "chain (close each extra branch by a loop, [[limbs.loops]] in mechanism.toml)",
            )
        _check_joint_numbers(model, j, kind, name, path)
    named = [i for i, f in enumerate(model.frames) if f.name == platform_link]
    # the link of that name (a joint may share it); a limb cut from a closed-loop tree has a frame
    bodies = [i for i in named if model.frames[i].type == pin.FrameType.BODY] or named
    if not bodies:
        raise URDFError(
            name,
            path,
            f"no platform link '{platform_link}' (links: "
            + ", ".join(f.name for f in model.frames if f.type == pin.FrameType.BODY)
            + ")",
        )
    fid = bodies[0]
    if not loops and model.frames[fid].parentJoint != model.njoints - 1:
        raise URDFError(name, path, f"platform link '{platform_link}' is not at the end of the chain")
    limb_loops = _limb_loops(name, model, path, fid, loops, dh) if loops else ()
    joint_names = list(model.names[1:])
    act: list[int] = []
    for a in actuated:
        if a not in joint_names:
            src = path.name if path is not None else "the model"
            raise UnknownJointError(name, a, joint_names, src)
        act.append(joint_names.index(a))
    if len(act) > 1:
        raise URDFError(name, path, f"{len(act)} actuated joints; a limb may have at most one")
    attach = platform_link + "_attach"
    if not loops:
        for f in model.frames:
            if f.type == pin.FrameType.FIXED_JOINT and f.parentJoint == model.njoints - 1:
                attach = f.name
    elif model.frames[model.frames[fid].parentFrame].type == pin.FrameType.FIXED_JOINT:
        attach = model.frames[model.frames[fid].parentFrame].name
    if home is None:
        home_arr = np.zeros(model.nq)
    else:
        home_arr = values.array(f"home of limb '{name}'", home)
        if home_arr.shape != (model.nq,):
            raise URDFError(name, path, f"home has {home_arr.size} values for {model.nq} joints")
    return Limb(
        name=name,
        model=model,
        platform_frame=fid,
        actuated=tuple(act),
        home=home_arr,
        urdf_path=path,
        attach_name=attach,
        dh=dh,
        visual_model=visual_model,
        loops=limb_loops,
    )


def _limb_loops(
    name: str,
    model: pin.Model,
    path: Path | None,
    platform: int,
    loops: Sequence[tuple[str, str, str, str]],
    dh: DHTable | None,
) -> tuple[LimbLoop, ...]:
    """The checked :class:`LimbLoop` objects of a tree limb (see :func:`make_limb`)."""
    if dh is not None:
        raise URDFError(
            name, path, "a D–H table describes a serial limb; a limb with loops takes the urdf set"
        )
    frames = [f.name for f in model.frames]
    parent = model.frames[model.frames[platform].parentFrame]
    taken = set(model.names[1:]) | {model.frames[platform].name, parent.name}
    out: list[LimbLoop] = []
    used_b: set[int] = set()
    for lname, fa, fb, kind in loops:
        what = f"loop '{lname}'"
        if lname in taken or not lname:
            raise URDFError(
                name, path, f"{what}: the name is empty or also a joint, frame or loop name; rename the loop"
            )
        taken.add(lname)
        if kind not in LOOP_KINDS:
            raise URDFError(name, path, f"{what}: unknown type {kind!r}; use '6d' or '3d'")
        ids = []
        for side in (fa, fb):
            if not model.existFrame(side):
                raise URDFError(
                    name, path, f"{what}: no frame '{side}' in the limb (frames: {', '.join(frames[1:])})"
                )
            ids.append(frame_id(model, side))
        ja, jb = (model.frames[f].parentJoint for f in ids)
        if ja == jb:
            raise URDFError(
                name,
                path,
                f"{what}: '{fa}' and '{fb}' are on the same link, so the loop has no joint; "
                "put the two frames on the two links the loop joins",
            )
        if ids[1] == platform or ids[1] in used_b:
            raise URDFError(
                name,
                path,
                f"{what}: frame '{fb}' (the side whose placement error is the loop's) is the platform "
                "frame or another loop's; give the loop a frame of its own",
            )
        used_b.add(ids[1])
        out.append(LimbLoop(lname, ids[0], ids[1], kind, (fa, fb)))
    for lp in out:
        if lp.frame_a in used_b:
            raise URDFError(
                name,
                path,
                f"loop '{lp.name}': frame '{lp.frame_names[0]}' is the second side of another loop; "
                "give each loop its own frames",
            )
    ends = [model.frames[platform].parentJoint] + [
        model.frames[f].parentJoint for lp in out for f in (lp.frame_a, lp.frame_b)
    ]
    reached = {j for e in ends for j in model.supports[e]}
    for j in range(1, model.njoints):
        if j not in reached:
            raise URDFError(
                name,
                path,
                f"joint '{model.names[j]}' lies on no path from the base to the platform or to a "
                "loop frame: close its branch by a loop, or remove it",
            )
    return tuple(out)
