"""Write (or check) a limb-folder robot as ONE closed-loop URDF tree with a sidecar.

The output is the "extended URDF" form read by ``pkmtol.closed_loop`` (docs/closed-loop.md): the
limbs' URDFs merged into one tree rooted at the common base link; limb 1 keeps the platform link
(the platform hangs on it); every other limb k+1 ends in a link ``closedloop<k>_B`` at its last
joint, and the platform carries the partner link ``closedloop<k>_A`` placed where that joint sits
when the loop is closed (origin = the inverse of the limb's platform attachment). The sidecar
``robot.yaml`` lists the loops and the motors in example-parallel-robots' format; the
``mechanism.toml`` holds pkmtol's own keys (reference point, task space, design) and the
``[closed_loop]`` table with the home configuration.

Usage:
    python scripts/limbs_to_closed_loop.py ROBOT OUT          # write robot.urdf, robot.yaml, mechanism.toml
    python scripts/limbs_to_closed_loop.py ROBOT OUT --check  # exit 1 if OUT differs
"""

from __future__ import annotations

import argparse
import sys
import tomllib
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

from pkmtol.model.loader import load_mechanism


def urdf_origin(joint: ET.Element) -> pin.SE3:
    o = joint.find("origin")
    xyz = np.zeros(3) if o is None else np.array([float(x) for x in o.get("xyz", "0 0 0").split()])
    rpy = np.zeros(3) if o is None else np.array([float(x) for x in o.get("rpy", "0 0 0").split()])
    return pin.SE3(pin.rpy.rpyToMatrix(rpy), xyz)


def _fmt(v: np.ndarray) -> str:
    return " ".join("0" if abs(x) < 1e-12 else f"{x:.12g}" for x in v)


def _fixed(name: str, parent: str, child: str, xyz: str = "0 0 0", rpy: str = "0 0 0") -> ET.Element:
    j = ET.Element("joint", name=name, type="fixed")
    ET.SubElement(j, "origin", xyz=xyz, rpy=rpy)
    ET.SubElement(j, "parent", link=parent)
    ET.SubElement(j, "child", link=child)
    return j


def tree_urdf(
    folder: Path,
) -> tuple[str, list[tuple[str, str]], list[str], list[str], dict[str, float]]:
    """The merged tree, the loops and their types, the motors and the home joint values of a robot.

    A limb's internal loops (``[[limbs.loops]]``) become loops of the tree between the same frames.
    """
    mech = load_mechanism(folder)
    doc = tomllib.loads((folder / "mechanism.toml").read_text(encoding="utf-8"))
    platform = doc.get("platform_link", "platform")
    robot = ET.Element("robot", name=f"{mech.name}_closed")
    robot.append(
        ET.Comment(f" generated from {folder.name}/ by scripts/limbs_to_closed_loop.py; do not edit ")
    )
    links: list[ET.Element] = []
    joints: list[ET.Element] = []
    seen: set[str] = set()
    loops, motors, home = [], [], {}
    inner: list[tuple[tuple[str, str], str]] = []
    for i, limb in enumerate(mech.limbs):
        assert limb.urdf_path is not None
        src = ET.parse(limb.urdf_path).getroot()
        attach = next(j for j in src.findall("joint") if j.find("child").get("link") == platform)  # type: ignore[union-attr]
        for link in src.findall("link"):
            name = link.get("name")
            if name in seen or (i > 0 and name == platform):
                continue
            seen.add(str(name))
            links.append(link)
        for joint in src.findall("joint"):
            if joint is not attach or i == 0:
                joints.append(joint)
        if i > 0:
            a, b = f"closedloop{i}_A", f"closedloop{i}_B"
            last = attach.find("parent").get("link")  # type: ignore[union-attr]
            links += [ET.Element("link", name=b), ET.Element("link", name=a)]
            # the closure sits at the limb's last joint, axes parallel to the platform's: B keeps
            # the attachment's rotation, A is a pure translation on the platform
            origin = attach.find("origin")
            rpy = "0 0 0" if origin is None else origin.get("rpy", "0 0 0")
            placement = urdf_origin(attach)
            joints.append(_fixed(f"{b}_joint", str(last), b, rpy=rpy))
            joints.append(
                _fixed(f"{a}_joint", platform, a, xyz=_fmt(-placement.rotation.T @ placement.translation))
            )
            loops.append((a, b))
        motors += [limb.joint_names[k] for k in limb.actuated]
        home.update({n: float(v) for n, v in zip(limb.joint_names, limb.home, strict=True) if v != 0.0})
        # a limb's internal loops stay loops of the tree, listed after the limbs' closures
        inner += [(lp.frame_names, lp.kind) for lp in limb.loops]
    types = ["6d"] * len(loops) + [kind for _, kind in inner]
    loops += [pair for pair, _ in inner]
    for el in links + joints:
        robot.append(el)
    ET.indent(robot, space="  ")
    text = '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
    return text, loops, types, motors, home


def toml_value(v: object) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(v)


def generate(folder: Path) -> dict[str, str]:
    """File name → text of the closed-loop form of the robot in ``folder``."""
    urdf, loops, types, motors, home = tree_urdf(folder)
    mech = load_mechanism(folder)
    doc = tomllib.loads((folder / "mechanism.toml").read_text(encoding="utf-8"))
    yaml = f"closed_loop: {[list(p) for p in loops]}\ntype: {types}\nname_mot: {motors}\n"
    lines = [
        f"# {mech.name} written as one closed-loop URDF tree (robot.urdf) with its sidecar (robot.yaml);",
        f"# generated from {folder.name}/ by scripts/limbs_to_closed_loop.py; do not edit.",
        f"name = {toml_value(mech.name + '_closed')}",
        f"description = {toml_value(doc.get('description', ''))}",
        "",
        "[closed_loop]",
        'urdf = "robot.urdf"',
        'sidecar = "robot.yaml"',
        f"limbs = {toml_value([lb.name for lb in mech.limbs])}",
        "",
        "[closed_loop.home]  # joint values [rad or m] where every loop closes; others are 0",
    ]
    lines += [f"{name} = {value!r}" for name, value in home.items()]
    for table in ("reference_point", "task", "task_space", "design", "cost"):
        if table in doc:
            lines += ["", f"[{table}]"]
            lines += [f"{k} = {toml_value(v)}" for k, v in doc[table].items() if not isinstance(v, dict)]
    return {"robot.urdf": urdf, "robot.yaml": yaml, "mechanism.toml": "\n".join(lines) + "\n"}


def write_or_check(
    argv: list[str] | None,
    description: str | None,
    generate_files: Callable[[Path], dict[str, str]],
    written: str,
    script: str,
) -> int:
    """The command line of a limb-folder converter: write ``generate_files(robot)`` to OUT, or ``--check`` it.

    ``written`` names the files for the help text; ``script`` is the command that regenerates them.
    """
    ap = argparse.ArgumentParser(
        description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("robot", type=Path, help="limb-folder robot (mechanism.toml with [[limbs]])")
    ap.add_argument("out", type=Path, help=f"folder to write {written} to")
    ap.add_argument("--check", action="store_true", help="compare with OUT instead of writing")
    args = ap.parse_args(argv)
    files = generate_files(args.robot)
    if args.check:
        stale = [
            n
            for n, t in files.items()
            if not (args.out / n).is_file() or (args.out / n).read_text(encoding="utf-8") != t
        ]
        if stale:
            print(f"out of date in {args.out}: {', '.join(stale)}", file=sys.stderr)
            print(f"regenerate with: python scripts/{script} {args.robot} {args.out}", file=sys.stderr)
            return 1
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (args.out / name).write_text(text, encoding="utf-8")
        print(f"wrote {args.out / name}")
    return 0


def main(argv: list[str] | None = None) -> int:
    return write_or_check(
        argv, __doc__, generate, "robot.urdf, robot.yaml and mechanism.toml", "limbs_to_closed_loop.py"
    )


if __name__ == "__main__":
    sys.exit(main())
