"""The catalogue of bad inputs: each with the pkmtol error class it must raise and the culprit it must name.

``tests/test_errors_doc.py`` runs every case and asserts both; ``scripts/make_errors_doc.py`` writes
``docs/errors.md`` from the same cases and the messages they get (a test keeps the page in sync).

A case's ``run(tmp)`` does the bad thing, usually on a fresh copy of the seed robot in
``tmp / "robot"`` (:func:`robot`): an edit of ``mechanism.toml`` or a URDF, a Python API call, or a
command line through :func:`pkmtol.cli.run` (which lets the error propagate instead of printing it).
"""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol import (
    ClosedChain,
    DesignOptions,
    DrawingSettings,
    Mechanism,
    TaskSpace,
    TreeChain,
    allocate,
    fosm_tolerances,
    load_closed_loop,
    load_mechanism,
    load_mjcf,
    parameter_set,
    perturbed_limb_models,
    sign_off,
    sweep,
    tree_from_mechanism,
    verify,
    write_outputs,
)
from pkmtol import exceptions as E
from pkmtol.calibration.fit_check import PoorFitError
from pkmtol.cli import run as cli_run
from pkmtol.design.budget import check_memory
from pkmtol.kinematics import acceleration
from pkmtol.present.run_folder import RunFolder
from pkmtol.units import parse_length

REPO = Path(__file__).resolve().parents[1]
SEED = REPO / "robots" / "r2rps_ups"
HYBRID = REPO / "robots" / "r2rps_ups_wrist"
SMALL = ["--samples", "300", "--exact-samples", "0", "--verification-poses", "30", "--no-progress"]
TASK = TaskSpace(kind="cylinder", radius_m=0.6, z_range_m=(0.9, 1.1), layers=3, rings=(8, 16, 24))
HOMES = [[0.32175, 0, 0.79057, 0, 0, -0.32175], [0, 0.2606, 0.77621, 0, 0, -0.2606], [0, -0.2606, 0.77621, 0, 0, 0.2606], [0, 0, 0.75]]  # fmt: skip


@dataclass(frozen=True)
class Case:
    """One bad input.

    Attributes:
        section: Heading of docs/errors.md it is listed under.
        what: The bad input, in words.
        run: Does it; ``tmp`` is a fresh folder.
        error: The exception (or warning) class it must raise.
        needles: Substrings the message must contain (the culprit first).
        attrs: Attributes the exception must carry, with their values.
    """

    section: str
    what: str
    run: Callable[[Path], Any]
    error: type[BaseException]
    needles: tuple[str, ...]
    attrs: dict[str, Any] = field(default_factory=dict)


def robot(tmp: Path) -> Path:
    """A fresh copy of the seed robot in ``tmp / "robot"``."""
    folder = tmp / "robot"
    if not folder.exists():
        shutil.copytree(SEED, folder)
    return folder


def edit(file: str, old: str | bytes, new: str | bytes) -> Callable[[Path], Any]:
    """Replace ``old`` (exactly once) by ``new`` in ``file`` of the seed robot copy, then load it."""

    def go(tmp: Path) -> Any:
        folder = robot(tmp)
        path = folder / file
        data = path.read_bytes()
        o = old.encode() if isinstance(old, str) else old
        n = new.encode() if isinstance(new, str) else new
        assert data.count(o) == 1, f"{old!r} must occur once in {file}"
        path.write_bytes(data.replace(o, n))
        return load_mechanism(folder)

    return go


def toml(old: str, new: str) -> Callable[[Path], Any]:
    """An edit of the seed robot's mechanism.toml."""
    return edit("mechanism.toml", old, new)


def urdf(old: str, new: str, file: str = "limb4.urdf") -> Callable[[Path], Any]:
    """An edit of a seed robot URDF (default limb 4's)."""
    return edit(file, old, new)


def cli(*argv: str) -> Callable[[Path], Any]:
    """A command line; ``{robot}`` and ``{tmp}`` in an argument become the seed copy and the folder."""

    def go(tmp: Path) -> Any:
        folder = robot(tmp)
        return cli_run([a.format(robot=folder, tmp=tmp, seed=SEED) for a in argv])

    return go


def models() -> list[pin.Model]:
    return [pin.buildModelFromUrdf(str(SEED / f"limb{i}.urdf")) for i in (1, 2, 3, 4)]


def from_models(**changes: Any) -> Callable[[Path], Any]:
    """``Mechanism.from_models`` on the seed robot's limbs with ``changes`` to its arguments."""

    def go(tmp: Path) -> Any:
        kw: dict[str, Any] = dict(
            name="m",
            models=models(),
            actuated=[["limb1_p3"], ["limb2_p3"], ["limb3_p3"], []],
            platform_frame="platform",
            reference_point_m=[0.0, 0.0, 0.3],
            task_space=TASK,
            homes=HOMES,
        )
        kw.update({k: (v() if callable(v) else v) for k, v in changes.items()})
        return Mechanism.from_models(**kw)

    return go


def seed_mech() -> Mechanism:
    return load_mechanism(SEED)


def contract_without_machines(tmp: Path) -> Any:
    from pkmtol.design.contract import check_contract

    small = DesignOptions(samples=300, verification_poses=30, exact_samples=0, claim_poses=10)
    return check_contract(allocate(seed_mech(), small), machines=0)


def _forward_below_limit(tmp: Path) -> Any:
    """Limb 1's slide commanded 10 mm below its lower limit (0.4 m) from the task-space centre."""
    mech = seed_mech()
    chain = ClosedChain(mech)
    pose = chain.inverse(mech.task_space.grid()[0])
    u = pose.q_all[chain.actuated_idx].copy()
    u[0] = 0.39
    return chain.forward(u, pose.q_all)


def _tree_forward_below_limit(tmp: Path) -> Any:
    """The seed robot as one loop tree, limb 1's slide commanded 10 mm below its lower limit (0.4 m)."""
    chain = TreeChain(tree_from_mechanism(seed_mech())[0])
    home = chain.home()
    u = home[chain.batch.actuated_idx].copy()
    u[0] = 0.39
    return chain.forward(u, home)


def _mjcf_geom_nan(tmp: Path) -> Any:
    """The MJCF seed robot with its first sphere's size ``nan``."""
    folder = tmp / "mjcf"
    shutil.copytree(REPO / "tests" / "data" / "r2rps_ups_mjcf", folder)
    xml = folder / "robot.xml"
    xml.write_text(xml.read_text(encoding="utf-8").replace('size="0.03"', 'size="nan"', 1), encoding="utf-8")
    return load_mechanism(folder)


def _verify_one(**changes: Any) -> Any:
    """``verify`` of one parameter at one pose, with ``changes`` to its arguments."""
    mech = seed_mech()
    pset = parameter_set(mech)
    kw: dict[str, Any] = dict(
        mechanism=mech, pset=pset, sweep_random=sweep(mech, pset, mech.task_space.grid()[:1]),
        columns=np.array([0]), sigma=np.array([1e-5]), target_m=5e-5, distribution="gaussian",
        samples=10, exact_samples=0, rng=np.random.default_rng(0),
    )  # fmt: skip
    kw.update(changes)
    return verify(**kw)


def locked_out(tmp: Path) -> Any:
    out = tmp / "busy"
    with RunFolder(out):
        return cli_run(["allocate", str(SEED), "--out", str(out), *SMALL])


def new_in_taken(tmp: Path) -> Any:
    (tmp / "taken").mkdir()
    (tmp / "taken" / "notes.txt").write_text("mine")
    return cli_run(["new", "exechon", "--out", str(tmp / "taken")])


def ballbar_reading_in_degrees(tmp: Path) -> Any:
    folder = robot(tmp)
    data = tmp / "ballbar.csv"
    data.write_text(
        "pose,limb1.limb1_p3 [mm],limb2.limb2_p3 [mm],limb3.limb3_p3 [mm],station,d [deg]\n0,900,900,900,0,150\n"
    )
    return cli_run(["calibrate", str(folder), "--instrument", "ballbar", "--measurements", str(data)])


def sidecar_not_utf8(tmp: Path) -> Any:
    folder = tmp / "closed"
    shutil.copytree(REPO / "tests" / "data" / "r2rps_ups_closed", folder)
    side = folder / "robot.yaml"
    side.write_bytes(side.read_bytes() + b"# \xff\n")
    return load_mechanism(folder)


def _first_axis(xyz: str, extra: str = "") -> Callable[[Path], Any]:
    """Limb 4's first joint axis (``limb4_u1``) replaced by ``xyz`` (and ``extra`` XML after it)."""

    def go(tmp: Path) -> Any:
        folder = robot(tmp)
        path = folder / "limb4.urdf"
        text = path.read_text(encoding="utf-8")
        head, sep, tail = text.partition('<axis xyz="0 0 1" />')
        path.write_text(head + f'<axis xyz="{xyz}" />{extra}' + tail, encoding="utf-8")
        return load_mechanism(folder)

    return go


def _sdf_root(tmp: Path) -> Any:
    folder = robot(tmp)
    path = folder / "limb4.urdf"
    text = path.read_text(encoding="utf-8").replace("<robot ", "<sdf ").replace("</robot>", "</sdf>")
    path.write_text(text, encoding="utf-8")
    return load_mechanism(folder)


def _one_limb(tmp: Path) -> Any:
    folder = robot(tmp)
    path = folder / "mechanism.toml"
    text = path.read_text(encoding="utf-8")
    path.write_text(text[: text.index("# ---- limb 2")], encoding="utf-8")
    return load_mechanism(folder)


def _missing_mesh(tmp: Path) -> Any:
    import warnings

    folder = robot(tmp)
    path = folder / "limb4.urdf"
    text = path.read_text(encoding="utf-8")
    path.write_text(
        text.replace('<sphere radius="0.03" />', '<mesh filename="meshes/nope.stl" />', 1), encoding="utf-8"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", E.MissingMeshWarning)
        return load_mechanism(folder)


def _home_of(run: Callable[[Path], Any]) -> Callable[[Path], Any]:
    """The mechanism ``run`` loads, then its home pose solved (as every command but ``check`` does)."""

    def go(tmp: Path) -> Any:
        return ClosedChain(run(tmp)).home()

    return go


def _warned(category: type[Warning], run: Callable[[Path], Any]) -> Callable[[Path], Any]:
    """``run`` with ``category`` warnings raised as errors (so the catalogue can catch the first)."""

    def go(tmp: Path) -> Any:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("error", category)
            return run(tmp)

    return go


def jit_switch_misspelt(tmp: Path) -> Any:
    """The compiled kernels' switch set to a value that is neither on nor off (read on first solve)."""
    before = os.environ.get(acceleration.ENVIRONMENT)
    os.environ[acceleration.ENVIRONMENT] = "maybe"
    try:
        return acceleration.kernels.__wrapped__()  # the switch as a new process reads it
    finally:
        if before is None:
            del os.environ[acceleration.ENVIRONMENT]
        else:
            os.environ[acceleration.ENVIRONMENT] = before


L4_LAST = "  [0.0, 0.0, 0.0, 0.0],\n]\nend = [0.0, 90.0]\nlimits = [[-90.0, 90.0], [-90.0, 90.0], [0.3, 1.6]]"
L4_U1 = '<joint name="limb4_u1" type="revolute">'
#: Limb 4's first link and the start of its visual (a sphere).
L4_L1_VISUAL = '<link name="limb4_l1">\n    <visual>\n      <geometry>\n        <sphere radius="0.03" />'
L4_U1_LIMIT = '<child link="limb4_l1" />\n    <axis xyz="0 0 1" />\n    <limit lower="-1.5707963267948966" upper="1.5707963267948966"'
MF, UE, IA, UK = E.MechanismFormatError, E.URDFError, E.InvalidArgumentError, E.UnknownKeyError


def _epr_with_constraint(kind: str) -> Callable[[Path], Any]:
    """robots/delta_epr's tree with one urdfdom ``<constraint>`` of type ``kind`` and no sidecar."""

    def run(tmp: Path) -> Any:
        from pkmtol.model.tree_inputs import tree_from_urdf

        text = (REPO / "robots" / "delta_epr" / "robot.urdf").read_text(encoding="utf-8")
        extra = (
            f'  <constraint name="rod2_cut" type="{kind}"><parent link="arm1_rod2_socket"/>'
            '<child link="arm1_rod2_end"/></constraint>\n</robot>'
        )
        (tmp / "robot.urdf").write_text(text.replace("</robot>", extra), encoding="utf-8")
        return tree_from_urdf(tmp / "robot.urdf", task_frame="platform", actuated=["arm1_mot"])

    return run


def _tree_task_frame_missing(tmp: Path) -> Any:
    from pkmtol.model.tree_inputs import tree_from_urdf

    for name in ("robot.urdf", "robot.yaml"):
        shutil.copy(REPO / "robots" / "delta_epr" / name, tmp / name)
    return tree_from_urdf(tmp / "robot.urdf", task_frame="tcp")


def _tree_unknown_constraint(tmp: Path) -> Any:
    from pkmtol.model.tree_inputs import tree_from_constraint_models

    cm = seed_mech().constraint_models()
    return tree_from_constraint_models(cm.model, [pin.SE3.Identity()], ["limb1_p3"], "platform")


def _tree_loop_on_one_body(tmp: Path) -> Any:
    from pkmtol.model.limb import LimbLoop
    from pkmtol.model.loop_tree import LoopTree, PointTask

    cm = seed_mech().constraint_models()
    f = cm.platform_frame
    loop = LimbLoop("same_body", f, f, "6d", ("platform", "platform"))
    return LoopTree("seed", cm.model, (loop,), (2,), f, PointTask(np.zeros(3)))


CASES: list[Case] = [
    # ---- the robot folder and mechanism.toml as a file
    Case("Files", "a folder that does not exist", lambda t: load_mechanism(t / "nope"), MF, ("is not a folder",)),
    Case("Files", "a folder without mechanism.toml", lambda t: load_mechanism(t), MF, ("mechanism.toml", "file not found")),
    Case("Files", "`load_mechanism(None)`", lambda t: load_mechanism(None), IA, ("folder = None",), {"argument": "folder"}),  # type: ignore[arg-type]
    Case("Files", "mechanism.toml not UTF-8 (a byte 0xff)", edit("mechanism.toml", b'name = "r2rps_ups"', b'name = "r2rps_\xff"'), MF, ("not UTF-8", "0xff")),
    Case("Files", "mechanism.toml not valid TOML", toml('name = "r2rps_ups"', 'name = "r2rps_ups'), MF, ("not valid TOML",)),
    Case("Files", "a limb URDF not UTF-8", edit("limb2.urdf", b"limb2_r1", b"limb2_\xff1"), UE, ("limb 'limb2'", "not UTF-8"), {"limb": "limb2"}),
    Case("Files", "a sidecar (closed-loop import) not UTF-8", sidecar_not_utf8, MF, ("robot.yaml", "not UTF-8")),
    Case("Files", "a limb's URDF file missing", toml('urdf = "limb2.urdf"', 'urdf = "limb9.urdf"'), UE, ("limb 'limb2'", "limb9.urdf", "file not found"), {"limb": "limb2"}),
    # ---- keys
    Case("TOML keys", "a misspelt key: `targte = \"1 um\"`", toml('target = "0.05 mm"', 'targte = "1 um"'), UK, ("design.targte", "did you mean 'target'"), {"key": "design.targte", "suggestion": "target"}),
    Case("TOML keys", "a misspelt key in a limb: `actaated`", toml('actuated = []', 'actaated = []'), UK, ("limbs[3].actaated", "did you mean 'actuated'"), {"key": "limbs[3].actaated"}),
    Case("TOML keys", "a misspelt table: `[desing]`", toml("[design]", "[desing]"), UK, ("desing", "did you mean 'design'"), {"key": "desing"}),
    Case("TOML keys", "a key in the wrong table (`radius_m` under `[design]`)", toml("design_beta = 2.0", "design_beta = 2.0\nradius_m = 0.6"), UK, ("design.radius_m",), {"key": "design.radius_m"}),
    Case("TOML keys", "an unknown field of a cost table", toml("[design]", "[cost.length]\nC = 1.0\n\n[design]"), UK, ("cost.length.C",), {"key": "cost.length.C"}),
    Case("TOML keys", "a cost field that is not a number", toml("[design]", '[cost.angle]\nB = "cheap"\n\n[design]'), MF, ("cost.angle.B", "expected float or int")),
    Case("TOML keys", "a required key missing (`name`)", toml('name = "r2rps_ups"\n', ""), MF, ("'name'", "missing"), {"key": "name"}),
    Case("TOML keys", "an empty mechanism name", toml('name = "r2rps_ups"', 'name = ""'), MF, ("'name'", "must not be empty"), {"key": "name"}),
    Case("TOML keys", "both `[[limbs]]` and `[closed_loop]`", toml("[design]", '[closed_loop]\nurdf = "robot.urdf"\n\n[design]'), MF, ("'closed_loop'", "give the limbs one way"), {"key": "closed_loop"}),
    # ---- numbers
    Case("Numbers", "`nan` in the reference point", toml("position_m = [0.0, 0.0, 0.3]", "position_m = [0.0, nan, 0.3]"), MF, ("reference_point.position_m", "finite"), {"key": "reference_point.position_m[1]"}),
    Case("Numbers", "`inf` in a home", toml("home = [0.0, 0.0, 0.75]", "home = [0.0, 0.0, inf]"), MF, ("limbs[3].home", "finite"), {"key": "limbs[3].home[2]"}),
    Case("Numbers", "`nan` in the task-space centre", toml("layers = 3", "layers = 3\ncenter_xy_m = [nan, 0.0]"), MF, ("task_space.center_xy_m", "finite")),
    Case("Numbers", "`nan` in a D–H row", toml("  [0.0, 0.0, 0.5, 90.0],", "  [0.0, 0.0, nan, 90.0],"), MF, ("limbs[0].dh.links", "finite")),
    Case("Numbers", "`-inf` in a D–H end", toml("end = [0.0, 180.0]", "end = [-inf, 180.0]"), MF, ("limbs[0].dh.end", "finite")),
    Case("Numbers", "`nan` as the design β", toml("design_beta = 2.0", "design_beta = nan"), MF, ("design.design_beta", "finite")),
    Case("Numbers", "`nan` in the z range", toml("z_m = [0.9, 1.1]", "z_m = [0.9, nan]"), MF, ("task_space.z_m", "finite")),
    Case("Numbers", "`nan` in a table another stage reads (`[calibration]`)", toml("[design]", "[calibration]\ntargets_m = [[0.0, nan, 0.3]]\n\n[design]"), MF, ("calibration.targets_m[0][1]", "not a finite number"), {"key": "calibration.targets_m[0][1]"}),
    Case("Numbers", "a reference point 1e308 m away", toml("position_m = [0.0, 0.0, 0.3]", "position_m = [0.0, 1e308, 0.3]"), MF, ("reference_point.position_m", "beyond ±10000 m")),
    Case("Numbers", "a URDF origin 1e9 m away", urdf('<origin xyz="0 0 0" rpy="1.570796326794897 0 0" />', '<origin xyz="1e9 0 0" rpy="1.570796326794897 0 0" />'), UE, ("limb4_u1", "beyond ±10000 m")),
    Case("Numbers", "a string in a home", toml("home = [0.0, 0.0, 0.75]", 'home = [0.0, "a", 0.75]'), MF, ("limbs[3].home", "list of numbers")),
    Case("Numbers", "a home with too few values", toml("home = [0.0, 0.0, 0.75]", "home = [0.0, 0.75]"), UE, ("limb 'limb4'", "home has 2 values for 3 joints")),
    # ---- task space
    Case("Task space", "`kind = \"sphere\"`", toml('kind = "cylinder"', 'kind = "sphere"'), MF, ("task_space.kind", "'cylinder' or 'points'")),
    Case("Task space", "a negative radius", toml("radius_m = 0.6", "radius_m = -0.6"), MF, ("task_space.radius_m", "> 0")),
    Case("Task space", "a ring of 0 points", toml("rings = [8, 16, 24]", "rings = [8, 0, 24]"), MF, ("task_space.rings", "≥ 1")),
    Case("Task space", "0 layers", toml("layers = 3", "layers = 0"), MF, ("task_space.layers", "at least 1")),
    Case("Task space", "`z_m` reversed", toml("z_m = [0.9, 1.1]", "z_m = [1.1, 0.9]"), MF, ("task_space.z_m", "[z_min, z_max]")),
    Case("Task space", "a cylinder key with `kind = \"points\"`", toml('kind = "cylinder"', 'kind = "points"\npoints_m = [[0.0, 0.0, 1.0]]'), MF, ("task_space.radius_m", "belongs to kind = 'cylinder'")),
    Case("Task space", "`task.kind` other than position", toml('kind = "position"', 'kind = "pose"'), MF, ("task.kind", "'position'")),
    Case("Task space", "a grid of 10⁹ points", toml("rings = [8, 16, 24]", "rings = [1000000000]"), MF, ("task_space", "at most 1000000")),
    # ---- design target
    Case("Design target", "`target = \"50\"` (no unit)", toml('target = "0.05 mm"', 'target = "50"'), MF, ("design.target", "has no unit")),
    Case("Design target", "`target = 50` (a bare number)", toml('target = "0.05 mm"', "target = 50"), MF, ("design.target", "write the unit")),
    Case("Design target", "an unknown unit", toml('target = "0.05 mm"', 'target = "0.05 furlong"'), MF, ("design.target", "unknown unit 'furlong'")),
    Case("Design target", "a negative target", toml('target = "0.05 mm"', 'target = "-0.05 mm"'), MF, ("design.target", "must be positive")),
    Case("Design target", "a β of 0 in the series", toml("beta = [0.5, 1.0", "beta = [0.0, 1.0"), MF, ("design.beta", "positive")),
    Case("Design target", "a negative design β", toml("design_beta = 2.0", "design_beta = -2.0"), MF, ("design.design_beta", "β must be positive")),
    Case("Design target", "`parse_length(\"50\")`", lambda t: parse_length("50", "target"), E.InvalidRequestError, ("target", "has no unit")),
    # ---- limbs
    Case("Limbs", "one limb only", lambda t: _one_limb(t), MF, ("'limbs'", "at least two")),
    Case("Limbs", "two limbs with one name", toml('name = "limb2"', 'name = "limb1"'), MF, ("limbs[1].name", "also used by limbs[0]")),
    Case("Limbs", "`actuated` as a string", toml('actuated = ["limb1_p3"]', 'actuated = "limb1_p3"'), MF, ("limbs[0].actuated", "expected list")),
    Case("Limbs", "a number among the actuated joints", toml('actuated = ["limb1_p3"]', "actuated = [3]"), MF, ("limbs[0].actuated", "list of strings")),
    Case("Limbs", "an actuated joint that is not in the limb", toml('actuated = ["limb1_p3"]', 'actuated = ["limb1_p9"]'), E.UnknownJointError, ("limb 'limb1'", "limb1_p9", "limb1_p3"), {"limb": "limb1", "joint": "limb1_p9"}),
    Case("Limbs", "two actuated joints in one limb", toml('actuated = ["limb1_p3"]', 'actuated = ["limb1_p3", "limb1_u1"]'), UE, ("limb 'limb1'", "2 actuated joints")),
    Case("Limbs", "an actuator removed: too few for the mobility (`pkmtol check` exits 1 with it)", _home_of(toml('actuated = ["limb3_p3"]', "actuated = []")), E.MobilityError, ("too few actuators", "needs 3 actuated joints, 2 given")),
    Case("Limbs", "an actuator too many", _home_of(toml('actuated = []', 'actuated = ["limb4_p3"]')), E.MobilityError, ("too many actuators", "make 1 of them passive")),
    Case("Limbs", "platform frames apart at home", toml("home = [0.0, 0.0, 0.75]", "home = [0.0, 0.0, 0.95]"), E.PlatformMismatchError, ("limb 'limb4'",), {"limb": "limb4"}),
    # ---- D–H tables
    Case("D–H tables", "a table that disagrees with the URDF (a_4 of limb 4 + 0.2 m)", toml(L4_LAST, L4_LAST.replace("[0.0, 0.0, 0.0, 0.0],", "[0.0, 0.0, 0.2, 0.0],")), E.DHMismatchError, ("limb 'limb4'", "limb4_platform_attach", "0.2 m", "python scripts/dh_to_urdf.py"), {"limb": "limb4", "joint": "limb4_platform_attach", "what": "origin"}),
    Case("D–H tables", "a table limit that disagrees with the URDF", toml("limits = [[-90.0, 90.0], [-90.0, 90.0], [0.3, 1.6]]", "limits = [[-90.0, 90.0], [-90.0, 90.0], [0.3, 1.7]]"), E.DHMismatchError, ("limb 'limb4'", "limb4_p3", "limits"), {"joint": "limb4_p3", "what": "limits"}),
    Case("D–H tables", "a joint type other than R or P", toml('joint_types = ["R", "R", "P"]', 'joint_types = ["R", "X", "P"]'), MF, ("limbs[3].dh.joint_types", "'R' and 'P'")),
    Case("D–H tables", "a row missing", toml(L4_LAST, L4_LAST.replace("  [0.0, 0.0, 0.0, 0.0],\n", "")), MF, ("limbs[3].dh.links", "need 4 rows")),
    Case("D–H tables", "table limits reversed", toml("limits = [[-90.0, 90.0], [-90.0, 90.0], [0.3, 1.6]]", "limits = [[-90.0, 90.0], [-90.0, 90.0], [1.6, 0.3]]"), MF, ("limbs[3].dh.limits", "reversed")),
    Case("D–H tables", "a joint name missing", toml('joint_names = ["limb4_u1", "limb4_u2", "limb4_p3"]', 'joint_names = ["limb4_u1", "limb4_u2"]'), MF, ("limbs[3].dh.joint_names", "2 names for 3")),
    # ---- URDF joints and structure
    Case("URDF", "a zero joint axis in limb 4", _first_axis("0 0 0"), UE, ("limb 'limb4'", "limb4_u1", "(0 0 0)"), {"limb": "limb4"}),
    Case("URDF", "a non-unit joint axis `0 0 5`", _first_axis("0 0 5"), UE, ("limb 'limb4'", "limb4_u1", "length 5"), {"limb": "limb4"}),
    Case("URDF", "`nan` in a joint axis", _first_axis("0 0 nan"), UE, ("limb4_u1", "axis xyz")),
    Case("URDF", "`nan` in a joint origin", urdf('<origin xyz="0 0 0" rpy="1.570796326794897 0 0" />', '<origin xyz="0 nan 0" rpy="1.570796326794897 0 0" />'), UE, ("limb4_u1", "origin xyz")),
    Case("URDF", "a mimic joint", _first_axis("0 0 1", '<mimic joint="limb4_u2" />'), UE, ("limb4_u1", "mimics joint 'limb4_u2'")),
    Case("URDF", "a kinematic loop (a link that is the child of two joints)", urdf('<child link="limb4_l3" />', '<child link="limb4_l1" />'), UE, ("limb4_l1", "child of two joints", "kinematic loop")),
    Case("URDF", "a joint whose parent is its child", urdf('<child link="limb4_l1" />', '<child link="base" />'), UE, ("limb4_u1", "kinematic loop")),
    Case("URDF", "two joints with one name", urdf('<joint name="limb4_u2" type="revolute">', '<joint name="limb4_u1" type="revolute">'), UE, ("limb4_u1", "defined twice")),
    Case("URDF", "a revolute joint without `<limit>` (a warning: ±π assumed)", _warned(E.MissingLimitWarning, urdf('<limit lower="-1.5707963267948966" upper="1.5707963267948966" effort="1000" velocity="1" />\n  </joint>\n  <joint name="limb4_u2"', '</joint>\n  <joint name="limb4_u2"')), E.MissingLimitWarning, ("limb4_u1", "no lower/upper limit")),
    Case("URDF", "URDF limits reversed", urdf('lower="0.3" upper="1.6"', 'lower="1.6" upper="0.3"'), UE, ("limb4_p3", "reversed")),
    Case("URDF", "an unknown joint type", urdf('type="prismatic"', 'type="slider"'), UE, ("limb4_p3", "unknown type 'slider'")),
    Case("URDF", "a continuous joint (a warning: read as revolute over ±π)", _warned(E.MissingLimitWarning, urdf(L4_U1, '<joint name="limb4_u1" type="continuous">', "limb4.urdf")), E.MissingLimitWarning, ("limb 'limb4'", "limb4_u1", "is continuous")),
    Case("URDF", "a revolute `<limit>` without lower/upper (a warning: ±π assumed)", _warned(E.MissingLimitWarning, urdf(L4_U1_LIMIT, L4_U1_LIMIT.split("<limit")[0] + "<limit")), E.MissingLimitWarning, ("limb 'limb4'", "limb4_u1", "assumed [-3.14159, 3.14159] rad")),
    Case("URDF", "a prismatic `<limit>` without lower/upper", urdf('<limit lower="0.3" upper="1.6"', "<limit"), E.MissingLimitError, ("limb 'limb4'", "limb4_p3", "stroke"), {"limb": "limb4", "joint": "limb4_p3"}),
    Case("URDF", "a parent link not in the file", urdf('<parent link="limb4_l1" />', '<parent link="limb4_lx" />'), UE, ("limb4_lx", "is not a <link>")),
    Case("URDF", "a limit without `effort` (urdfdom's reason captured)", urdf('lower="0.3" upper="1.6" effort="1000"', 'lower="0.3" upper="1.6"'), UE, ("limb 'limb4'", "limit has no effort")),
    Case("URDF", "malformed XML", urdf("</robot>", "</robo>"), UE, ("limb 'limb4'", "malformed XML")),
    Case("URDF", "a root element other than `<robot>`", _sdf_root, UE, ("limb 'limb4'", "not <robot>")),
    Case("URDF", "a platform link no URDF has", toml('platform_link = "platform"', 'platform_link = "plate"'), UE, ("limb 'limb1'", "no platform link 'plate'")),
    Case("URDF", "a missing mesh (a warning: only that visual is left out)", lambda t: _missing_mesh(t), E.MissingMeshWarning, ("limb 'limb4'", "meshes/nope.stl")),
    # ---- Python API
    Case("Python API", "`Mechanism.from_models([])`", from_models(models=[]), IA, ("models", "at least two limbs"), {"argument": "models"}),
    Case("Python API", "a one-limb mechanism", from_models(models=lambda: models()[:1]), IA, ("models", "at least two limbs")),
    Case("Python API", "`actuated` shorter than `models`", from_models(actuated=[["limb1_p3"]]), IA, ("actuated", "need 4, one per limb"), {"argument": "actuated"}),
    Case("Python API", "a limb that is not a `pin.Model`", from_models(models=lambda: [*models()[:3], "limb4.urdf"]), IA, ("models[3]", "Model"), {"argument": "models[3]"}),
    Case("Python API", "a 2-element reference point", from_models(reference_point_m=[0.0, 0.3]), IA, ("reference_point_m", "3 numbers"), {"argument": "reference_point_m"}),
    Case("Python API", "`target_m=-1` in `from_models`", from_models(target_m=-1), IA, ("target_m", "> 0"), {"argument": "target_m"}),
    Case("Python API", "`homes` with a string", from_models(homes=[*HOMES[:3], ["a", 0, 0]]), IA, ("homes[3]",), {"argument": "homes[3]"}),
    Case("Python API", "`TaskSpace(kind=\"sphere\")`", lambda t: TaskSpace(kind="sphere"), IA, ("TaskSpace.kind", "'cylinder', 'points'"), {"argument": "TaskSpace.kind"}),
    Case("Python API", "a negative task-space radius", lambda t: TaskSpace(kind="cylinder", radius_m=-0.6, z_range_m=(0.9, 1.1), rings=(8,)), IA, ("TaskSpace.radius_m", "> 0")),
    Case("Python API", "an empty explicit task space", lambda t: TaskSpace(kind="points", points_m=np.zeros((0, 3))), IA, ("TaskSpace.points_m",), {"argument": "TaskSpace.points_m"}),
    Case("Python API", "`allocate(mech, \"fast\")`", lambda t: allocate(seed_mech(), "fast"), IA, ("options", "DesignOptions"), {"argument": "options"}),  # type: ignore[arg-type]
    Case("Python API", "`allocate` given a folder instead of a mechanism", lambda t: allocate("robots/r2rps_ups"), IA, ("mechanism", "load_mechanism"), {"argument": "mechanism"}),  # type: ignore[arg-type]
    Case("Python API", "`DesignOptions(claim_poses=0)`", lambda t: DesignOptions(claim_poses=0), IA, ("claim_poses", "≥ 1"), {"argument": "claim_poses"}),
    Case("Python API", "`DesignOptions(target_m=\"50um\")`", lambda t: DesignOptions(target_m="50um"), IA, ("target_m", "parse_length"), {"argument": "target_m"}),  # type: ignore[arg-type]
    Case("Python API", "`DesignOptions(samples=True)`", lambda t: DesignOptions(samples=True), IA, ("samples", "whole number"), {"argument": "samples"}),
    Case("Python API", "`DesignOptions(samples=2000.0)`", lambda t: DesignOptions(samples=2000.0), IA, ("samples", "whole number")),  # type: ignore[arg-type]
    Case("Python API", "`DesignOptions(seed=-1)`", lambda t: DesignOptions(seed=-1), IA, ("seed", "≥ 0"), {"argument": "seed"}),
    Case("Python API", "`DesignOptions(method=\"fast\")`", lambda t: DesignOptions(method="fast"), IA, ("method", "'fosm', 'exact', 'cost'")),
    Case("Python API", "a criterion with `method=\"fosm\"`", lambda t: DesignOptions(method="fosm", criterion="worst"), IA, ("criterion", "only method 'exact'"), {"argument": "criterion"}),
    Case("Python API", "a misspelt parameter set", lambda t: DesignOptions(parameter_set="dhh"), IA, ("parameter_set", "did you mean 'dh'")),
    Case("Python API", "an empty β series", lambda t: DesignOptions(betas=()), IA, ("betas", "positive")),
    Case("Python API", "a run that does not fit in memory", lambda t: check_memory(seed_mech(), DesignOptions(samples=10**11), available_bytes=8e9), E.ResourceLimitError, ("samples", "more than the 8 GB available", "at most about"), {"argument": "samples"}),
    Case("Python API", "`mech.limb(\"limb9\")`", lambda t: seed_mech().limb("limb9"), IA, ("limb9", "limb1, limb2, limb3, limb4")),
    Case("Python API", "`ClosedChain` given a folder name", lambda t: ClosedChain("robots/r2rps_ups"), IA, ("mechanism", "pkmtol.Mechanism"), {"argument": "mechanism"}),  # type: ignore[arg-type]
    Case("Python API", "`fosm_tolerances` with a `nan` sensitivity", lambda t: fosm_tolerances(np.array([1.0, np.nan]), 5e-5, np.array([2.0])), IA, ("omega", "finite"), {"argument": "omega"}),
    Case("Python API", "`sweep` given points of 2 coordinates", lambda t: sweep(seed_mech(), parameter_set(seed_mech()), np.zeros((4, 2))), IA, ("points_m", "(n, 3)"), {"argument": "points_m"}),
    Case("Python API", "`load_closed_loop` given a number as the sidecar", lambda t: load_closed_loop(REPO / "tests/data/r2rps_ups_closed/robot.urdf", 5, reference_point_m=[0, 0, 0.3], task_space=TASK), IA, ("sidecar", "file path"), {"argument": "sidecar"}),  # type: ignore[arg-type]
    Case("Python API", "`load_mjcf` given `None` as the file", lambda t: load_mjcf(None, reference_point_m=[0, 0, 0.3], task_space=TASK), IA, ("path", "file path"), {"argument": "path"}),  # type: ignore[arg-type]
    Case("Python API", "`write_outputs` given something else than a result", lambda t: write_outputs("result", t / "o"), IA, ("result", "DesignResult")),  # type: ignore[arg-type]
    Case("Python API", "`check_contract(design, machines=0)`", contract_without_machines, IA, ("machines = 0", "integer ≥ 1"), {"argument": "machines"}),
    # ---- Python API: arguments of every public callable (tests/test_api_fuzz.py fuzzes them all)
    Case("Python API", "`ClosedChain.inverse(None)`", lambda t: ClosedChain(seed_mech()).inverse(None), IA, ("target_m", "numbers"), {"argument": "target_m"}),  # type: ignore[arg-type]
    Case("Python API", "`ClosedChain.forward` driving an actuator beyond its limits", _forward_below_limit, IA, ("q_actuated", "limb1_p3", "outside its limits [0.4, 1.6]"), {"argument": "q_actuated"}),
    Case("Python API", "`TreeChain.forward` driving an actuator beyond its limits", _tree_forward_below_limit, IA, ("q_actuated", "limb1_p3", "outside its limits [0.4, 1.6]"), {"argument": "q_actuated"}),
    Case("Python API", "`mech.constraint_models(5)`", lambda t: seed_mech().constraint_models(5), IA, ("models", "list of pin.Model"), {"argument": "models"}),  # type: ignore[arg-type]
    Case("Python API", "`perturbed_limb_models(mech, None)`", lambda t: perturbed_limb_models(seed_mech(), None), IA, ("eps", "one per limb"), {"argument": "eps"}),  # type: ignore[arg-type]
    Case("Python API", "`load_mechanism(folder, urdf_texts=5)`", lambda t: load_mechanism(SEED, urdf_texts=5), IA, ("urdf_texts", "mapping"), {"argument": "urdf_texts"}),  # type: ignore[arg-type]
    Case("Python API", "`load_mjcf(..., keyframe=[])`", lambda t: load_mjcf(REPO / "tests/data/r2rps_ups_mjcf/robot.xml", reference_point_m=[0, 0, 0.3], task_space=TASK, keyframe=[]), IA, ("keyframe", "string"), {"argument": "keyframe"}),  # type: ignore[arg-type]
    Case("Python API", "`verify(..., target_m=nan)` (it returned R = 1)", lambda t: _verify_one(target_m=float("nan")), IA, ("target_m", "finite"), {"argument": "target_m"}),
    Case("Python API", "`verify(..., distribution=\"normal\")`", lambda t: _verify_one(distribution="normal"), IA, ("distribution", "'gaussian'"), {"argument": "distribution"}),
    Case("Python API", "`sign_off(None)`", lambda t: sign_off(None), IA, ("result", "DesignResult"), {"argument": "result"}),  # type: ignore[arg-type]
    Case("Python API", "`DrawingSettings(k=None)`", lambda t: DrawingSettings(k=None), IA, ("DrawingSettings.k", "number"), {"argument": "DrawingSettings.k"}),  # type: ignore[arg-type]
    Case("Python API", "`DrawingSettings(k=1e308)`", lambda t: DrawingSettings(k=1e308), IA, ("DrawingSettings.k", "≤ 100"), {"argument": "DrawingSettings.k"}),
    Case("Python API", "`fosm_tolerances` given one β as a number", lambda t: fosm_tolerances(np.ones(3), 5e-5, 1e308), IA, ("betas", "1 dimension"), {"argument": "betas"}),  # type: ignore[arg-type]
    Case("Python API", "`TaskSpace.sample(rng, 10**12)`", lambda t: TASK.sample(np.random.default_rng(0), 10**12), IA, ("count", "≤ 100000000"), {"argument": "count"}),
    Case("Python API", "a length of 1e300 m", lambda t: DesignOptions(target_m=1e300), IA, ("target_m", "beyond 10000 m"), {"argument": "target_m"}),
    Case("URDF", "`nan` as a visual's sphere radius", urdf(L4_L1_VISUAL, L4_L1_VISUAL.replace('"0.03"', '"nan"')), UE, ("limb 'limb4'", "link 'limb4_l1'", "<visual> <sphere> radius = 'nan'"), {"limb": "limb4"}),
    Case("URDF", "`inf` in a visual's origin", urdf(L4_L1_VISUAL, L4_L1_VISUAL.replace("<geometry>", '<origin xyz="0 inf 0" />\n      <geometry>')), UE, ("link 'limb4_l1'", "<visual> origin xyz"), {"limb": "limb4"}),
    Case("URDF", "`nan` as the size of an MJCF `<geom>`", _mjcf_geom_nan, E.MJCFError, ("limb1_l1", "<geom 'limb1_l1_visual'> size = 'nan'")),
    # ---- command line
    Case("Command line", "`--seed -1`", cli("allocate", "{robot}", "--seed", "-1"), IA, ("--seed -1", "≥ 0"), {"argument": "--seed"}),
    Case("Command line", "`--samples 0`", cli("allocate", "{robot}", "--samples", "0"), IA, ("--samples 0", "≥ 2"), {"argument": "--samples"}),
    Case("Command line", "`--verification-poses 0`", cli("allocate", "{robot}", "--verification-poses", "0"), IA, ("--verification-poses 0",)),
    Case("Command line", "`--exact-samples -1`", cli("allocate", "{robot}", "--exact-samples", "-1"), IA, ("--exact-samples -1",)),
    Case("Command line", "`--target 50` (no unit)", cli("allocate", "{robot}", "--target", "50"), IA, ("--target 50", "has no unit"), {"argument": "--target"}),
    Case("Command line", "`--target 0mm`", cli("allocate", "{robot}", "--target", "0mm"), IA, ("--target 0mm", "must be positive")),
    Case("Command line", "`--beta 0`", cli("allocate", "{robot}", "--beta", "0"), IA, ("--beta", "β must be positive"), {"argument": "--beta"}),
    Case("Command line", "`--criterion` with `--method fosm`", cli("allocate", "{robot}", "--method", "fosm", "--criterion", "worst"), IA, ("--criterion worst", "--method exact"), {"argument": "--criterion"}),
    Case("Command line", "`sweep --criterion` with `--method fosm`", cli("sweep", "{robot}", "--vary", "task_space.radius_m=0.5:0.6:2", "--method", "fosm", "--criterion", "worst"), IA, ("--criterion worst", "--method exact"), {"argument": "--criterion"}),
    Case("Command line", "a huge `--samples`", cli("allocate", "{robot}", "--samples", "1000000000000"), E.ResourceLimitError, ("--samples 1000000000000", "needs about", "at most about"), {"argument": "--samples"}),
    Case("Command line", "`--html` into a folder that does not exist", cli("allocate", "{robot}", "--html", "{tmp}/no/s.html", *SMALL), E.OutputError, ("s.html", "does not exist")),
    Case("Command line", "`--out` that is a file", cli("allocate", "{robot}", "--out", "{robot}/mechanism.toml", *SMALL), E.OutputError, ("mechanism.toml",)),
    Case("Command line", "`--out` another run is writing into", locked_out, E.OutputLockedError, ("busy", "is writing a run into this folder")),
    Case("Command line", "`errors --json` into a folder that does not exist", cli("errors", "{robot}", "--json", "{tmp}/no/e.json"), E.OutputError, ("e.json", "does not exist")),
    Case("Command line", "`new` with a bare number (its unit missing)", cli("new", "tricept", "--base-radius", "550", "--out", "{tmp}/t"), IA, ("--base-radius 550", "has no unit"), {"argument": "--base-radius"}),
    Case("Command line", "`new` with a rod shorter than the radii allow", cli("new", "sprint_z3", "--rod-length", "50mm", "--out", "{tmp}/s"), IA, ("--rod-length 0.05", "must be longer"), {"argument": "--rod-length"}),
    Case("Command line", "`new` into a folder that is not empty", new_in_taken, E.OutputError, ("taken", "not an empty folder")),
    Case("Command line", "`PKMTOL_JIT=maybe` in the environment", jit_switch_misspelt, IA, ("PKMTOL_JIT = 'maybe'", "set it to 0"), {"argument": "PKMTOL_JIT"}),
    Case("Command line", "`new` with a task space the robot cannot reach", cli("new", "tricept", "--task-radius", "1.5m", "--out", "{tmp}/big", "--no-progress"), E.RobotCheckError, ("tricept", "117 of 147 task-space points are not reachable"), {"family": "tricept"}),
    Case("One tree with loops", "a urdfdom `<constraint>` of type `revolute`", _epr_with_constraint("revolute"), E.ClosedLoopError, ("rod2_cut", "revolute", "cut the loop at a fixed"), {"culprit": "rod2_cut"}),
    Case("One tree with loops", "a task frame that is not in the tree", _tree_task_frame_missing, E.ClosedLoopError, ("tcp", "no frame 'tcp'"), {"culprit": "tcp"}),
    Case("One tree with loops", "a constraint model that is not a frame or point anchor", _tree_unknown_constraint, E.ClosedLoopError, ("constraint 1", "FrameAnchorConstraintModel"), {"culprit": "constraint 1"}),
    Case("One tree with loops", "a loop whose two frames are on one body", _tree_loop_on_one_body, E.ClosedLoopError, ("same_body", "same body"), {"culprit": "same_body"}),
    Case("Command line", "`calibrate --instrument ballbar` with a reading in degrees", ballbar_reading_in_degrees, E.MeasurementFileError, ("'d'", "not a length unit")),
    Case("Command line", "`calibrate --plan-per-machine` without `--simulate`", cli("calibrate", "{robot}", "--plan-per-machine"), E.InvalidRequestError, ("--plan-per-machine", "give --simulate too")),
    # ---- hybrid machines: a tool chain on the platform (docs/hybrid.md)
    Case("Hybrid machines", "`--tool-length` on a robot without a `[tool]` chain", cli("check", "{robot}", "--tool-length", "150mm"), IA, ("--tool-length 150mm", "has no tool chain"), {"argument": "--tool-length"}),
    Case("Hybrid machines", "`--lock-wrist` that leaves a wrist joint free", cli("check", str(HYBRID), "--lock-wrist", "wrist_a=45deg"), IA, ("--lock-wrist wrist_a=45deg", "missing wrist_c"), {"argument": "--lock-wrist"}),
    Case("Hybrid machines", "`calibrate --tracker-on nose` on a robot without a `[tool]` chain", cli("calibrate", "{robot}", "--tracker-on", "nose"), E.InvalidRequestError, ("--tracker-on nose", "has no tool chain")),
    Case("Hybrid machines", "`pkmtol calibrate` of a hybrid machine with a ballbar", cli("calibrate", str(HYBRID), "--instrument", "ballbar"), E.InvalidRequestError, ("r2rps_ups_wrist", "is a hybrid machine", "not a ballbar")),
    Case("Hybrid machines", "a `[tool]` table with `task.kind = \"position\"`", toml("[design]", '[tool]\nurdf = "limb4.urdf"\nnose_frame = "platform"\n\n[design]'), MF, ("task.kind", "a [tool] table needs task.kind = 'tool'")),
]  # fmt: skip


# ---- issue 25: calibrate's data path, tracebacks, outputs, silent acceptance


def measured_at_grid(tmp: Path, edit: Callable[[np.ndarray], np.ndarray]) -> Path:
    """A measurement file of the seed robot at 30 grid poses, its exact P positions changed by ``edit``."""
    from pkmtol.calibration.measurement_files import measurements_csv

    mech = load_mechanism(SEED)
    chain = ClosedChain(mech)
    poses = [chain.inverse(p) for p in mech.task_space.grid()[::4][:30]]
    commands = np.array([pose.q_all[chain.actuated_idx] for pose in poses])
    points = np.array([pose.p_m for pose in poses])[:, None, :]
    path = tmp / "measured.csv"
    path.write_text(measurements_csv(mech, commands, edit(points)))
    return path


def calibrate_zeros(tmp: Path) -> Any:
    data = measured_at_grid(tmp, lambda y: 0.0 * y)
    return cli_run(["calibrate", str(robot(tmp)), "--measurements", str(data), "--out", str(tmp / "cal")])


def calibrate_millimetres_as_metres(tmp: Path) -> Any:
    data = measured_at_grid(tmp, lambda y: 1e3 * y)
    return cli_run(["calibrate", str(robot(tmp)), "--measurements", str(data), "--out", str(tmp / "cal")])


def calibrate_two_target_columns(tmp: Path) -> Any:
    data = measured_at_grid(tmp, lambda y: y)
    data.write_text(data.read_text(encoding="utf-8").replace("pose,", "target,", 1), encoding="utf-8")
    return cli_run(["calibrate", str(robot(tmp)), "--measurements", str(data), "--out", str(tmp / "cal")])


def calibrate_offset(tmp: Path) -> Any:
    data = measured_at_grid(tmp, lambda y: y + np.array([0.05, 0.0, 0.0]))
    return cli_run(["calibrate", str(robot(tmp)), "--measurements", str(data), "--out", str(tmp / "cal")])


def calibrate_huge_coordinate(tmp: Path) -> Any:
    data = measured_at_grid(tmp, lambda y: y + np.array([0.0, 0.0, 1e300]))
    return cli_run(["calibrate", str(robot(tmp)), "--measurements", str(data), "--out", str(tmp / "cal")])


def errors_json_into_a_fifo(tmp: Path) -> Any:
    os.mkfifo(tmp / "pipe")
    return cli_run(["errors", str(robot(tmp)), "--json", str(tmp / "pipe")])


def html_at_allocation_json(tmp: Path) -> Any:
    (tmp / "out").mkdir()
    return cli_run(
        [
            "allocate",
            str(robot(tmp)),
            "--out",
            str(tmp / "out"),
            "--html",
            str(tmp / "out" / "allocation.json"),
        ]
    )


def other_robots_allocation(tmp: Path) -> Any:
    path = tmp / "allocation.json"
    path.write_text(
        '{"mechanism": "tricept", "parameter_set": "dh", "beta": [2.0], "design_beta": 2.0, "parameters": []}'
    )
    return cli_run(["calibrate", str(robot(tmp)), "--tolerances", str(path), "--out", str(tmp / "cal")])


CASES += [
    Case("Calibration data", "`calibrate --measurements` with every coordinate 0", calibrate_zeros, PoorFitError, ("measured.csv", "every measured coordinate is 0", "--accept-poor-fit"), {"cause": "zeros"}),
    Case("Calibration data", "`calibrate --measurements` with every coordinate 1000× the nominal", calibrate_millimetres_as_metres, PoorFitError, ("measured.csv", "before any fit", "about 1000× the nominal ones", "micrometres under [mm]"), {"cause": "units"}),
    Case("Calibration data", "`calibrate --measurements` with two `target` columns", calibrate_two_target_columns, E.MeasurementFileError, ("measured.csv", "'target': column given twice"), {"column": "target"}),
    Case("Calibration data", "`calibrate --measurements` read 50 mm off the base frame", calibrate_offset, PoorFitError, ("measured.csv", "rigid offset of the tracker's frame", "--tracker-frame identify"), {"cause": "frame offset"}),
    Case("Calibration data", "`calibrate --measurements` with a coordinate of 1e300", calibrate_huge_coordinate, E.MeasurementFileError, ("measured.csv", "column 'z'", "not a measurement"), {"column": "z"}),
    Case("Calibration data", "`calibrate --measurements /dev/zero` (it read until the kernel killed it)", cli("calibrate", "{robot}", "--measurements", "/dev/zero", "--out", "{tmp}/cal"), E.MeasurementFileError, ("/dev/zero", "holds more than 256 MiB")),
    Case("Calibration data", "`calibrate --measurements` naming a folder", cli("calibrate", "{robot}", "--measurements", "{tmp}", "--out", "{tmp}/cal"), E.MeasurementFileError, ("is a folder",)),
    Case("Calibration data", "`calibrate --tolerances` with another robot's allocation.json", other_robots_allocation, E.InvalidRequestError, ("'tricept', not of 'r2rps_ups'",)),
    Case("Calibration data", "`calibrate --tolerances` with `--measurements` but no `--prior`", cli("calibrate", "{robot}", "--measurements", "{tmp}/m.csv", "--tolerances", "{tmp}/a.json", "--out", "{tmp}/cal"), IA, ("--tolerances", "give --prior"), {"argument": "--tolerances"}),
    Case("Calibration options", "`--noise 1e300mm`", cli("calibrate", "{robot}", "--noise", "1e300mm", "--out", "{tmp}/cal"), IA, ("--noise 1e300mm", "between 0 and 1 m"), {"argument": "--noise"}),
    Case("Calibration options", "`calibrate --poses 0`", cli("calibrate", "{robot}", "--poses", "0", "--out", "{tmp}/cal"), IA, ("--poses 0", "≥ 1"), {"argument": "--poses"}),
    Case("Calibration options", "`calibrate --random-sets -1`", cli("calibrate", "{robot}", "--random-sets", "-1", "--out", "{tmp}/cal"), IA, ("--random-sets -1",), {"argument": "--random-sets"}),
    Case("Calibration options", "a huge `calibrate --holdout`", cli("calibrate", "{robot}", "--holdout", "10000000000", "--out", "{tmp}/cal"), E.ResourceLimitError, ("--holdout 10000000000", "needs about", "at most about"), {"argument": "--holdout"}),
    Case("Calibration options", "`allocate --poses 5` without `--compensation calibrated`", cli("allocate", "{robot}", "--poses", "5", "--out", "{tmp}/a"), IA, ("--poses 5", "only with --compensation calibrated"), {"argument": "--poses"}),
    Case("Calibration options", "`allocate --drawing-k 1e308`", cli("allocate", "{robot}", "--drawing-k", "1e308", "--out", "{tmp}/a"), IA, ("--drawing-k 1e+308", "(0, 10]"), {"argument": "--drawing-k"}),
    Case("Outputs", "`errors --json` at a FIFO (or a device such as /dev/null)", errors_json_into_a_fifo, E.OutputError, ("pipe", "not a regular file")),
    Case("Outputs", "`allocate --html` at the run's own allocation.json", html_at_allocation_json, E.OutputError, ("allocation.json", "of the same run")),
    Case("Outputs", "`sweep` over four axes of 65,536 values", cli("sweep", "{robot}", *[f"--vary=reference_point.position_m[{i}]=0.0:0.01:65536" for i in range(3)], "--vary=task_space.radius_m=0.5:0.6:65536", "--out", "{tmp}/s"), E.SweepSpecError, ("18446744073709551616 variants",)),
]  # fmt: skip


def message(err: BaseException, tmp: Path) -> str:
    """The message with the case's folder shown as ``<tmp>`` and machine-dependent numbers normalised."""
    text = str(err).replace(str(tmp), "<tmp>")
    text = re.sub(r"more than the [\d.,]+ [GMT]B available", "more than the N GB available", text)
    text = re.sub(r"at most about [\d,]+ for --", "at most about M for --", text)
    return re.sub(r"at most about [\d,]+ samples", "at most about M samples", text)


def catch(case: Case, tmp: Path) -> BaseException:
    """Run ``case`` and return what it raised (an AssertionError if it raised nothing)."""
    try:
        case.run(tmp)
    except (E.PkmtolError, E.PkmtolWarning) as err:
        return err
    raise AssertionError(f"{case.what}: nothing raised")
