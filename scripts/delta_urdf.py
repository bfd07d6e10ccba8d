"""Generate (or check) the Delta robot of robots/delta: three arm URDFs and mechanism.toml.

Usage:
    python scripts/delta_urdf.py                 # write robots/delta/arm{1,2,3}.urdf and mechanism.toml
    python scripts/delta_urdf.py --check         # exit 1 if a file differs from what this script writes
    python scripts/delta_urdf.py --out DIR       # write into another folder
    python scripts/delta_urdf.py --loop 6d --out DIR   # the variant with 6D loops (rod 2 ends in a 3R ball)

The geometry (docs/robots.md, "Delta"): three rotary-actuated arms at 0°, 120° and 240° about the
vertical axis z of the base frame K (z up). Arm i's motor axis is horizontal and tangential, at
``BASE_RADIUS`` from the axis; its upper arm has length ``UPPER_ARM``; the forearm is a
parallelogram of two rods of length ``FOREARM``, ``WIDTH`` apart along the elbow bar, ending on the
platform at ``PLATFORM_RADIUS`` from its centre. The platform translates; the tool point P sits
``TOOL_OFFSET`` below its centre.

Each arm is one limb, a tree closed by an internal loop:

* ``arm<i>_mot`` (actuated): the motor, axis along the elbow bar; q = angle of the upper arm below
  the horizontal [rad];
* rod 1: a universal joint at the elbow (``_rod1_u1`` about the elbow bar, ``_rod1_u2`` about the
  axis perpendicular to the bar and the rod), the rod, a ball of three orthogonal revolutes at the
  platform (``_rod1_s1``, ``_s2``, ``_s3``), then the platform (fixed joint ``arm<i>_platform_attach``);
* rod 2: the same universal joint, the rod, ending in ``arm<i>_rod2_end``, which must coincide with
  the platform's socket ``arm<i>_rod2_socket``: a ``3d`` (point) loop — the ball joint at the
  platform. No rod has an idle spin (the universal joint holds it).

The joint frames are written at the home pose (platform centre at ``HOME_Z``), so that every passive
joint is 0 there: a rod frame has x along the elbow bar and z along the rod.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
FOLDER = ROOT / "robots" / "delta"

#: Dimensions [m] (docs/robots.md): an industrial pick-and-place Delta of ~1.1 m reach diameter.
BASE_RADIUS = 0.2
PLATFORM_RADIUS = 0.05
UPPER_ARM = 0.35
FOREARM = 0.8
WIDTH = 0.1
TOOL_OFFSET = 0.1
#: Height of the platform centre at home [m] (frame K, z up: below the base).
HOME_Z = -0.85
AZIMUTHS_DEG = (0.0, 120.0, 240.0)
#: Joint limits [rad]: motor, universal joints, ball.
MOTOR_LIMITS = (-0.7, 1.6)
U_LIMITS = (-1.4, 1.4)
S_LIMITS = (-1.4, 1.4)


def home_angle(home_z: float = HOME_Z) -> float:
    """The motor angle θ0 [rad] that puts the platform centre at ``(0, 0, home_z)``, elbows outward."""
    a = BASE_RADIUS - PLATFORM_RADIUS
    # (a + L cos θ)² + (z + L sin θ)² = l²  ⇔  A cos θ + B sin θ = C
    big_a, big_b = 2 * a * UPPER_ARM, 2 * home_z * UPPER_ARM
    c = FOREARM**2 - a**2 - home_z**2 - UPPER_ARM**2
    rho, phi = np.hypot(big_a, big_b), np.arctan2(big_b, big_a)
    # θ = φ ± acos(C/ρ); the elbow-out branch is the larger angle of the upper arm below horizontal
    up, down = phi + np.arccos(c / rho), phi - np.arccos(c / rho)
    return float(up if up < np.pi / 2 else down)


def _num(v: float) -> str:
    s = repr(round(float(v), 15))
    return "0" if s in ("0.0", "-0.0") else s


def _fmt(v: np.ndarray) -> str:
    return " ".join(_num(x) for x in v)


def _origin(parent: ET.Element, placement: pin.SE3) -> None:
    ET.SubElement(
        parent, "origin", xyz=_fmt(placement.translation), rpy=_fmt(pin.rpy.matrixToRpy(placement.rotation))
    )


def _visual(link: ET.Element, shape: str, size: dict[str, str], at: pin.SE3, rgba: str) -> None:
    vis = ET.SubElement(link, "visual")
    _origin(vis, at)
    ET.SubElement(ET.SubElement(vis, "geometry"), shape, **size)
    ET.SubElement(ET.SubElement(vis, "material", name=rgba.replace(" ", "_")), "color", rgba=rgba)


def arm_urdf(i: int, theta0: float, loop: str = "3d") -> str:
    """The URDF of arm ``i`` (1-based), written at the home pose (motor at ``theta0``)."""
    phi = np.radians(AZIMUTHS_DEG[i - 1])
    u = np.array([np.cos(phi), np.sin(phi), 0.0])
    t = np.array([-np.sin(phi), np.cos(phi), 0.0])
    r_phi = pin.utils.rotate("z", phi)
    r_upper = r_phi @ pin.utils.rotate("y", theta0)  # upper-arm frame at home (x along the arm)
    elbow = BASE_RADIUS * u + UPPER_ARM * (r_upper @ np.array([1.0, 0.0, 0.0]))
    centre = np.array([0.0, 0.0, HOME_Z])
    d = centre + PLATFORM_RADIUS * u - elbow
    assert abs(np.linalg.norm(d) - FOREARM) < 1e-12, "the home angle does not close the forearm"
    d = d / FOREARM
    r_rod = np.column_stack([t, np.cross(d, t), d])  # rod frame: x along the bar, z along the rod
    p = f"arm{i}"
    robot = ET.Element("robot", name=p)
    grey, blue, orange = "0.6 0.6 0.6 0.8", "0.2 0.4 0.8 1", "0.8 0.5 0.1 1"
    links = {"base": None}

    def link(name: str) -> ET.Element:
        el = ET.SubElement(robot, "link", name=name)
        links[name] = el
        return el

    def joint(name: str, kind: str, parent: str, child: str, at: pin.SE3, axis: str = "", lim=None) -> None:
        j = ET.SubElement(robot, "joint", name=name, type=kind)
        _origin(j, at)
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=child)
        if kind == "revolute":
            ET.SubElement(j, "axis", xyz=axis)
            ET.SubElement(j, "limit", lower=_num(lim[0]), upper=_num(lim[1]), effort="1000", velocity="1")

    base = link("base")
    if i == 1:
        _visual(
            base, "cylinder", {"radius": _num(BASE_RADIUS + 0.05), "length": "0.02"}, pin.SE3.Identity(), grey
        )
    upper = link(f"{p}_upper")
    arm_vis = pin.SE3(pin.utils.rotate("y", np.pi / 2), np.array([UPPER_ARM / 2, 0.0, 0.0]))
    _visual(upper, "cylinder", {"radius": "0.015", "length": _num(UPPER_ARM)}, arm_vis, blue)
    _visual(
        upper,
        "cylinder",
        {"radius": "0.01", "length": _num(WIDTH)},
        pin.SE3(pin.utils.rotate("x", np.pi / 2), np.array([UPPER_ARM, 0.0, 0.0])),
        blue,
    )
    joint(
        f"{p}_mot",
        "revolute",
        "base",
        upper.get("name"),
        pin.SE3(r_phi, BASE_RADIUS * u),
        "0 1 0",
        MOTOR_LIMITS,
    )
    rod_vis = pin.SE3(np.eye(3), np.array([0.0, 0.0, FOREARM / 2]))
    for rod, side in ((1, 1.0), (2, -1.0)):
        q = f"{p}_rod{rod}"
        cross = link(f"{q}_cross")
        bar = link(q)
        _visual(bar, "cylinder", {"radius": "0.008", "length": _num(FOREARM)}, rod_vis, orange)
        # both universal-joint axes at the elbow end of the rod, in the rod frame at home
        at = pin.SE3(r_upper.T @ r_rod, np.array([UPPER_ARM, side * WIDTH / 2, 0.0]))
        joint(f"{q}_u1", "revolute", upper.get("name"), cross.get("name"), at, "1 0 0", U_LIMITS)
        joint(f"{q}_u2", "revolute", cross.get("name"), q, pin.SE3.Identity(), "0 1 0", U_LIMITS)
        end = pin.SE3(np.eye(3), np.array([0.0, 0.0, FOREARM]))
        if rod == 1 or loop == "6d":
            parent = q
            for k, axis in enumerate(("1 0 0", "0 1 0", "0 0 1"), 1):
                child = f"{q}_s{k}"
                link(child)
                joint(child, "revolute", parent, child, end if k == 1 else pin.SE3.Identity(), axis, S_LIMITS)
                parent = child
            if rod == 1:
                plat = link("platform")
                _visual(
                    plat,
                    "cylinder",
                    {"radius": _num(PLATFORM_RADIUS + 0.02), "length": "0.02"},
                    pin.SE3.Identity(),
                    grey,
                )
                _visual(
                    plat,
                    "sphere",
                    {"radius": "0.012"},
                    pin.SE3(np.eye(3), np.array([0, 0, -TOOL_OFFSET])),
                    grey,
                )
                s_point = elbow + side * WIDTH / 2 * t + FOREARM * d
                joint(
                    f"{p}_platform_attach",
                    "fixed",
                    parent,
                    "platform",
                    pin.SE3(r_rod.T, r_rod.T @ (centre - s_point)),
                )
            else:
                link(f"{q}_end")
                joint(f"{q}_end_fix", "fixed", parent, f"{q}_end", pin.SE3(r_rod.T, np.zeros(3)))
        else:
            link(f"{q}_end")
            joint(f"{q}_end_fix", "fixed", q, f"{q}_end", end)
    link(f"{p}_rod2_socket")
    joint(
        f"{p}_rod2_socket_fix",
        "fixed",
        "platform",
        f"{p}_rod2_socket",
        pin.SE3(np.eye(3), PLATFORM_RADIUS * u - WIDTH / 2 * t),
    )
    ET.indent(robot, "  ")
    return (
        '<?xml version="1.0"?>\n'
        "<!-- generated by scripts/delta_urdf.py; do not edit -->\n"
        + ET.tostring(robot, encoding="unicode")
        + "\n"
    )


MECHANISM = """# Delta robot: three rotary-actuated arms, parallelogram forearms (docs/robots.md, "Delta").
# Generated by scripts/delta_urdf.py (dimensions there); do not edit.
# Each arm is one limb whose forearm is closed by an internal loop: rod 1 carries the platform
# (universal joint at the elbow, ball of 3 revolutes at the platform), rod 2 ends in a point that
# must meet its socket on the platform (a '{loop}' loop).
name = "delta"
description = "Delta pick-and-place robot: 3 rotary arms, parallelogram forearms, tool point P"
platform_link = "platform"

[reference_point]
# P: the tool point, {tool} m below the platform centre O'
position_m = [0.0, 0.0, {tool_neg}]

[task]
kind = "position"

[task_space]
kind = "cylinder"
radius_m = {radius}
z_m = [{z0}, {z1}]
layers = 3
rings = [8, 16, 24]        # 3 layers x (1 + 8 + 16 + 24) = 147 points

[design]
target = "0.05 mm"
beta = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
design_beta = 2.0
{limbs}
[calibration]
# a laser tracker on the tool point (10 µm noise), 40 D-optimal poses. The controller identifies
# every non-absorbed parameter: a rod's length is uncompensatable on its own (it tilts the
# platform), but the mean length of a parallelogram's two rods moves P like a compensatable error,
# and a controller that knows only the compensatable ones cannot remove it (docs/robots.md)
controller = "full"
noise = "0.01 mm"
"""

LIMB = """
[[limbs]]
name = "arm{i}"
urdf = "arm{i}.urdf"
actuated = ["arm{i}_mot"]
home = [{home}]

[[limbs.loops]]
name = "rod2"
frames = ["arm{i}_rod2_socket", "arm{i}_rod2_end"]
type = "{loop}"
"""

#: Task space of P [m]: a cylinder below the base.
TASK_RADIUS = 0.4
TASK_Z = (-1.0, -0.8)


def generate(out: Path = FOLDER, loop: str = "3d") -> dict[Path, str]:
    """Text of every generated file of the robot folder ``out``."""
    theta0 = home_angle()
    files = {out / f"arm{i}.urdf": arm_urdf(i, theta0, loop) for i in (1, 2, 3)}
    n_passive = 7 if loop == "3d" else 10
    home = ", ".join([_num(round(theta0, 12))] + ["0.0"] * n_passive)
    limbs = "".join(LIMB.format(i=i, home=home, loop=loop) for i in (1, 2, 3))
    files[out / "mechanism.toml"] = MECHANISM.format(
        loop=loop,
        tool=_num(TOOL_OFFSET),
        tool_neg=_num(-TOOL_OFFSET),
        radius=_num(TASK_RADIUS),
        z0=_num(TASK_Z[0]),
        z1=_num(TASK_Z[1]),
        limbs=limbs,
    )
    return files


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare instead of writing")
    ap.add_argument("--out", type=Path, default=FOLDER, help="robot folder (default robots/delta)")
    ap.add_argument("--loop", choices=("3d", "6d"), default="3d", help="rod 2's loop at the platform")
    args = ap.parse_args(argv)
    stale = []
    args.out.mkdir(parents=True, exist_ok=True)
    for path, text in generate(args.out, args.loop).items():
        if args.check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(path)
        else:
            tmp = path.with_suffix(path.suffix + ".tmp")
            tmp.write_text(text, encoding="utf-8")
            tmp.replace(path)
            print(f"wrote {path}")
    if stale:
        print("out of date with scripts/delta_urdf.py: " + ", ".join(map(str, stale)), file=sys.stderr)
        print("regenerate with: python scripts/delta_urdf.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
