"""Deriving a limb's D–H table from its joint axes at home: the common normals, link by link.

A limb is described by the lines of its joint axes in K at home (a point and a direction each,
:class:`Axis`) and the platform frame; :func:`dh_rows` turns them into the D–H rows of
``[limbs.dh]`` (paper §2.1: link j maps K_{j-1} to K_j by ``Rz(θ_j) Tz(d_j) Tx(a_j) Rx(φ_j)``, the
end link adds ``Tz(d_e) Rz(θ_e)``) with every revolute at 0 and every slide at its home length;
:func:`limb_table` checks that the table reproduces the platform frame at home (1e-9), and
:func:`rounded` rounds it as a mechanism.toml holds it (:mod:`pkmtol.model.families` uses them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pkmtol.exceptions import InvalidArgumentError
from pkmtol.model.dh import DHTable, forward

#: Decimals of the D–H entries (degrees and metres) and of the homes in a written mechanism.toml.
DH_DECIMALS = 6
HOME_DECIMALS = 5


@dataclass(frozen=True)
class Axis:
    """A joint axis at home: ``kind`` R or P, a point on its line and a unit direction (in K)."""

    name: str
    kind: str
    point: np.ndarray
    direction: np.ndarray


def unit(v: Any) -> np.ndarray:
    """``v`` scaled to length 1."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _angle(a: np.ndarray, b: np.ndarray, about: np.ndarray) -> float:
    """Signed angle from ``a`` to ``b`` about ``about`` (all unit, a and b ⟂ about)."""
    return math.atan2(float(np.cross(a, b) @ about), float(a @ b))


def dh_rows(
    axes: Sequence[Axis], home: Sequence[float], platform: tuple[np.ndarray, np.ndarray]
) -> tuple[list[list[float]], tuple[float, float]]:
    """D–H rows (θ, d, a, φ) [rad, m] for links 1..n+1 and (d_e, θ_e), constant parts at ``home``."""
    o, x, z = np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    rows = []
    p_origin, p_rot = platform
    lines = [(a.point, unit(a.direction)) for a in axes] + [(p_origin, p_rot[:, 2])]
    for k, (p, u) in enumerate(lines):
        c = np.cross(z, u)
        if np.linalg.norm(c) > 1e-12:
            # closest points of o + s z and p + t u
            m = np.array([[z @ z, -(z @ u)], [z @ u, -(u @ u)]])
            s, t = np.linalg.solve(m, np.array([(p - o) @ z, (p - o) @ u]))
            f1, f2 = o + s * z, p + t * u
            gap = f2 - f1
            xn = unit(gap) if np.linalg.norm(gap) > 1e-12 else unit(c)
        else:
            # parallel lines: the common normal through the axis's own point
            f1 = o + ((p - o) @ z) * z
            perp = p - f1
            xn = unit(perp) if np.linalg.norm(perp) > 1e-12 else x
            f2 = p
        theta = _angle(x, xn, z)
        d = float((f1 - o) @ z)
        a = float((f2 - f1) @ xn)
        phi = _angle(z, u, xn)
        if k > 0:  # the variable of joint k (1-based) enters link k+1
            if axes[k - 1].kind == "R":
                theta -= home[k - 1]
            else:
                d -= home[k - 1]
        rows.append([theta, d, a, phi])
        o, x, z = f2, xn, u
    d_e = float((p_origin - o) @ z)
    theta_e = _angle(x, p_rot[:, 0], z)
    return rows, (d_e, theta_e)


def limb_table(
    name: str,
    axes: Sequence[Axis],
    home: Sequence[float],
    platform: tuple[np.ndarray, np.ndarray],
    limits: Sequence[Sequence[float]],
) -> tuple[DHTable, list[float]]:
    """The D–H table of a limb from its axes at home; checks that it reproduces the platform frame.

    Args:
        name: Limb name (for the error message).
        axes: Its joint axes at home, base to platform.
        home: Its joint values at home [rad or m].
        platform: Platform frame at home: ``(origin (3,), rotation (3, 3))`` in K.
        limits: Joint limits [rad or m] (unrounded).

    Raises:
        InvalidArgumentError: the table misses the platform frame by more than 1e-9 (the axes
            do not describe a chain that reaches it).
    """
    rows, end = dh_rows(axes, home, platform)
    table = DHTable(
        links=np.round(np.array(rows), 12),
        end=end,
        joint_types=tuple(a.kind for a in axes),
        joint_names=tuple(a.name for a in axes),
        limits=np.array(limits, dtype=float),
    )
    got = forward(table, np.array(home))
    err = max(
        float(np.linalg.norm(got.translation - platform[0])),
        float(np.linalg.norm(got.rotation - platform[1])),
    )
    if not err < 1e-9:
        raise InvalidArgumentError(
            f"limb {name}", f"{err:.3g}", "its D–H table misses the platform frame at home"
        )
    return table, list(home)


def rounded(
    table: DHTable, home: Sequence[float], limits_user: Sequence[Sequence[float]]
) -> tuple[DHTable, list[float]]:
    """The table and home as a mechanism.toml holds them (6 and 5 decimals), and limits in TOML units."""
    links = np.array(table.links, dtype=float).copy()
    links[:, 0] = np.radians(np.round(np.degrees(links[:, 0]), DH_DECIMALS))
    links[:, 3] = np.radians(np.round(np.degrees(links[:, 3]), DH_DECIMALS))
    links[:, 1:3] = np.round(links[:, 1:3], DH_DECIMALS)
    end = (round(table.end[0], DH_DECIMALS), math.radians(round(math.degrees(table.end[1]), DH_DECIMALS)))
    lim = np.array(limits_user, dtype=float).copy()
    for k, t in enumerate(table.joint_types):
        if t == "R":
            lim[k] = np.radians(lim[k])
    out = DHTable(
        links=links, end=end, joint_types=table.joint_types, joint_names=table.joint_names, limits=lim
    )
    return out, [round(float(h), HOME_DECIMALS) + 0.0 for h in home]


def radial_tangential(angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal unit vectors at ``angle_deg`` about z: radial and tangential (counter-clockwise)."""
    a = math.radians(angle_deg)
    return np.array([math.cos(a), math.sin(a), 0.0]), np.array([-math.sin(a), math.cos(a), 0.0])


def ups_axes(
    name: str, base: np.ndarray, plat: np.ndarray, u1: np.ndarray, s: Sequence[np.ndarray]
) -> tuple[list[Axis], list[float]]:
    """A UPS leg from the base point to the platform point; U first axis ``u1`` (⟂ leg), S axes ``s``."""
    leg = unit(plat - base)
    u2 = unit(np.cross(leg, u1))
    axes = [
        Axis(f"{name}_u1", "R", base, u1),
        Axis(f"{name}_u2", "R", base, u2),
        Axis(f"{name}_p3", "P", base, leg),
        Axis(f"{name}_s4", "R", plat, s[0]),
        Axis(f"{name}_s5", "R", plat, s[1]),
        Axis(f"{name}_s6", "R", plat, s[2]),
    ]
    return axes, [0.0, 0.0, float(np.linalg.norm(plat - base)), 0.0, 0.0, 0.0]
