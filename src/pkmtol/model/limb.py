"""A limb: one serial chain of 1-DOF joints from the base (frame K) to the platform, and its checks."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError, UnknownJointError, URDFError
from pkmtol.model.dh import DHTable


@dataclass(frozen=True, eq=False)
class Limb:
    """One serial limb from the base (frame K) to the platform.

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

    @property
    def nq(self) -> int:
        """Number of joints of the limb."""
        return int(self.model.nq)

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
) -> Limb:
    """Validate a limb model and wrap it (raises URDFError / UnknownJointError / InvalidArgumentError).

    Checked: every joint is a 1-DOF revolute or prismatic joint with a unit axis, finite origin
    and limits; the chain does not branch; the platform link is at its end; the actuated names
    exist (at most one); ``home`` has one finite value per joint.
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
        if model.parents[j] != j - 1:
            raise URDFError(name, path, f"joint '{model.names[j]}' branches: a limb must be a serial chain")
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
    if model.frames[fid].parentJoint != model.njoints - 1:
        raise URDFError(name, path, f"platform link '{platform_link}' is not at the end of the chain")
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
    for f in model.frames:
        if f.type == pin.FrameType.FIXED_JOINT and f.parentJoint == model.njoints - 1:
            attach = f.name
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
    )
