"""The mechanism: limbs (URDF → ``pin.Model``), actuators, platform, reference point, task space.

A mechanism folder holds ``mechanism.toml`` and one URDF per limb (``docs/mechanism-format.md``).
Every limb URDF is a serial chain of 1-DOF revolute/prismatic joints from the common base link
(frame K) to the platform link; the platform link's frame is the platform frame, and all limbs'
platform frames coincide at the ``home`` configuration given in the TOML (default: all zeros).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.dh import DHTable
from pkmtol.exceptions import (
    MechanismFormatError,
    PlatformMismatchError,
    UnknownJointError,
    URDFError,
)
from pkmtol.taskspace import TaskSpace
from pkmtol.units import parse_length

#: Mismatch allowed between the limbs' platform frames at ``home`` before Newton refines it.
HOME_TOLERANCE_M = 1e-3
HOME_TOLERANCE_RAD = 1e-3

DEFAULT_BETAS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


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
        return tuple(_joint_kind(self.model.joints[j].shortname()) for j in range(1, self.model.njoints))


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

    @property
    def n_joints(self) -> int:
        """Total number of joints over all limbs."""
        return sum(limb.nq for limb in self.limbs)

    @property
    def n_actuators(self) -> int:
        """Number of actuated joints."""
        return sum(len(limb.actuated) for limb in self.limbs)

    def limb(self, name: str) -> Limb:
        """The limb called ``name``."""
        for limb in self.limbs:
            if limb.name == name:
                return limb
        raise KeyError(f"no limb '{name}' (limbs: {', '.join(x.name for x in self.limbs)})")

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
        names = list(limb_names or [f"limb{i + 1}" for i in range(len(models))])
        limbs = []
        for i, (lname, model) in enumerate(zip(names, models, strict=True)):
            home = None if homes is None else homes[i]
            limbs.append(_make_limb(lname, model, list(actuated[i]), platform_frame, home, None))
        return cls.from_limbs(name, limbs, reference_point_m, task_space, target_m, betas, design_beta)

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
    ) -> Mechanism:
        """A mechanism from validated limbs, checked: one common root link, closed at ``home``.

        Every constructor of pkmtol (TOML, ``pin.Model`` limbs, closed-loop tree) ends here.

        Raises:
            URDFError: the limbs start from different root links.
            PlatformMismatchError: the platform frames do not coincide at ``home``.
        """
        mech = cls(
            name=name,
            limbs=tuple(limbs),
            reference_point_m=np.asarray(reference_point_m, dtype=float),
            task_space=task_space,
            target_m=float(target_m),
            betas=tuple(float(b) for b in betas),
            design_beta=float(design_beta),
            root=root,
            description=description,
            extra=dict(extra or {}),
        )
        check_root_links(mech)
        check_home(mech)
        return mech


def _joint_kind(shortname: str) -> str:
    if shortname.startswith("JointModelR") and "Unbounded" not in shortname and "RUB" not in shortname:
        return "R"
    if shortname.startswith("JointModelP"):
        return "P"
    return "?"


def _make_limb(
    name: str,
    model: pin.Model,
    actuated: list[str],
    platform_link: str,
    home: Sequence[float] | None,
    path: Path | None,
    dh: DHTable | None = None,
    visual_model: Any = None,
) -> Limb:
    """Validate a limb model and wrap it (raises URDFError / UnknownJointError)."""
    for j in range(1, model.njoints):
        kind = _joint_kind(model.joints[j].shortname())
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
    if model.njoints < 2:
        raise URDFError(name, path, "the limb has no moving joint")
    if not model.existFrame(platform_link):
        raise URDFError(
            name,
            path,
            f"no platform link '{platform_link}' (links: "
            + ", ".join(f.name for f in model.frames if f.type == pin.FrameType.BODY)
            + ")",
        )
    fid = model.getFrameId(platform_link)
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
        home_arr = np.asarray(home, dtype=float)
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


def check_home(mech: Mechanism) -> None:
    """Raise PlatformMismatchError if the platform frames do not coincide at ``home``."""
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


# --- TOML loading ------------------------------------------------------------------------


def load_mechanism(folder: Path | str) -> Mechanism:
    """Load ``<folder>/mechanism.toml`` and its limb URDFs.

    Raises:
        MechanismFormatError: the folder has no mechanism.toml, or a key is missing or mistyped.
        URDFError: a limb URDF is missing, malformed or unusable.
        UnknownJointError: an actuated joint is not in its limb.
        PlatformMismatchError: the limbs' platform frames do not coincide at ``home``.
    """
    folder = Path(folder)
    path = folder / "mechanism.toml"
    if not folder.is_dir():
        raise MechanismFormatError(
            path, "-", f"'{folder}' is not a folder; give a robot folder such as robots/r2rps_ups"
        )
    if not path.is_file():
        raise MechanismFormatError(
            path, "-", "file not found; a robot folder needs a mechanism.toml (see docs/mechanism-format.md)"
        )
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise MechanismFormatError(path, "-", f"not valid TOML: {err}") from err
    r = _Reader(path, doc)
    name = r.get("name", str)
    platform_link = r.get("platform_link", str, default="platform")
    p_ref = r.vector("reference_point.position_m", 3)
    kind = r.get("task.kind", str, default="position")
    if kind != "position":
        r.fail("task.kind", f"unknown task kind {kind!r}; supported: 'position' (of P)")
    task_space = _read_task_space(r)
    target = r.get("design.target", (str, float, int), default="0.05 mm")
    try:
        target_m = parse_length(target, "design.target")
    except Exception as err:
        r.fail("design.target", str(err))
    betas = tuple(float(b) for b in r.array("design.beta", default=list(DEFAULT_BETAS)))
    design_beta = float(r.get("design.design_beta", (float, int), default=2.0))
    limbs = []
    if "closed_loop" in doc:
        # one URDF tree with closure frame pairs (docs/closed-loop.md); local import: that
        # module builds on this one
        from pkmtol.closed_loop import limbs_from_toml

        limbs = limbs_from_toml(folder, r)
    limbs_doc = r.get("limbs", list) if "closed_loop" not in doc else []
    if "closed_loop" not in doc and len(limbs_doc) < 2:
        r.fail("limbs", "a parallel mechanism needs at least two [[limbs]]")
    for i, ld in enumerate(limbs_doc):
        lr = _Reader(path, ld, prefix=f"limbs[{i}].")
        lname = lr.get("name", str)
        urdf = folder / lr.get("urdf", str)
        actuated = lr.get("actuated", list, default=[])
        home = lr.get("home", list, default=None)
        dh = _read_dh(lr) if "dh" in ld else None
        model, visual = _load_urdf(lname, urdf)
        limbs.append(_make_limb(lname, model, actuated, platform_link, home, urdf, dh, visual))
    return Mechanism.from_limbs(
        name,
        limbs,
        p_ref,
        task_space,
        target_m,
        betas,
        design_beta,
        root=folder,
        description=r.get("description", str, default=""),
        extra={"cost": r.get("cost", dict, default={})},
    )


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


def _load_urdf(limb: str, path: Path) -> tuple[pin.Model, Any]:
    if not path.is_file():
        raise URDFError(limb, path, "file not found; check the 'urdf' entry of this limb in mechanism.toml")
    text = path.read_text(encoding="utf-8")
    import xml.etree.ElementTree as ET

    try:
        ET.fromstring(text)
    except ET.ParseError as err:
        raise URDFError(limb, path, f"malformed XML: {err}") from err
    try:
        model = pin.buildModelFromXML(text)
    except (RuntimeError, ValueError) as err:
        raise URDFError(limb, path, f"Pinocchio cannot read it: {err}") from err
    try:
        visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    except Exception:  # noqa: BLE001 - visuals are optional (meshes may be missing)
        visual = None
    return model, visual


def _read_task_space(r: _Reader) -> TaskSpace:
    kind = r.get("task_space.kind", str)
    if kind == "cylinder":
        z = r.vector("task_space.z_m", 2)
        rings_f = r.array("task_space.rings")
        if rings_f.ndim != 1 or np.any(rings_f != np.round(rings_f)):
            r.fail("task_space.rings", f"expected a list of integers, got {rings_f.tolist()!r}")
        rings = tuple(int(x) for x in rings_f)
        radius = float(r.get("task_space.radius_m", (float, int)))
        layers = int(r.get("task_space.layers", int))
        if radius <= 0 or layers < 1 or not rings or min(rings) < 1 or z[1] < z[0]:
            r.fail("task_space", "need radius_m > 0, layers ≥ 1, rings of ≥ 1 point and z_m = [min, max]")
        return TaskSpace(
            kind="cylinder",
            radius_m=radius,
            z_range_m=(float(z[0]), float(z[1])),
            layers=layers,
            rings=rings,
            center_xy_m=tuple(r.vector("task_space.center_xy_m", 2, default=[0.0, 0.0])),  # type: ignore[arg-type]
        )
    if kind == "points":
        pts = r.array("task_space.points_m")
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            r.fail("task_space.points_m", "need a list of [x, y, z] points in metres")
        return TaskSpace(kind="points", points_m=pts)
    r.fail("task_space.kind", f"unknown kind {kind!r}; use 'cylinder' or 'points'")
    raise AssertionError  # unreachable


def _read_dh(r: _Reader) -> DHTable:
    types = tuple(r.get("dh.joint_types", list))
    n = len(types)
    links = r.array("dh.links")
    if links.shape != (n + 1, 4):
        r.fail("dh.links", f"need {n + 1} rows [theta_deg, d_m, a_m, phi_deg] for {n} joints")
    links = links.copy()
    links[:, 0] = np.radians(links[:, 0])
    links[:, 3] = np.radians(links[:, 3])
    end = r.vector("dh.end", 2)
    limits = r.array("dh.limits")
    if limits.shape != (n, 2):
        r.fail("dh.limits", f"need {n} rows [lower, upper] (deg for R, m for P)")
    limits = limits.copy()
    for k, t in enumerate(types):
        if t == "R":
            limits[k] = np.radians(limits[k])
    names = tuple(r.get("dh.joint_names", list))
    try:
        return DHTable(
            links=links,
            end=(float(end[0]), math.radians(end[1])),
            joint_types=types,
            joint_names=names,
            limits=limits,
        )  # type: ignore[arg-type]
    except ValueError as err:
        r.fail("dh", str(err))
        raise


class _Reader:
    """Typed access to a TOML document with errors that name the file and the dotted key."""

    def __init__(self, path: Path, doc: dict[str, Any], prefix: str = "") -> None:
        self.path, self.doc, self.prefix = path, doc, prefix

    def fail(self, key: str, problem: str) -> None:
        raise MechanismFormatError(self.path, self.prefix + key, problem)

    _MISSING = object()

    def get(self, key: str, types: Any, default: Any = _MISSING) -> Any:
        node: Any = self.doc
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                if default is not self._MISSING:
                    return default
                self.fail(key, "missing; see docs/mechanism-format.md")
            node = node[part]
        tt = types if isinstance(types, tuple) else (types,)
        if isinstance(node, bool) or not isinstance(node, tt):
            names = " or ".join(t.__name__ for t in tt)
            self.fail(key, f"expected {names}, got {type(node).__name__} {node!r}")
        return node

    def array(self, key: str, default: Any = _MISSING) -> np.ndarray:
        """Read a (nested) list of numbers as a float array; fail naming ``key`` if it is not."""
        v = self.get(key, list, default)
        try:
            return np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            self.fail(key, f"expected a list of numbers (rows of equal length), got {v!r}")
            raise

    def vector(self, key: str, n: int, default: Any = _MISSING) -> np.ndarray:
        v = self.get(key, list, default)
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if arr.shape != (n,):
            self.fail(key, f"expected a list of {n} numbers, got {v!r}")
        return arr
