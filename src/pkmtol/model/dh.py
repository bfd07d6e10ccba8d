"""Denavit–Hartenberg limb tables (the paper's Tables I and II) and their URDF form.

Convention (paper §2.1): link ``j`` transforms frame ``K_{j-1}`` into ``K_j`` by
``Rz(θ_j) Tz(d_j) Tx(a_j) Rx(φ_j)``; the end link adds ``Tz(d_e) Rz(θ_e)``. The variable of
joint ``j-1`` (a rotation about, or a translation along, ``z_{j-1}``) enters ``θ_j`` (R) or
``d_j`` (P) of link ``j``; link 1 is fixed to the base.

Because a joint's motion about ``z_{j-1}`` commutes with ``Rz(θ_j) Tz(d_j)``, link ``j`` equals
``M_{j-1}(q_{j-1}) · D_j`` with the constant ``D_j = Rz(θ_j) Tz(d_j) Tx(a_j) Rx(φ_j)``. The URDF
form is therefore: joint ``k`` (``k = 1..n``) has origin ``D_k`` and axis ``z``; a fixed joint
with origin ``D_{n+1} · Tz(d_e) Rz(θ_e)`` attaches the platform link.

The D–H error parameters (δθ, δd, δa, δφ per link, δd_e, δθ_e for the end link) are linear
combinations of the URDF origin errors ``origin · exp6(ε)``: :func:`dh_error_directions`
returns, for each D–H parameter, the unit ``ε`` it produces in the URDF joint frame.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.exceptions import DHMismatchError, InvalidArgumentError

JOINT_TYPES = ("R", "P")
#: A URDF generated from a D–H table must reproduce it to this [m, rad] (it is written to 1e-15).
DH_MATCH_TOLERANCE = 1e-9


@dataclass(frozen=True)
class DHTable:
    """The D–H table of one limb.

    Attributes:
        links: Shape (n+1, 4): rows ``(θ [rad], d [m], a [m], φ [rad])`` for links 1..n+1,
            constant parts only (the joint variable of joint ``j-1`` is added to ``θ_j`` or ``d_j``).
        end: ``(d_e [m], θ_e [rad])`` of the end link.
        joint_types: ``"R"`` or ``"P"`` for joints 1..n.
        joint_names: URDF names of joints 1..n.
        limits: Shape (n, 2): lower/upper limits of joints 1..n [rad or m].
    """

    links: np.ndarray
    end: tuple[float, float]
    joint_types: tuple[str, ...]
    joint_names: tuple[str, ...]
    limits: np.ndarray

    def __post_init__(self) -> None:
        """Check the shapes and entries (raises InvalidArgumentError naming the field)."""
        types = values.strings("DHTable.joint_types", self.joint_types)
        bad = [t for t in types if t not in JOINT_TYPES]
        if bad or not types:
            raise InvalidArgumentError(
                "DHTable.joint_types", self.joint_types, "expected 'R' or 'P' per joint"
            )
        n = len(types)
        links = values.array("DHTable.links", self.links)
        if links.shape != (n + 1, 4):
            raise InvalidArgumentError(
                "DHTable.links", f"shape {links.shape}", f"need {n + 1} rows (θ, d, a, φ) for {n} joints"
            )
        names = values.strings("DHTable.joint_names", self.joint_names)
        if len(names) != n:
            raise InvalidArgumentError(
                "DHTable.joint_names", self.joint_names, f"need {n} names, one per joint"
            )
        limits = values.array("DHTable.limits", self.limits)
        if limits.shape != (n, 2):
            raise InvalidArgumentError(
                "DHTable.limits", f"shape {limits.shape}", f"need {n} rows (lower, upper), one per joint"
            )
        end = values.vector("DHTable.end", self.end, 2)
        object.__setattr__(self, "links", links)
        object.__setattr__(self, "limits", limits)
        object.__setattr__(self, "joint_types", types)
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "end", (float(end[0]), float(end[1])))

    @property
    def n_joints(self) -> int:
        """Number of 1-DOF joints n."""
        return len(self.joint_types)


def _dh(theta: float, d: float, a: float, phi: float) -> pin.SE3:
    """``Rz(θ) Tz(d) Tx(a) Rx(φ)`` as a placement."""
    rz = pin.SE3(pin.utils.rotate("z", float(theta)), np.array([0.0, 0.0, float(d)]))
    tx = pin.SE3(pin.utils.rotate("x", float(phi)), np.array([float(a), 0.0, 0.0]))
    return rz * tx


def link_origins(table: DHTable) -> list[pin.SE3]:
    """URDF origins: joints 1..n (``D_1 .. D_n``), then the platform attachment ``D_{n+1} T_e``."""
    origins = [_dh(*row) for row in table.links]
    d_e, theta_e = table.end
    te = pin.SE3(pin.utils.rotate("z", theta_e), np.array([0.0, 0.0, d_e]))
    origins[-1] = origins[-1] * te
    return origins


def forward(table: DHTable, q: np.ndarray) -> pin.SE3:
    """Placement of the platform frame in the base frame for joint values ``q`` (n,) [rad, m]."""
    origins = link_origins(table)
    m = pin.SE3.Identity()
    for k, t in enumerate(table.joint_types):
        m = m * origins[k]
        if t == "R":
            m = m * pin.SE3(pin.utils.rotate("z", float(q[k])), np.zeros(3))
        else:
            m = m * pin.SE3(np.eye(3), np.array([0.0, 0.0, float(q[k])]))
    return m * origins[-1]


def check_dh_matches(limb: Any, table: DHTable, command: str) -> None:
    """Raise DHMismatchError unless the limb's URDF is the URDF form of its D–H ``table``.

    Compared, joint by joint: the name, the type (R/P about the joint's z axis), the origin (to
    :data:`DH_MATCH_TOLERANCE` in metres and radians) and the limits; then the platform attachment.

    Args:
        limb: The :class:`~pkmtol.model.limb.Limb` read from the URDF.
        table: Its ``[limbs.dh]`` table.
        command: The command that regenerates the URDF (quoted in the message).
    """
    model = limb.model

    def mismatch(joint: str, what: str, detail: str, difference: float = 0.0) -> DHMismatchError:
        return DHMismatchError(limb.name, limb.urdf_path, joint, what, detail, command, difference)

    if model.nq != table.n_joints:
        raise mismatch(
            limb.joint_names[-1] if limb.joint_names else "-",
            "number of joints",
            f"{model.nq} joints in the URDF, {table.n_joints} in the table",
        )
    origins = link_origins(table)
    for k in range(table.n_joints):
        name, want = str(model.names[k + 1]), table.joint_names[k]
        if name != want:
            raise mismatch(name, "name", f"joint {k + 1} is '{name}' in the URDF, '{want}' in the table")
        kind = table.joint_types[k]
        shortname = model.joints[k + 1].shortname()
        if shortname != ("JointModelRZ" if kind == "R" else "JointModelPZ"):
            raise mismatch(
                name, "type or axis", f"{shortname} in the URDF, a {kind} joint about z in the table"
            )
        _check_origin(model.jointPlacements[k + 1], origins[k], name, mismatch)
        lo_hi = (float(model.lowerPositionLimit[k]), float(model.upperPositionLimit[k]))
        diff = max(abs(lo_hi[0] - table.limits[k, 0]), abs(lo_hi[1] - table.limits[k, 1]))
        if diff > DH_MATCH_TOLERANCE:
            raise mismatch(
                name,
                "limits",
                f"[{lo_hi[0]:.9g}, {lo_hi[1]:.9g}] in the URDF, "
                f"[{table.limits[k, 0]:.9g}, {table.limits[k, 1]:.9g}] in the table (rad or m)",
                diff,
            )
    _check_origin(model.frames[limb.platform_frame].placement, origins[-1], limb.attach_name, mismatch)


def _check_origin(got: pin.SE3, want: pin.SE3, joint: str, mismatch: Any) -> None:
    distance = float(np.linalg.norm(got.translation - want.translation))
    angle = float(np.linalg.norm(pin.log3(want.rotation.T @ got.rotation)))
    if max(distance, angle) > DH_MATCH_TOLERANCE:
        xyz = " ".join(f"{x:.9g}" for x in got.translation)
        txyz = " ".join(f"{x:.9g}" for x in want.translation)
        raise mismatch(
            joint,
            "origin",
            f"xyz ({xyz}) in the URDF, ({txyz}) from the table: {distance:.3g} m and {angle:.3g} rad apart",
            max(distance, angle),
        )


def dh_error_directions(table: DHTable) -> list[list[tuple[str, int, np.ndarray]]]:
    """D–H error parameters as directions of the URDF origin errors.

    For link ``j`` the parameters ``δθ_j, δd_j, δa_j, δφ_j`` (and ``δd_e, δθ_e`` for the end link)
    perturb the constant transform ``D_j``; to first order each equals ``D_j · exp6(c · δ)`` with a
    unit twist ``c`` expressed in the URDF frame at the end of ``D_j`` (the joint frame of joint
    ``j``, or the platform frame for the end link). This is the paper's Appendix (twists
    ``ŝ_{m,j}`` in ``K_j``), computed from the table rather than typed in.

    Returns:
        For each link ``j = 1..n+1``, a list of ``(symbol, origin_index, c)`` with ``symbol`` one of
        ``θ d a φ`` (and ``d_e θ_e``), ``origin_index = j-1`` (0-based URDF origin index; the last
        is the platform attachment) and ``c`` of shape (6,) ordered ``[v; ω]``.
    """
    out: list[list[tuple[str, int, np.ndarray]]] = []
    n1 = table.n_joints + 1
    z = np.array([0.0, 0.0, 1.0])
    x = np.array([1.0, 0.0, 0.0])
    for j, (_theta, _d, a, phi) in enumerate(table.links):
        tail_after_rz = _dh(0.0, 0.0, a, phi)  # Tz(d) commutes with Rz(θ): both about z
        tail_after_tx = pin.SE3(pin.utils.rotate("x", phi), np.zeros(3))
        extra = pin.SE3.Identity()
        if j == n1 - 1:
            d_e, theta_e = table.end
            extra = pin.SE3(pin.utils.rotate("z", theta_e), np.array([0.0, 0.0, d_e]))

        def to_end(tail: pin.SE3, v: np.ndarray, w: np.ndarray, ex: pin.SE3 = extra) -> np.ndarray:
            return (ex.inverse() * tail.inverse()).act(pin.Motion(v, w)).vector

        params = [
            ("θ", to_end(tail_after_rz, np.zeros(3), z)),
            ("d", to_end(tail_after_rz, z, np.zeros(3))),
            ("a", to_end(tail_after_tx, x, np.zeros(3))),
            ("φ", to_end(pin.SE3.Identity(), np.zeros(3), x)),
        ]
        if j == n1 - 1:
            d_e, theta_e = table.end
            rz_e = pin.SE3(pin.utils.rotate("z", theta_e), np.zeros(3))
            params.append(("d_e", rz_e.inverse().act(pin.Motion(z, np.zeros(3))).vector))
            params.append(("θ_e", np.r_[np.zeros(3), z]))
        out.append([(s, j, c) for s, c in params])
    return out


def to_urdf(
    table: DHTable,
    robot_name: str,
    base_link: str,
    platform_link: str,
    link_prefix: str,
    visuals: bool = True,
) -> str:
    """Write a D–H table as a URDF string.

    Links are ``<link_prefix>_l1 .. _ln`` between ``base_link`` and ``platform_link``; joints carry
    ``table.joint_names``. With ``visuals``, each moving link gets a small sphere (R) or a cylinder
    along its axis (P) and the platform a thin plate, so that the limb shows in a viewer.
    """
    origins = link_origins(table)
    robot = ET.Element("robot", name=robot_name)
    names = [base_link] + [f"{link_prefix}_l{k + 1}" for k in range(table.n_joints)] + [platform_link]
    for k, name in enumerate(names):
        link = ET.SubElement(robot, "link", name=name)
        if visuals and 0 < k <= table.n_joints:
            _add_visual(link, table.joint_types[k - 1])
        if visuals and name == platform_link:
            _add_plate(link)
    for k in range(table.n_joints + 1):
        last = k == table.n_joints
        jname = f"{link_prefix}_platform_attach" if last else table.joint_names[k]
        jtype = "fixed" if last else ("revolute" if table.joint_types[k] == "R" else "prismatic")
        joint = ET.SubElement(robot, "joint", name=jname, type=jtype)
        o = origins[k]
        rpy = pin.rpy.matrixToRpy(o.rotation)
        ET.SubElement(joint, "origin", xyz=_fmt(o.translation), rpy=_fmt(rpy))
        ET.SubElement(joint, "parent", link=names[k])
        ET.SubElement(joint, "child", link=names[k + 1])
        if not last:
            ET.SubElement(joint, "axis", xyz="0 0 1")
            lo, hi = table.limits[k]
            ET.SubElement(joint, "limit", lower=_num(lo), upper=_num(hi), effort="1000", velocity="1")
    ET.indent(robot, "  ")
    return (
        '<?xml version="1.0"?>\n'
        "<!-- generated from mechanism.toml by scripts/dh_to_urdf.py; do not edit -->\n"
        + ET.tostring(robot, encoding="unicode")
        + "\n"
    )


def _num(v: float) -> str:
    s = repr(float(v))
    return "0" if s in ("0.0", "-0.0") else s


def _fmt(v: np.ndarray) -> str:
    return " ".join(_num(round(float(x), 15)) for x in v)


def _add_visual(link: ET.Element, joint_type: str) -> None:
    vis = ET.SubElement(link, "visual")
    geom = ET.SubElement(vis, "geometry")
    if joint_type == "R":
        ET.SubElement(geom, "sphere", radius="0.03")
        color = "0.2 0.4 0.8 1"
    else:
        # the sliding leg: a rod behind the joint frame along -z (it moves with the slide)
        ET.SubElement(vis, "origin", xyz="0 0 -0.3", rpy="0 0 0")
        vis.remove(geom)
        vis.append(geom)
        ET.SubElement(geom, "cylinder", radius="0.02", length="0.6")
        color = "0.8 0.5 0.1 1"
    mat = ET.SubElement(vis, "material", name=f"c{joint_type}")
    ET.SubElement(mat, "color", rgba=color)


def _add_plate(link: ET.Element) -> None:
    vis = ET.SubElement(link, "visual")
    ET.SubElement(vis, "geometry").append(ET.Element("cylinder", radius="0.3", length="0.02"))
    mat = ET.SubElement(vis, "material", name="platform")
    ET.SubElement(mat, "color", rgba="0.6 0.6 0.6 0.8")


def deg(x: float) -> float:
    """Degrees to radians."""
    return math.radians(x)
