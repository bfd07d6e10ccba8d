"""Derive the D–H tables and home values of the bundled machines from their dimensions.

Each limb is described at its home configuration by the lines of its joint axes in K (a point and
a direction each) and the platform frame; this script turns them into the D–H rows of
``[limbs.dh]`` (paper §2.1: link j maps K_{j-1} to K_j by ``Rz(θ_j) Tz(d_j) Tx(a_j) Rx(φ_j)``, the
end link adds ``Tz(d_e) Rz(θ_e)``) with every revolute at 0 and every slide at its home length, and
checks that the table reproduces the platform frame at home. The dimensions are those chosen in
docs/robots.md; the printed blocks are what robots/<machine>/mechanism.toml holds (D–H numbers
rounded to 6 decimals, homes to 5).

Usage:
    python scripts/derive_dh.py tricept|exechon|sprint_z3
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass

import numpy as np

from pkmtol.model.dh import DHTable, forward


@dataclass
class Axis:
    """A joint axis at home: ``kind`` R or P, a point on its line and a unit direction (in K)."""

    name: str
    kind: str
    point: np.ndarray
    direction: np.ndarray


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _angle(a: np.ndarray, b: np.ndarray, about: np.ndarray) -> float:
    """Signed angle from ``a`` to ``b`` about ``about`` (all unit, a and b ⟂ about)."""
    return math.atan2(float(np.cross(a, b) @ about), float(a @ b))


def dh_rows(axes: list[Axis], home: list[float], platform: tuple[np.ndarray, np.ndarray]):
    """D–H rows (θ, d, a, φ) for links 1..n+1 and (d_e, θ_e), constant parts at ``home``."""
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


def limb_table(name: str, axes: list[Axis], home: list[float], platform, limits):
    rows, end = dh_rows(axes, home, platform)
    table = DHTable(
        links=np.round(np.array(rows), 12),
        end=end,
        joint_types=tuple(a.kind for a in axes),
        joint_names=tuple(a.name for a in axes),
        limits=np.array(limits, dtype=float),
    )
    got = forward(table, np.array(home))
    err_p = np.linalg.norm(got.translation - platform[0])
    err_r = np.linalg.norm(got.rotation - platform[1])
    assert err_p < 1e-9 and err_r < 1e-9, (name, err_p, err_r)
    return table, home


def print_limb(name: str, table: DHTable, home: list[float], limits_user) -> None:
    def num(v: float, nd: int) -> str:
        r = round(float(v), nd)
        return repr(0.0 if r == 0 else r)

    print(f"# ---- {name}")
    print("home = [" + ", ".join(num(h, 5) for h in home) + "]")
    print("[limbs.dh]")
    print("joint_types = [" + ", ".join(f'"{t}"' for t in table.joint_types) + "]")
    print("joint_names = [" + ", ".join(f'"{t}"' for t in table.joint_names) + "]")
    print("links = [")
    for th, d, a, ph in table.links:
        print(f"  [{num(math.degrees(th), 6)}, {num(d, 6)}, {num(a, 6)}, {num(math.degrees(ph), 6)}],")
    print("]")
    print(f"end = [{num(table.end[0], 6)}, {num(math.degrees(table.end[1]), 6)}]")
    print("limits = [" + ", ".join(f"[{lo}, {hi}]" for lo, hi in limits_user) + "]")
    print()


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


# ---- machines --------------------------------------------------------------------------------


def ups(name: str, base: np.ndarray, plat: np.ndarray, u1: np.ndarray, s: list[np.ndarray]):
    """UPS leg from the base point to the platform point; U first axis ``u1`` (⟂ leg), S axes ``s``."""
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
    home = [0.0, 0.0, float(np.linalg.norm(plat - base)), 0.0, 0.0, 0.0]
    return axes, home


def _radial_tangential(angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal unit vectors at ``angle_deg`` about z: radial and tangential (counter-clockwise)."""
    a = math.radians(angle_deg)
    return np.array([math.cos(a), math.sin(a), 0.0]), np.array([-math.sin(a), math.cos(a), 0.0])


def tricept():
    rb, rp, h = 0.45, 0.18, 0.9  # base U radius, platform S radius, O' height at home
    platform = (np.array([0, 0, h]), np.eye(3))
    out = []
    for i, ang in enumerate((90.0, 210.0, 330.0)):
        r, t = _radial_tangential(ang)
        # S axes at home: radial, tangential, vertical (orthogonal, far from gimbal lock)
        axes, home = ups(f"leg{i + 1}", rb * r, rp * r + [0, 0, h], t, [r, t, np.array([0, 0, 1.0])])
        lim = [[-60, 60], [-60, 60], [0.6, 1.4], [-180, 180], [-180, 180], [-180, 180]]
        out.append((f"leg{i + 1}", axes, home, platform, lim))
    # central passive UP: U at O (x then y), slide along the platform's z
    axes = [
        Axis("centre_u1", "R", np.zeros(3), [1, 0, 0]),
        Axis("centre_u2", "R", np.zeros(3), [0, 1, 0]),
        Axis("centre_p3", "P", np.zeros(3), [0, 0, 1]),
    ]
    out.append(("centre", axes, [0.0, 0.0, h], platform, [[-60, 60], [-60, 60], [0.5, 1.3]]))
    return out


def sprint_z3(rb=0.3, rp=0.2, rod=0.4, zs=0.2):
    """Rail radius, platform S radius, rod length, slider height at home [m]."""
    h = zs + math.sqrt(rod**2 - (rb - rp) ** 2)  # O' height at home
    platform = (np.array([0, 0, h]), np.eye(3))
    out = []
    for i, ang in enumerate((90.0, 210.0, 330.0)):
        r, t = _radial_tangential(ang)
        c = rb * r + [0, 0, zs]  # R joint on the slider
        b = rp * r + [0, 0, h]  # S joint on the platform
        rod_dir = unit(b - c)
        n = f"leg{i + 1}"
        assert abs(rod_dir @ t) < 1e-12
        # S axes at home: tangential (parallel to the R), radial, vertical
        axes = [
            Axis(f"{n}_p1", "P", rb * r, [0, 0, 1]),
            Axis(f"{n}_r2", "R", c, t),
            Axis(f"{n}_s3", "R", b, t),
            Axis(f"{n}_s4", "R", b, r),
            Axis(f"{n}_s5", "R", b, [0, 0, 1]),
        ]
        lim = [[0.0, 0.5], [-90, 90], [-180, 180], [-180, 180], [-180, 180]]
        out.append((n, axes, [zs, 0.0, 0.0, 0.0, 0.0], platform, lim))
    return out


def exechon():
    b, c = 0.3, 0.45  # U centres at (0, ∓b, 0) on the common U axis (y); S centre at (-c, 0, 0)
    e, e2, h = 0.12, 0.18, 0.9  # platform R joints at (0, ∓e, 0), (-e2, 0, 0) in the platform frame
    platform = (np.array([0, 0, h]), np.eye(3))
    out = []
    for n, y in (("leg1", -1.0), ("leg3", 1.0)):
        base = np.array([0, y * b, 0])
        plat = np.array([0, y * e, h])
        leg = unit(plat - base)
        axes = [
            Axis(f"{n}_u1", "R", base, [0, 1, 0]),  # common U axis of the two UPR legs
            Axis(f"{n}_u2", "R", base, [1, 0, 0]),  # ⟂ the plane of the two legs
            Axis(f"{n}_p3", "P", base, leg),
            Axis(f"{n}_r4", "R", plat, [1, 0, 0]),  # platform R, parallel to u2
        ]
        lim = [[-60, 60], [-60, 60], [0.6, 1.4], [-90, 90]]
        out.append((n, axes, [0.0, 0.0, float(np.linalg.norm(plat - base)), 0.0], platform, lim))
    base = np.array([-c, 0, 0])
    plat = np.array([-e2, 0, h])
    leg = unit(plat - base)
    # S axes at home: vertical, along y, along x
    axes = [
        Axis("leg2_s1", "R", base, [0, 0, 1]),
        Axis("leg2_s2", "R", base, [0, 1, 0]),
        Axis("leg2_s3", "R", base, [1, 0, 0]),
        Axis("leg2_p4", "P", base, leg),
        Axis("leg2_r5", "R", plat, [0, 1, 0]),  # platform R, along the line of the UPR joints
    ]
    lim = [[-180, 180], [-180, 180], [-180, 180], [0.6, 1.4], [-90, 90]]
    home = [0.0, 0.0, 0.0, float(np.linalg.norm(plat - base)), 0.0]
    # limb order: leg1 (UPR), leg2 (SPR), leg3 (UPR)
    return [out[0], ("leg2", axes, home, platform, lim), out[1]]


MACHINES = {"tricept": tricept, "exechon": exechon, "sprint_z3": sprint_z3}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("machine", choices=sorted(MACHINES))
    args = ap.parse_args(argv)
    for name, axes, home, platform, lim in MACHINES[args.machine]():
        table, home = limb_table(name, axes, home, platform, lim)
        print_limb(name, table, home, lim)
    return 0


if __name__ == "__main__":
    sys.exit(main())
