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

import numpy as np
import pinocchio as pin

JOINT_TYPES = ("R", "P")


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
        n = len(self.joint_types)
        if self.links.shape != (n + 1, 4):
            raise ValueError(f"D–H table needs {n + 1} link rows for {n} joints, got {self.links.shape}")
        if len(self.joint_names) != n or self.limits.shape != (n, 2):
            raise ValueError("D–H table: joint_names and limits need one entry per joint")
        bad = [t for t in self.joint_types if t not in JOINT_TYPES]
        if bad:
            raise ValueError(f"D–H joint types must be 'R' or 'P', got {bad}")

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
