"""The tool chain on the platform: a serial wrist, the spindle and the TCP frame (``[tool]``).

A hybrid machine is a parallel module (the limbs) carrying a serial chain: its own URDF, rooted
on the platform link, whose joints are the wrist's (each actuated, or locked at a given value),
ending at the spindle nose. The TCP is the point ``length_m`` beyond the nose along the nose
frame's z axis, which is the tool axis (from the spindle towards the tool tip). pkmtol adds the
TCP as a frame ``tcp`` of the chain's ``pin.Model``, so Pinocchio's frame kinematics and
kinematic regressor give its pose, its Jacobian and its error columns like the limbs'.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import UnknownJointError, URDFError
from pkmtol.model.dh import DHTable
from pkmtol.model.limb import Limb, frame_id, joint_kind

#: Name of the TCP frame pkmtol adds to the tool chain's model.
TCP_FRAME = "tcp"
#: Name of the tool chain in messages (the ``limb`` of its errors).
TOOL = "tool"


@dataclass(frozen=True, eq=False)
class Tool:
    """A serial tool chain rooted on the platform link (the wrist, the spindle, the tool).

    Attributes:
        model: The chain's ``pin.Model``; its root is the platform link (frame = the platform
            frame), its joints are 1-DOF, and it holds the added frame ``tcp``.
        actuated: Indices (into the chain's q) of the actuated wrist joints, in chain order.
        home: Joint values, shape (nq,) [rad or m]: the locked joints' values, and the actuated
            joints' first guess for the inverse kinematics.
        nose_frame: Frame id of the spindle nose in ``model``.
        tcp_frame: Frame id of the TCP in ``model``.
        length_m: Tool length: the TCP is ``(0, 0, length_m)`` in the nose frame [m].
        urdf_path: Source URDF (None if built from a ``pin.Model``).
        visual_model: Optional ``pin.GeometryModel`` of the visuals (for the viewer).
        dh: Optional D–H table of the chain, platform → spindle nose (``[tool.dh]``; enables the
            wrist's ``dh`` parameters).
    """

    model: pin.Model
    actuated: tuple[int, ...]
    home: np.ndarray
    nose_frame: int
    tcp_frame: int
    length_m: float
    urdf_path: Path | None = None
    visual_model: Any = None
    dh: DHTable | None = None

    @property
    def nq(self) -> int:
        """Number of joints of the chain."""
        return int(self.model.nq)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in chain order."""
        return tuple(self.model.names[j] for j in range(1, self.model.njoints))

    @property
    def joint_kinds(self) -> tuple[str, ...]:
        """``"R"`` or ``"P"`` per joint."""
        return tuple(joint_kind(self.model.joints[j].shortname()) for j in range(1, self.model.njoints))

    @property
    def locked(self) -> tuple[int, ...]:
        """Indices of the locked joints (held at their ``home`` values)."""
        return tuple(j for j in range(self.nq) if j not in self.actuated)

    @property
    def nose_name(self) -> str:
        """Name of the spindle-nose frame."""
        return str(self.model.frames[self.nose_frame].name)

    def as_limb(self, frame: int | None = None) -> Limb:
        """The chain as a :class:`Limb` (platform → TCP): the same raw-error layout, for limb readers.

        Its "platform frame" is the TCP frame and its attachment the TCP frame's placement
        (``tool.tcp``), so a tool parameter's raw errors index it as a limb's do; ``frame``
        another end frame (the spindle nose: the end of its D–H table).
        """
        return Limb(
            name=TOOL,
            model=self.model,
            platform_frame=self.tcp_frame if frame is None else frame,
            actuated=self.actuated,
            home=self.home,
            urdf_path=self.urdf_path,
            attach_name=TCP_FRAME,
            visual_model=self.visual_model,
        )

    def with_length(self, length_m: float) -> Tool:
        """The same chain with another tool length [m] (``--tool-length``)."""
        length = values.number("length_m", length_m)
        values.within_length("length_m", length)
        model = self.model.copy()
        nose = model.frames[self.nose_frame]
        model.frames[self.tcp_frame].placement = nose.placement * pin.SE3(np.eye(3), np.array([0, 0, length]))
        return replace(self, model=model, length_m=float(length))

    def with_locked(self, locked: Mapping[str, float]) -> Tool:
        """The same chain with the joints ``locked`` (name → value [rad or m]) held (3-axis work)."""
        locked = values.joint_values("locked", locked)
        home = self.home.copy()
        names = self.joint_names
        for jname, value in locked.items():
            if jname not in names:
                raise UnknownJointError(TOOL, jname, names, "the tool chain")
            home[names.index(jname)] = float(value)
        actuated = tuple(j for j in self.actuated if names[j] not in locked)
        return replace(self, actuated=actuated, home=home)


def make_tool(
    model: pin.Model,
    platform_link: str,
    actuated: Sequence[str],
    locked: Mapping[str, float],
    nose_frame: str,
    length_m: float,
    home: Sequence[float] | np.ndarray | None = None,
    path: Path | None = None,
    visual_model: Any = None,
) -> Tool:
    """Validate a tool chain's model, add its TCP frame and wrap it.

    Checked: the root link is the platform link; the joints form one chain of 1-DOF revolute or
    prismatic joints; the nose frame exists and is carried by the last joint; every joint is
    either actuated or locked (a serial chain has no passive joint), and not both.

    Args:
        model: The chain's ``pin.Model`` (e.g. from its URDF).
        platform_link: Name of the module's platform link, the chain's root.
        actuated: Names of the actuated wrist joints.
        locked: Locked joints: name → value [rad or m].
        nose_frame: Name of the spindle-nose frame (a link of the chain).
        length_m: Tool length, nose → TCP along the nose z axis [m].
        home: First guess of every joint (nq,) [rad or m] (default: zeros); a locked joint's
            ``locked`` value replaces its entry.
        path: Source file (for messages).
        visual_model: Optional visuals.

    Raises:
        URDFError: a wrong root link, a branch, a joint that is not 1-DOF, a missing nose frame.
        UnknownJointError: an actuated or locked name that is not a joint of the chain.
    """
    values.instance("model", model, pin.Model, "a pinocchio.Model of the tool chain")
    root = next((f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == 0), None)
    if root != platform_link:
        raise URDFError(
            TOOL,
            path,
            f"its root link is '{root}'; the tool chain must start at the platform link "
            f"'{platform_link}' (the wrist is mounted on the platform)",
        )
    names = tuple(model.names[j] for j in range(1, model.njoints))
    for j in range(1, model.njoints):
        kind = joint_kind(model.joints[j].shortname())
        if kind == "?" or model.joints[j].nq != 1:
            raise URDFError(
                TOOL, path, f"joint '{model.names[j]}' is not a 1-DOF revolute or prismatic joint"
            )
        if model.parents[j] != j - 1:
            raise URDFError(
                TOOL,
                path,
                f"joint '{model.names[j]}' branches off joint '{model.names[model.parents[j]]}'; "
                "the tool chain must be one serial chain from the platform to the spindle nose",
            )
    if not any(f.name == nose_frame for f in model.frames):
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        raise URDFError(
            TOOL, path, f"no link '{nose_frame}' for the spindle nose (links: {', '.join(links)})"
        )
    nose = frame_id(model, nose_frame)
    if model.njoints > 1 and model.frames[nose].parentJoint != model.njoints - 1:
        raise URDFError(
            TOOL,
            path,
            f"the spindle nose '{nose_frame}' is not carried by the last joint "
            f"'{model.names[model.njoints - 1]}'; put it at the end of the chain",
        )
    for jname in [*actuated, *locked]:
        if jname not in names:
            raise UnknownJointError(TOOL, jname, names, str(path or "the tool chain"))
    both = sorted(set(actuated) & set(locked))
    if both:
        raise URDFError(TOOL, path, f"joint '{both[0]}' is both actuated and locked; choose one")
    loose = [n for n in names if n not in actuated and n not in locked]
    if loose:
        raise URDFError(
            TOOL,
            path,
            f"joint '{loose[0]}' is neither actuated nor locked; a serial tool chain has no passive "
            "joint (list it in [tool] actuated, or give its value in [tool] locked)",
        )
    q = np.zeros(model.nq) if home is None else values.vector("home", home, model.nq).copy()
    for jname, value in locked.items():
        q[names.index(jname)] = float(value)
    length = values.number("length_m", length_m)
    values.within_length("length_m", length)
    model = model.copy()
    f = model.frames[nose]
    tcp = pin.Frame(
        TCP_FRAME,
        f.parentJoint,
        nose,
        f.placement * pin.SE3(np.eye(3), np.array([0.0, 0.0, length])),
        pin.FrameType.OP_FRAME,
    )
    tcp_id = model.addFrame(tcp, False)
    return Tool(
        model=model,
        actuated=tuple(sorted(names.index(n) for n in actuated)),
        home=q,
        nose_frame=nose,
        tcp_frame=int(tcp_id),
        length_m=float(length),
        urdf_path=path,
        visual_model=visual_model,
    )
