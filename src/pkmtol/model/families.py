"""Mechanism families from a few dimensions: the bundled robots' structures with their sizes as parameters.

Each family (:data:`FAMILIES`) is the structure of a bundled robot (``robots/``): the Tricept
(3-UPS&UP), the Sprint Z3 head (3-PRS), the Exechon (2-UPR&SPR) and the paper's seed robot
R(2-RPS&RP)&UPS. A family function takes the dimensions [m] and returns the limbs as
:class:`LimbDraft` (D–H table, home, limits, actuated joint) in a :class:`RobotDraft`;
:mod:`pkmtol.model.robot_files` writes it as a robot folder and ``pkmtol new`` checks it.

The Tricept, Sprint Z3 and Exechon limbs are given by their joint axes at home
(:mod:`pkmtol.model.dh_derivation` derives the D–H rows); the seed robot is written in the
paper's own form (Tables I and II, with the α of its UPS/RPS limbs). Numbers are rounded as the
bundled files hold them (D–H entries to 6 decimals, homes to 5), so that the defaults reproduce
``robots/<name>`` exactly (``tests/test_families.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.model.dh import DHTable, forward
from pkmtol.model.dh_derivation import Axis, limb_table, radial_tangential, rounded, unit, ups_axes
from pkmtol.model.wrist_draft import DESCRIPTIONS, WRIST_HELP, wrist_fields


@dataclass(frozen=True)
class Dimension:
    """One dimension of a family: ``pkmtol new <family> --<name with dashes> VALUE``.

    Attributes:
        name: Keyword of the family function (``base_radius``).
        default: The bundled robot's value.
        unit: ``"m"``, ``"deg"``, or ``"m2"`` for a ``[min, max]`` pair in metres.
        help: What it is.
    """

    name: str
    default: float | tuple[float, float]
    unit: str
    help: str


@dataclass(frozen=True)
class LimbDraft:
    """A limb of a generated robot.

    Attributes:
        name: Limb name (also its URDF's stem and link prefix).
        table: Its D–H table (radians and metres, rounded as written).
        home: Joint values at home [rad or m] (rounded as written).
        limits: Joint limits as written in the TOML (deg for R, m for P), one ``[lower, upper]`` each.
        actuated: The actuated joint names ([] for a passive limb).
        comment: A comment line for the TOML.
    """

    name: str
    table: DHTable
    home: tuple[float, ...]
    limits: tuple[tuple[float, float], ...]
    actuated: tuple[str, ...]
    comment: str = ""


@dataclass(frozen=True)
class RobotDraft:
    """A robot folder's content before it is written (see :mod:`pkmtol.model.robot_files`).

    Attributes:
        family: Family name.
        description: The ``description`` key.
        limbs: The limbs, reference limb first.
        reference_point_m: P in the platform frame [m].
        task_space: ``[task_space]`` keys (cylinder).
        dimensions: The dimensions used, by name (for the header comment).
        comment: Header comment lines.
    """

    family: str
    description: str
    limbs: tuple[LimbDraft, ...]
    reference_point_m: tuple[float, float, float]
    task_space: Mapping[str, Any]
    dimensions: Mapping[str, Any] = field(default_factory=dict)
    comment: tuple[str, ...] = ()
    tool: Mapping[str, Any] | None = None


def _draft(
    name: str,
    table: DHTable,
    home: Sequence[float],
    limits_user: Sequence[Sequence[float]],
    actuated: Sequence[str],
    comment: str = "",
) -> LimbDraft:
    t, h = rounded(table, home, limits_user)
    return LimbDraft(
        name, t, tuple(h), tuple((float(a), float(b)) for a, b in limits_user), tuple(actuated), comment
    )


def _cylinder(radius: float, z: tuple[float, float]) -> dict[str, Any]:
    return {"kind": "cylinder", "radius_m": radius, "z_m": [z[0], z[1]], "layers": 3, "rings": [8, 16, 24]}


def _check(name: str, value: Any, *, positive: bool = True) -> float:
    return values.number(f"--{name.replace('_', '-')}", value, positive=positive)


def _range(name: str, value: Any, *, nonnegative: bool = True) -> tuple[float, float]:
    arr = values.vector(f"--{name.replace('_', '-')}", value, 2)
    if not arr[0] < arr[1] or (nonnegative and arr[0] < 0):
        low = "0 ≤ " if nonnegative else ""
        raise InvalidArgumentError(
            f"--{name.replace('_', '-')}",
            f"{arr[0]:g} {arr[1]:g}",
            f"write it as MIN MAX, {low}MIN < MAX [m]",
        )
    return float(arr[0]), float(arr[1])


def _in_stroke(option: str, length: float, stroke: tuple[float, float]) -> None:
    if not stroke[0] <= length <= stroke[1]:
        raise InvalidArgumentError(
            option,
            f"{stroke[0]:g} {stroke[1]:g}",
            f"the leg is {length:.5g} m long at home, outside this stroke; widen it or change the dimensions",
        )


def tricept(
    base_radius: float = 0.45,
    platform_radius: float = 0.18,
    height: float = 0.9,
    offset: float = 0.3,
    leg_stroke: tuple[float, float] = (0.6, 1.4),
    centre_stroke: tuple[float, float] = (0.5, 1.3),
    task_radius: float = 0.4,
    task_z: tuple[float, float] = (1.1, 1.3),
) -> RobotDraft:
    """Tricept 3-UPS&UP: U joints at ``base_radius`` (90°, 210°, 330°), S joints at ``platform_radius``.

    The central passive UP limb has its U at O (axes x, then y) and slides along the platform's z;
    O' is at (0, 0, ``height``) at home, P at ``offset`` beyond it [m].
    """
    rb, rp, h = (
        _check("base_radius", base_radius),
        _check("platform_radius", platform_radius),
        _check("height", height),
    )
    stroke, centre = _range("leg_stroke", leg_stroke), _range("centre_stroke", centre_stroke)
    platform = (np.array([0, 0, h]), np.eye(3))
    limbs = []
    for i, ang in enumerate((90.0, 210.0, 330.0)):
        r, t = radial_tangential(ang)
        # S axes at home: radial, tangential, vertical (orthogonal, far from gimbal lock)
        name = f"leg{i + 1}"
        axes, home = ups_axes(name, rb * r, rp * r + [0, 0, h], t, [r, t, np.array([0, 0, 1.0])])
        _in_stroke("--leg-stroke", home[2], stroke)
        lim: list[Any] = [[-60, 60], [-60, 60], list(stroke), [-180, 180], [-180, 180], [-180, 180]]
        table, home = limb_table(name, axes, home, platform, _limits_si(axes, lim))
        limbs.append(_draft(name, table, home, lim, [f"{name}_p3"]))
    axes = [
        Axis("centre_u1", "R", np.zeros(3), np.array([1.0, 0, 0])),
        Axis("centre_u2", "R", np.zeros(3), np.array([0, 1.0, 0])),
        Axis("centre_p3", "P", np.zeros(3), np.array([0, 0, 1.0])),
    ]
    _in_stroke("--centre-stroke", h, centre)
    lim = [[-60, 60], [-60, 60], list(centre)]
    table, home = limb_table("centre", axes, [0.0, 0.0, h], platform, _limits_si(axes, lim))
    limbs.append(_draft("centre", table, home, lim, []))
    return RobotDraft(
        family="tricept",
        description="Tricept 3-UPS&UP: three actuated UPS legs, passive central UP limb",
        limbs=tuple(limbs),
        reference_point_m=(0.0, 0.0, _check("offset", offset, positive=False)),
        task_space=_cylinder(_check("task_radius", task_radius), _range("task_z", task_z, nonnegative=False)),
        comment=("Tricept (3-UPS&UP): three actuated UPS legs and a passive central UP limb.",),
    )


def sprint_z3(
    rail_radius: float = 0.3,
    platform_radius: float = 0.2,
    rod_length: float = 0.4,
    slider_height: float = 0.2,
    offset: float = 0.3,
    slider_stroke: tuple[float, float] = (0.0, 0.5),
    task_radius: float = 0.15,
    task_z: tuple[float, float] = (0.8, 0.95),
) -> RobotDraft:
    """Sprint Z3 head 3-PRS: sliders on rails at ``rail_radius`` along z, R then a rod to the S joints.

    At home the sliders are at ``slider_height`` and the platform is level [m].
    """
    rb, rp, rod = (
        _check("rail_radius", rail_radius),
        _check("platform_radius", platform_radius),
        _check("rod_length", rod_length),
    )
    zs = _check("slider_height", slider_height, positive=False)
    stroke = _range("slider_stroke", slider_stroke, nonnegative=False)
    if rod <= abs(rb - rp):
        raise InvalidArgumentError(
            "--rod-length", rod, f"must be longer than |rail radius − platform radius| = {abs(rb - rp):g} m"
        )
    _in_stroke("--slider-stroke", zs, stroke)
    h = zs + math.sqrt(rod**2 - (rb - rp) ** 2)  # O' height at home
    platform = (np.array([0, 0, h]), np.eye(3))
    limbs = []
    for i, ang in enumerate((90.0, 210.0, 330.0)):
        r, t = radial_tangential(ang)
        c = rb * r + [0, 0, zs]  # R joint on the slider
        b = rp * r + [0, 0, h]  # S joint on the platform
        n = f"leg{i + 1}"
        # S axes at home: tangential (parallel to the R), radial, vertical
        axes = [
            Axis(f"{n}_p1", "P", rb * r, np.array([0, 0, 1.0])),
            Axis(f"{n}_r2", "R", c, t),
            Axis(f"{n}_s3", "R", b, t),
            Axis(f"{n}_s4", "R", b, r),
            Axis(f"{n}_s5", "R", b, np.array([0, 0, 1.0])),
        ]
        lim: list[Any] = [list(stroke), [-90, 90], [-180, 180], [-180, 180], [-180, 180]]
        table, home = limb_table(n, axes, [zs, 0.0, 0.0, 0.0, 0.0], platform, _limits_si(axes, lim))
        limbs.append(_draft(n, table, home, lim, [f"{n}_p1"]))
    return RobotDraft(
        family="sprint_z3",
        description="Sprint Z3 head 3-PRS: three actuated sliders on parallel rails at 120°, R then S",
        limbs=tuple(limbs),
        reference_point_m=(0.0, 0.0, _check("offset", offset, positive=False)),
        task_space=_cylinder(_check("task_radius", task_radius), _range("task_z", task_z, nonnegative=False)),
        comment=("Sprint Z3 head (3-PRS): three actuated sliders on parallel rails at 120°, R then S.",),
    )


def exechon(
    u_spacing: float = 0.3,
    s_offset: float = 0.45,
    upr_platform: float = 0.12,
    spr_platform: float = 0.18,
    height: float = 0.9,
    offset: float = 0.3,
    leg_stroke: tuple[float, float] = (0.6, 1.4),
    task_radius: float = 0.4,
    task_z: tuple[float, float] = (1.1, 1.3),
) -> RobotDraft:
    """Exechon 2-UPR&SPR: U centres at (0, ∓``u_spacing``, 0) on the axis y, S at (−``s_offset``, 0, 0).

    The platform revolutes are at (0, ∓``upr_platform``, 0) (axis x) and (−``spr_platform``, 0, 0)
    (axis y) in the platform frame; O' at (0, 0, ``height``) at home [m].
    """
    b, c = _check("u_spacing", u_spacing), _check("s_offset", s_offset)
    e, e2, h = (
        _check("upr_platform", upr_platform),
        _check("spr_platform", spr_platform),
        _check("height", height),
    )
    stroke = _range("leg_stroke", leg_stroke)
    platform = (np.array([0, 0, h]), np.eye(3))
    out = []
    for n, y in (("leg1", -1.0), ("leg3", 1.0)):
        base = np.array([0, y * b, 0])
        plat = np.array([0, y * e, h])
        leg = unit(plat - base)
        axes = [
            Axis(f"{n}_u1", "R", base, np.array([0, 1.0, 0])),  # common U axis of the two UPR legs
            Axis(f"{n}_u2", "R", base, np.array([1.0, 0, 0])),  # ⟂ the plane of the two legs
            Axis(f"{n}_p3", "P", base, leg),
            Axis(f"{n}_r4", "R", plat, np.array([1.0, 0, 0])),  # platform R, parallel to u2
        ]
        length = float(np.linalg.norm(plat - base))
        _in_stroke("--leg-stroke", length, stroke)
        lim: list[Any] = [[-60, 60], [-60, 60], list(stroke), [-90, 90]]
        table, home = limb_table(n, axes, [0.0, 0.0, length, 0.0], platform, _limits_si(axes, lim))
        out.append(_draft(n, table, home, lim, [f"{n}_p3"]))
    base = np.array([-c, 0, 0])
    plat = np.array([-e2, 0, h])
    leg = unit(plat - base)
    axes = [
        Axis("leg2_s1", "R", base, np.array([0, 0, 1.0])),
        Axis("leg2_s2", "R", base, np.array([0, 1.0, 0])),
        Axis("leg2_s3", "R", base, np.array([1.0, 0, 0])),
        Axis("leg2_p4", "P", base, leg),
        Axis("leg2_r5", "R", plat, np.array([0, 1.0, 0])),  # platform R, along the line of the UPR joints
    ]
    length = float(np.linalg.norm(plat - base))
    _in_stroke("--leg-stroke", length, stroke)
    lim = [[-180, 180], [-180, 180], [-180, 180], list(stroke), [-90, 90]]
    table, home = limb_table("leg2", axes, [0.0, 0.0, 0.0, length, 0.0], platform, _limits_si(axes, lim))
    spr = _draft("leg2", table, home, lim, ["leg2_p4"])
    return RobotDraft(
        family="exechon",
        description="Exechon 2-UPR&SPR: two actuated UPR legs in a common swinging plane, "
        "one actuated SPR leg",
        limbs=(out[0], spr, out[1]),  # limb order: leg1 (UPR), leg2 (SPR), leg3 (UPR)
        reference_point_m=(0.0, 0.0, _check("offset", offset, positive=False)),
        task_space=_cylinder(_check("task_radius", task_radius), _range("task_z", task_z, nonnegative=False)),
        comment=(
            "Exechon (2-UPR&SPR): two actuated UPR legs whose U joints share their first axis, one SPR leg.",
        ),
    )


def r2rps_ups(
    ups_base: float = 0.5,
    rps_base: float = 0.45,
    ups_platform: float = 0.25,
    rps_platform: float = 0.25,
    height: float = 0.75,
    offset: float = 0.3,
    leg_stroke: tuple[float, float] = (0.4, 1.6),
    centre_stroke: tuple[float, float] = (0.3, 1.6),
    task_radius: float = 0.6,
    task_z: tuple[float, float] = (0.9, 1.1),
) -> RobotDraft:
    """The paper's R(2-RPS&RP)&UPS in its Tables I and II: b_1 = ``ups_base``, b_{2,3} = ∓``rps_base``, e_i.

    Limb 1 (UPS, α = 1) has its U at (``ups_base``, 0, 0) and its S at ``ups_platform`` along the
    platform's x; limbs 2 and 3 (RPS, α = 0) their base R at y = ±``rps_base`` and their S at
    ∓``rps_platform`` along the platform's y; limb 4 (UP, passive) has its U at O and slides along
    the platform axis, ``height`` at home [m].
    """
    b1, b = _check("ups_base", ups_base), _check("rps_base", rps_base)
    e1, e = _check("ups_platform", ups_platform), _check("rps_platform", rps_platform)
    h = _check("height", height)
    stroke, centre = _range("leg_stroke", leg_stroke), _range("centre_stroke", centre_stroke)
    _in_stroke("--centre-stroke", h, centre)
    ups = [
        [0, 0, b1, 90],
        [90, 0, 0, 90],
        [90, 0, 0, 90],
        [0, 0, 0, 0],
        [0, 0, 0, 90],
        [90, 0, 0, 90],
        [90, 0, e1, 90],
    ]
    a1, l1 = math.atan2(b1 - e1, h), math.hypot(b1 - e1, h)
    a2, l2 = math.atan2(b - e, h), math.hypot(b - e, h)
    specs: list[Any] = [
        (
            "limb1",
            ["u1", "u2", "p3", "s4", "s5", "s6"],
            ups,
            180.0,
            [a1, 0.0, l1, 0.0, 0.0, -a1],
            "UPS (α = 1)",
        ),
        (
            "limb2",
            ["r1", "r2", "p3", "s4", "s5", "s6"],
            _rps(-b, e),
            90.0,
            [0.0, a2, l2, 0.0, 0.0, -a2],
            "RPS (α = 0)",
        ),
        (
            "limb3",
            ["r1", "r2", "p3", "s4", "s5", "s6"],
            _rps(b, -e),
            90.0,
            [0.0, -a2, l2, 0.0, 0.0, a2],
            "RPS (α = 0)",
        ),
    ]
    leg_lim: list[Any] = [
        [-90.0, 90.0],
        [-90.0, 90.0],
        list(stroke),
        [-180.0, 180.0],
        [-180.0, 180.0],
        [-180.0, 180.0],
    ]
    limbs = []
    for name, joints, rows, theta_e, home, what in specs:
        _in_stroke("--leg-stroke", home[2], stroke)
        table = _paper_table(name, joints, rows, theta_e, "RRPRRR", leg_lim)
        limbs.append(_draft(name, table, home, leg_lim, [f"{name}_p3"], what))
    lim4: list[Any] = [[-90.0, 90.0], [-90.0, 90.0], list(centre)]
    rows4 = [[0, 0, 0, 90], [90, 0, 0, 90], [90, 0, 0, 90], [0, 0, 0, 0]]
    table4 = _paper_table("limb4", ["u1", "u2", "p3"], rows4, 90.0, "RRP", lim4)
    limbs.append(_draft("limb4", table4, [0.0, 0.0, h], lim4, [], "UP, passive (Table II)"))
    _check_closed(limbs)
    return RobotDraft(
        family="r2rps_ups",
        description="R(2-RPS&RP)&UPS parallel mechanism of a 5-DOF hybrid machining robot (paper §4)",
        limbs=tuple(limbs),
        reference_point_m=(0.0, 0.0, _check("offset", offset, positive=False)),
        task_space=_cylinder(_check("task_radius", task_radius), _range("task_z", task_z, nonnegative=False)),
        comment=("R(2-RPS&RP)&UPS: the parallel part of the paper's 5-DOF hybrid machining robot.",),
    )


def r2rps_ups_wrist(
    ups_base: float = 0.5,
    rps_base: float = 0.45,
    ups_platform: float = 0.25,
    rps_platform: float = 0.25,
    height: float = 0.75,
    offset: float = 0.3,
    leg_stroke: tuple[float, float] = (0.4, 1.6),
    centre_stroke: tuple[float, float] = (0.3, 1.6),
    c_height: float = 0.15,
    nose: float = 0.12,
    tool_length: float = 0.15,
    task_radius: float = 0.3,
    task_z: tuple[float, float] = (1.15, 1.3),
    task_center_x: float = 0.19,
) -> RobotDraft:
    """The seed robot (:func:`r2rps_ups`) with the A/C wrist (:mod:`pkmtol.model.wrist_draft`)."""
    module = r2rps_ups(
        ups_base, rps_base, ups_platform, rps_platform, height, offset, leg_stroke, centre_stroke
    )
    fields = wrist_fields(
        module.comment, offset, c_height, nose, tool_length, task_radius, task_z, task_center_x
    )
    return RobotDraft(
        "r2rps_ups_wrist", DESCRIPTIONS["r2rps_ups_wrist"], module.limbs, module.reference_point_m, **fields
    )


def tricept_wrist(
    base_radius: float = 0.45,
    platform_radius: float = 0.18,
    height: float = 0.9,
    offset: float = 0.3,
    leg_stroke: tuple[float, float] = (0.6, 1.4),
    centre_stroke: tuple[float, float] = (0.5, 1.3),
    c_height: float = 0.15,
    nose: float = 0.12,
    tool_length: float = 0.15,
    task_radius: float = 0.2,
    task_z: tuple[float, float] = (1.35, 1.5),
    task_center_x: float = 0.19,
) -> RobotDraft:
    """The Tricept (:func:`tricept`) with the A/C wrist (:mod:`pkmtol.model.wrist_draft`)."""
    module = tricept(base_radius, platform_radius, height, offset, leg_stroke, centre_stroke)
    fields = wrist_fields(
        module.comment, offset, c_height, nose, tool_length, task_radius, task_z, task_center_x
    )
    return RobotDraft(
        "tricept_wrist", DESCRIPTIONS["tricept_wrist"], module.limbs, module.reference_point_m, **fields
    )


def _rps(b: float, e: float) -> list[list[float]]:
    return [
        [0, 0, 0, 90],
        [90, b, 0, 90],
        [90, 0, 0, 90],
        [0, 0, 0, 0],
        [90, 0, 0, 90],
        [90, 0, 0, 90],
        [90, 0, e, 90],
    ]


def _paper_table(
    limb: str,
    joints: Sequence[str],
    rows_deg: Sequence[Sequence[float]],
    theta_e_deg: float,
    kinds: str,
    limits_user: Sequence[Sequence[float]],
) -> DHTable:
    links = np.array(rows_deg, dtype=float)
    links[:, 0] = np.radians(links[:, 0])
    links[:, 3] = np.radians(links[:, 3])
    lim = np.array(limits_user, dtype=float)
    for k, t in enumerate(kinds):
        if t == "R":
            lim[k] = np.radians(lim[k])
    return DHTable(
        links=links,
        end=(0.0, math.radians(theta_e_deg)),
        joint_types=tuple(kinds),
        joint_names=tuple(f"{limb}_{j}" for j in joints),
        limits=lim,
    )


def _check_closed(limbs: Sequence[LimbDraft]) -> None:
    """All platform frames at home within 1e-4 m / rad of the first (homes are rounded to 1e-5)."""
    ref = forward(limbs[0].table, np.array(limbs[0].home))
    for lb in limbs[1:]:
        m = forward(lb.table, np.array(lb.home))
        gap = max(
            float(np.linalg.norm(m.translation - ref.translation)),
            float(np.linalg.norm(m.rotation - ref.rotation)),
        )
        if gap > 1e-4:
            raise InvalidArgumentError(
                f"limb {lb.name}", f"{gap:.3g}", "the limbs do not close at home with these dimensions"
            )


def _limits_si(axes: Sequence[Axis], limits_user: Sequence[Sequence[float]]) -> list[list[float]]:
    return [
        [math.radians(v) for v in lim] if a.kind == "R" else [float(v) for v in lim]
        for a, lim in zip(axes, limits_user, strict=True)
    ]


#: One line per family, for ``pkmtol new --help``.
SUMMARY = {
    "tricept": "Tricept 3-UPS&UP: three actuated UPS legs around a passive central UP limb",
    "sprint_z3": "Sprint Z3 head 3-PRS: three actuated sliders on parallel rails, R then S",
    "exechon": "Exechon 2-UPR&SPR: two UPR legs sharing their first U axis, one SPR leg",
    "r2rps_ups": "the paper's R(2-RPS&RP)&UPS (the seed robot): one UPS and two RPS legs, a passive UP limb",
    "r2rps_ups_wrist": "the seed robot with its A/C wrist and spindle: the paper's whole 5-DOF hybrid robot",
    "tricept_wrist": "the Tricept with its classic A/C wrist and spindle: a 5-axis hybrid machine",
}

#: The families: name → (function, its dimensions with defaults).
FAMILIES: dict[str, tuple[Callable[..., RobotDraft], tuple[Dimension, ...]]] = {}


def _register(fn: Callable[..., RobotDraft], helps: Mapping[str, str]) -> None:
    import inspect

    dims = []
    for p in inspect.signature(fn).parameters.values():
        d = p.default
        dims.append(Dimension(p.name, d, "m2" if isinstance(d, tuple) else "m", helps.get(p.name, "")))
    FAMILIES[fn.__name__] = (fn, tuple(dims))


_COMMON = {
    "height": "height of O' above the base at home [m]",
    "offset": "P beyond O' along the platform axis (the offset l) [m]",
    "leg_stroke": "stroke of the actuated legs: MIN MAX [m]",
    "centre_stroke": "stroke of the passive central slide: MIN MAX [m]",
    "task_radius": "radius of the cylindrical task space of P [m]",
    "task_z": "height range of the task space: MIN MAX [m]",
}
TRICEPT_HELP = {
    "base_radius": "radius of the leg U joints on the base [m]",
    "platform_radius": "radius of the leg S joints on the platform [m]",
}
_register(tricept, {**_COMMON, **TRICEPT_HELP})
_register(
    sprint_z3,
    {
        **_COMMON,
        "rail_radius": "radius of the three rails [m]",
        "platform_radius": "radius of the S joints on the platform [m]",
        "rod_length": "length of the rods from R to S [m]",
        "slider_height": "slider position at home [m]",
        "slider_stroke": "slider stroke: MIN MAX [m]",
    },
)
_register(
    exechon,
    {
        **_COMMON,
        "u_spacing": "U centres at y = ∓this on the common U axis [m]",
        "s_offset": "S centre of the SPR leg at x = −this [m]",
        "upr_platform": "UPR platform revolutes at y = ∓this in the platform frame [m]",
        "spr_platform": "SPR platform revolute at x = −this in the platform frame [m]",
    },
)
FAMILY_HELP = {
    "ups_base": "b_1: the UPS U joint at x = this [m]",
    "rps_base": "|b_2| = |b_3|: the RPS base R joints at y = ±this [m]",
    "ups_platform": "e_1: the UPS S joint along the platform's x [m]",
    "rps_platform": "|e_2| = |e_3|: the RPS S joints along the platform's y [m]",
    "height": "height of O' (limb 4's slide) at home [m]",
}
_register(r2rps_ups, {**_COMMON, **FAMILY_HELP})

_register(
    r2rps_ups_wrist, {**_COMMON, **{k: v for k, v in FAMILY_HELP.items() if k != "offset"}, **WRIST_HELP}
)
_register(tricept_wrist, {**_COMMON, **TRICEPT_HELP, **WRIST_HELP})


def draft(family: str, **dimensions: Any) -> RobotDraft:
    """The robot of ``family`` with ``dimensions`` (the others at their defaults).

    Raises:
        InvalidArgumentError: an unknown family or dimension, or dimensions that do not make the
            mechanism (naming the option).
    """
    values.choice("family", family, FAMILIES)
    fn, dims = FAMILIES[family]
    known = {d.name for d in dims}
    for key in dimensions:
        if key not in known:
            values.choice("dimension", key, sorted(known))
    used = {d.name: dimensions.get(d.name, d.default) for d in dims}
    robot = fn(**used)
    return RobotDraft(**{**robot.__dict__, "dimensions": used})
