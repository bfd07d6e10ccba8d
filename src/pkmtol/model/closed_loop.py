"""Closed-loop URDF import: one URDF tree with closure frame pairs, cut into serial limbs.

The convention is the "extended URDF" of Gepetto's example-parallel-robots (docs/closed-loop.md):
the mechanism is written as one kinematic *tree* rooted at the base link; every kinematic loop is
left open in the tree and closed by a pair of frames that must coincide, named
``closedloop<k>_A`` / ``closedloop<k>_B`` (k = loop number, 1-based). A sidecar file next to the
URDF (``robot.yaml``, or ``robot.toml`` with the same keys) lists the loops and the motors:

``closed_loop``
    list of frame-name pairs ``[[frame, frame], ...]``, one per loop (either order); when the key
    is missing, frames named ``closedloop<k>_A`` / ``closedloop<k>_B`` are paired by ``k``.
``type``
    per loop, ``"6d"`` (the two frames coincide in position and orientation) or ``"3d"`` (position
    only); default all ``"6d"``. pkmtol takes ``"6d"`` loops only.
``name_mot``
    the motor (actuated) joints; default: every joint whose name contains ``mot``.
``joint_name`` / ``joint_type``
    optional joint re-typing; ``FIXED`` locks a joint at 0 (``SPHERICAL`` and ``CARDAN`` are not
    1-DOF joints and are refused: write them as 3 or 2 revolutes).

How the tree is cut (:func:`cut_tree`):

* the **platform** is the link that holds one side of every loop (``platform_link`` overrides it;
  with a single loop, the ``_A`` side's link is taken); its frame is the platform frame O';
* the **reference limb** (limb 1) is the chain from the root to the platform: the branch the
  platform hangs on in the tree;
* each loop k gives one more limb: the chain from the root to the loop's other frame (the
  *limb-side* closure frame), ended by a platform frame placed where the platform is when the
  loop is closed: ``jMp = jMB · (pMA)⁻¹`` (B the limb-side frame relative to the limb's last
  joint, A the platform-side frame relative to the platform frame). Its origin error is that
  limb's platform-attachment parameter, named after the loop (``<limb>.closedloop<k>.dx`` ...);
* joints beyond the platform (e.g. a serial wrist) are not part of the parallel mechanism and are
  left out; any other moving joint that lies on no limb is an error (lock it with ``FIXED``).

Each limb's ``pin.Model`` is built joint by joint from the tree's ``pin.Model`` (same joint
models, placements and limits; the root link, the joint and body frames along the chain), so the
numbers are the tree's own. The result is an ordinary :class:`~pkmtol.model.mechanism.Mechanism`;
every later stage (kinematics, error model, allocation, viewer) sees serial limbs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path

import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import ClosedLoopError
from pkmtol.model.limb import Limb
from pkmtol.model.mechanism import DEFAULT_BETAS, Mechanism
from pkmtol.model.reading import TomlReader
from pkmtol.model.sidecar import Sidecar, default_sidecar, read_sidecar
from pkmtol.model.taskspace import TaskSpace
from pkmtol.model.tree_cut import MOTOR_MARK, TreeCut, cut_tree, load_tree
from pkmtol.model.tree_limbs import cut_limbs


def closed_loop_limbs(
    urdf: Path | str,
    sidecar: Path | str | Sidecar | None = None,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
) -> tuple[list[Limb], TreeCut]:
    """Cut a closed-loop URDF into :class:`~pkmtol.model.limb.Limb` objects.

    Args:
        urdf: The tree URDF.
        sidecar: The sidecar file (or a :class:`Sidecar`); default: next to the URDF
            (:func:`default_sidecar`).
        platform_link: The platform link (default: the link holding one side of every loop).
        limb_names: Limb names, reference limb first (default ``limb1`` ...).
        home: Joint values [rad or m] by joint name at which every loop closes (±1 mm, ±1 mrad);
            joints not named are at 0.

    Returns:
        ``(limbs, cut)``: the limbs (reference limb first) and how the tree was cut.

    Raises:
        URDFError, MechanismFormatError, ClosedLoopError (and its subclasses): see
        :func:`load_tree`, :func:`read_sidecar`, :func:`cut_tree`.
    """
    urdf = values.path("urdf", urdf)
    if isinstance(sidecar, Sidecar):
        side = sidecar
    else:
        side = read_sidecar(default_sidecar(urdf) if sidecar is None else values.path("sidecar", sidecar))
    tree, visual, _ = load_tree(urdf)
    locked = []
    for jname, jtype in side.joint_types.items():
        if not tree.existJointName(jname):
            raise ClosedLoopError(
                side.path or urdf,
                jname,
                f"joint_name '{jname}' is not a joint of the tree (joints: {', '.join(tree.names[1:])})",
            )
        if jtype == "FIXED":
            locked.append(tree.getJointId(jname))
        else:
            raise ClosedLoopError(
                side.path or urdf,
                jname,
                f"joint_type {jtype} of '{jname}': pkmtol takes 1-DOF joints only; write a spherical "
                "joint as three revolutes, a cardan as two",
            )
    if locked:
        if side.motors is not None:
            motors = set(side.motors)
        else:
            motors = {n for n in tree.names[1:] if MOTOR_MARK in n}
        for j in locked:
            if tree.names[j] in motors:
                raise ClosedLoopError(side.path or urdf, tree.names[j], "a motor joint cannot be FIXED")
        q0 = pin.neutral(tree)
        if visual is not None:
            tree, visual = pin.buildReducedModel(tree, visual, locked, q0)
        else:
            tree = pin.buildReducedModel(tree, locked, q0)
    cut = cut_tree(tree, side, platform_link, limb_names, urdf)
    cut = dataclasses.replace(cut, locked=tuple(side.joint_types))
    limbs = cut_limbs(tree, visual, cut, home, urdf)
    return limbs, cut


def load_closed_loop(
    urdf: Path | str,
    sidecar: Path | str | Sidecar | None = None,
    *,
    reference_point_m: Sequence[float],
    task_space: TaskSpace,
    name: str | None = None,
    platform_link: str | None = None,
    limb_names: Sequence[str] | None = None,
    home: Mapping[str, float] | None = None,
    target_m: float = 5e-5,
    betas: Sequence[float] = DEFAULT_BETAS,
    design_beta: float = 2.0,
    description: str = "",
) -> Mechanism:
    """Build a mechanism from a closed-loop URDF and its sidecar (the Python twin of ``[closed_loop]``).

    Args:
        urdf: The tree URDF (closure frames ``closedloop<k>_A`` / ``closedloop<k>_B``).
        sidecar: The sidecar file or a :class:`Sidecar`; default ``<stem>.yaml``/``.yml``/``.toml``.
        reference_point_m: P in the platform frame, shape (3,) [m].
        task_space: Task space of P in K.
        name: Mechanism name (default: the URDF's file stem).
        platform_link: The platform link (default: the link holding one side of every loop).
        limb_names: Limb names, reference limb first (default ``limb1`` ...).
        home: Joint values [rad or m] by joint name where every loop closes (default 0).
        target_m: Δλ* [m].
        betas: β series.
        design_beta: β of the design case.
        description: Free text.

    Raises:
        URDFError, MechanismFormatError, ClosedLoopError: bad tree or sidecar (naming the culprit).
        PlatformMismatchError: a loop is not closed at ``home``.
    """
    urdf = values.path("urdf", urdf)
    limbs, _ = closed_loop_limbs(urdf, sidecar, platform_link, limb_names, home)
    return Mechanism.from_limbs(
        name or urdf.stem,
        limbs,
        reference_point_m,
        task_space,
        target_m,
        betas,
        design_beta,
        description=description,
    )


def limbs_from_toml(folder: Path, r: TomlReader) -> list[Limb]:
    """The limbs of a ``mechanism.toml`` whose ``[closed_loop]`` table names a tree URDF.

    Called by :func:`pkmtol.model.loader.load_mechanism`. Keys (docs/closed-loop.md): ``urdf``
    (required), ``sidecar``, ``platform_link``, ``limbs`` (names), ``home`` (table joint → value).
    """
    urdf = folder / r.get("closed_loop.urdf", str)
    side = r.get("closed_loop.sidecar", str, default=None)
    names = r.strings("closed_loop.limbs", default=None, what="limb names")
    home = r.joint_values("closed_loop.home", default={})
    limbs, _ = closed_loop_limbs(
        urdf,
        None if side is None else folder / side,
        r.get("closed_loop.platform_link", str, default=None),
        names,
        home,
    )
    return limbs
