"""Closed-loop models read as one tree with loop constraints: example-parallel-robots URDF + YAML,
urdfdom ``<constraint>`` elements, MJCF equalities, Pinocchio 4 constraint models.

Each reader is checked against another route to the same mechanism (the limb path, another format)
and for the errors it names; the constraint models' Jacobians against the tree's, with their signs.
"""

from __future__ import annotations

import re
import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
from loop_robots import ROOT
from same_mechanism import assert_same_allocation

from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.table import error_table
from pkmtol.error_model.tree_parameters import tree_urdf_set
from pkmtol.error_model.tree_separation import tree_sweep
from pkmtol.exceptions import ClosedLoopError, UnknownMotorError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.kinematics.tree_chain import TreeBatch
from pkmtol.kinematics.tree_frames import forward, loop_jacobians, raw_world
from pkmtol.model.closed_loop import closed_loop_limbs
from pkmtol.model.loader import load_mechanism
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.mjcf import tree_from_mjcf
from pkmtol.model.tree_inputs import tree_from_constraint_models, tree_from_urdf

DATA = ROOT / "tests" / "data"
EPR = ROOT / "robots" / "delta_epr"
DELTA_HOME = {f"arm{i}_mot": 0.560725245458 for i in (1, 2, 3)}


def test_example_parallel_robots_delta_loads_whole_where_the_cut_stops():
    """robot_delta (reduced to links and joints): loops between rods, sphere revolutes below the effector,
    two motorised branches joined away from it. The cut into limbs refuses it; the tree takes it."""
    urdf = DATA / "epr_robot_delta" / "robot.urdf"
    with pytest.raises(ClosedLoopError, match="hangs below the platform|ambiguous|both have a motor"):
        closed_loop_limbs(urdf, platform_link="effecteur")
    tree = tree_from_urdf(urdf, task_frame="eff")
    assert [lp.name for lp in tree.loops] == ["fermeture1", "fermeture2", "fermeture3"]
    assert [tree.joint_names[a] for a in tree.actuated] == ["mot1_bras1", "mot1_bras2"]
    assert tree.nq == 14 - 3  # three sphere revolutes locked by joint_type FIXED
    limbs = tree.limbs
    assert len(limbs) == 2 and limbs[0].holds_platform and all(lb.reaches_base for lb in limbs)
    # the second limb is two branches from the base (bras2 with its motor, bras3 passive) and the
    # sphere revolutes that hang below the effector, joined by the loops
    names = {tree.joint_names[j] for j in limbs[1].joints}
    assert {"mot1_bras2", "libre1_bras3", "fermeture3_B"} <= names
    batch = TreeBatch(tree)
    gap = batch.worst_loop(tree.home)
    assert gap[3] > 1e-3  # written open at q = 0
    q = batch.chain.home()
    assert batch.worst_loop(q)[3] < 1e-12


def _with_constraints(tmp_path):
    """robots/delta_epr with its sidecar's loops written as urdfdom <constraint> elements instead."""
    root = ET.parse(EPR / "robot.urdf").getroot()
    links = {j.find("child").get("link"): j for j in root.findall("joint")}  # type: ignore[union-attr]
    pairs = [("platform", "closedloop1_B", "fixed"), ("platform", "closedloop2_B", "fixed")]
    pairs += [(f"arm{i}_rod2_socket", f"arm{i}_rod2_end", "spherical") for i in (1, 2, 3)]
    names = ["closedloop1", "closedloop2", "arm1_rod2", "arm2_rod2", "arm3_rod2"]
    for name, (parent, child, kind) in zip(names, pairs, strict=True):
        c = ET.SubElement(root, "constraint", name=name, type=kind)
        ET.SubElement(c, "parent", link=parent)
        ET.SubElement(c, "parent_origin", xyz="0 0 0", rpy="0 0 0")
        ET.SubElement(c, "child", link=child)
        ET.SubElement(c, "child_origin", xyz="0 0 0", rpy="0 0 0")
    assert links
    path = tmp_path / "robot.urdf"
    path.write_text(ET.tostring(root, encoding="unicode"), encoding="utf-8")
    return path


def test_urdfdom_constraint_elements_give_the_sidecar_mechanism(tmp_path):
    """The same loops as <constraint> elements (no sidecar): the same loops, poses and maps (1e-12)."""
    path = _with_constraints(tmp_path)
    kw = {
        "task_frame": "platform",
        "point_m": [0, 0, -0.1],
        "home": DELTA_HOME,
        "actuated": [f"arm{i}_mot" for i in (1, 2, 3)],
    }
    a = tree_from_urdf(EPR / "robot.urdf", **kw)
    b = tree_from_urdf(path, **kw)
    assert [lp.kind for lp in b.loops] == ["6d", "6d", "3d", "3d", "3d"]
    pa, pb = tree_urdf_set(a), tree_urdf_set(b)
    assert pa.names == pb.names
    pts = load_mechanism(ROOT / "robots" / "delta").task_space.grid()[::7]
    sa, sb = tree_sweep(a, pa, pts), tree_sweep(b, pb, pts)
    assert np.abs(sa.J - sb.J).max() < 1e-12
    assert np.abs(sa.J_total - sb.J_total).max() < 1e-12
    assert sa.classify() == sb.classify()


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            lambda t: t.replace('type="spherical"', 'type="revolute"', 1),
            "revolute.*cut the loop at a fixed or ball",
        ),
        (
            lambda t: t.replace('<parent link="arm1_rod2_socket"', '<parent link="nowhere"', 1),
            "no frame 'nowhere'",
        ),
        (lambda t: t.replace('name="closedloop2"', "", 1), "without a name"),
        (
            lambda t: re.sub(r'<child_origin xyz="0 0 0"', '<child_origin xyz="0 0 x"', t, count=1),
            "not three",
        ),
    ],
)
def test_bad_constraint_elements_are_named(tmp_path, edit, match):
    path = _with_constraints(tmp_path)
    path.write_text(edit(path.read_text(encoding="utf-8")), encoding="utf-8")
    with pytest.raises(ClosedLoopError, match=match):
        tree_from_urdf(path, task_frame="platform", actuated=["arm1_mot"])


def test_sidecar_errors_are_named(tmp_path):
    """A motor that is not a joint, a re-typing pkmtol cannot take, a task frame that is not there."""
    shutil.copy(EPR / "robot.urdf", tmp_path / "robot.urdf")
    side = (EPR / "robot.yaml").read_text(encoding="utf-8")
    (tmp_path / "robot.yaml").write_text(side.replace("'arm3_mot'", "'arm4_mot'"), encoding="utf-8")
    with pytest.raises(UnknownMotorError, match="arm4_mot"):
        tree_from_urdf(tmp_path / "robot.urdf", task_frame="platform")
    (tmp_path / "robot.yaml").write_text(
        side.replace("joint_name: []", "joint_name: ['arm1_rod1_s1']").replace(
            "joint_type: []", "joint_type: ['SPHERICAL']"
        ),
        encoding="utf-8",
    )
    with pytest.raises(ClosedLoopError, match="SPHERICAL.*three revolutes"):
        tree_from_urdf(tmp_path / "robot.urdf", task_frame="platform")
    (tmp_path / "robot.yaml").write_text(side, encoding="utf-8")
    with pytest.raises(ClosedLoopError, match="no frame 'tcp'"):
        tree_from_urdf(tmp_path / "robot.urdf", task_frame="tcp")


def test_mjcf_equalities_give_the_urdf_trees_error_model():
    """The Digit-like leg as MJCF (<connect> between sites) and as URDF + YAML: the same J (1e-15) and
    classes; the URDF's toe link adds its attachment error (toe_fix), which MJCF's site has not."""
    a = tree_from_urdf(DATA / "digit_like_leg" / "robot.urdf", task_frame="toe")
    b = tree_from_mjcf(DATA / "digit_like_leg" / "robot.xml", task_frame="toe")
    pa, pb = tree_urdf_set(a), tree_urdf_set(b)
    assert set(pa.names) - set(pb.names) == {f"toe_fix.{c}" for c in ("dx", "dy", "dz", "rx", "ry", "rz")}
    idx = [pa.names.index(n) for n in pb.names]
    pts = np.array([[0.12, 0.02, -0.8], [0.08, -0.03, -0.78], [0.16, 0.0, -0.82]])
    sa, sb = tree_sweep(a, pa, pts), tree_sweep(b, pb, pts)
    assert np.abs(sa.J[:, :, idx] - sb.J).max() < 1e-15
    assert np.abs(sa.J_total[:, :, idx] - sb.J_total).max() < 1e-15
    assert [sa.classify()[i] for i in idx] == sb.classify()


def test_mjcf_seed_robot_as_a_tree_solves_as_the_limbs():
    """tests/data/r2rps_ups_mjcf read as one tree (no cut): the limb path's poses of P and the platform."""
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    tree = tree_from_mjcf(DATA / "r2rps_ups_mjcf" / "robot.xml", task_frame="platform", point_m=[0, 0, 0.3])
    grid = mech.task_space.grid()[::5]
    chain = ClosedChain(mech)
    q = chain.home()
    batch = TreeBatch(tree)
    sols = batch.inverse(grid, np.tile(batch.chain.home(), (len(grid), 1)))
    for k, p in enumerate(grid):
        pose = chain.inverse(p, q)
        assert np.abs(sols.rotation[k] - pose.oMp.rotation).max() < 1e-12
        assert np.abs(sols.p_m[k] - pose.p_m).max() < 1e-12


@pytest.mark.parametrize("robot", ["r2rps_ups", "delta"])
def test_constraint_models_read_as_a_tree(robot):
    """A Pinocchio 4 stack (Mechanism.constraint_models) as a LoopTree: the limb path's poses; the
    constraint Jacobian of a FrameAnchorConstraintModel is the tree's loop rows, of a
    PointAnchorConstraintModel those rows in frame a (R_aᵀ), of a legacy RigidConstraintModel minus them."""
    mech = load_mechanism(ROOT / "robots" / robot)
    cm = mech.constraint_models()
    actuated = [cm.model.names[1 + a] for a in cm.actuated]
    platform = cm.model.frames[cm.platform_frame].name
    tree = tree_from_constraint_models(
        cm.model,
        cm.constraints,
        actuated,
        platform,
        mech.reference_point_m,
        home=np.concatenate([lb.home for lb in mech.limbs]),
    )
    assert [lp.kind for lp in tree.loops] == [
        "6d" if type(c).__name__.startswith("Frame") else "3d" for c in cm.constraints
    ]
    chain = ClosedChain(mech)
    pose = chain.inverse(mech.task_space.grid()[3], chain.home())
    batch = TreeBatch(tree)
    sol = batch.inverse(pose.p_m[None], batch.chain.home()[None])
    assert np.abs(sol.q[0] - cm.q(pose.q)).max() < 1e-10
    q = sol.q[0]
    poses = forward(batch.tables, q[None])
    c, _ = loop_jacobians(tree, poses, raw_world(tree, poses))
    rows = []
    for lp in tree.loops:
        block = (
            c[0, : lp.rows]
            if not rows
            else c[0, sum(len(r) for r in rows) : sum(len(r) for r in rows) + lp.rows]
        )
        if lp.kind == "3d":
            block = poses.frame(tree, lp.frame_a)[0, :3, :3].T @ block
        rows.append(block)
    mine = np.vstack(rows)
    assert np.abs(cm.jacobian(q) - mine).max() < 1e-10
    legacy = cm.rigid_constraints()
    data = cm.model.createData()
    datas = [rc.createData() for rc in legacy]
    pin.computeJointJacobians(cm.model, data, q)
    for rc, rd in zip(legacy, datas, strict=True):
        rc.calc(cm.model, data, rd)
    jac = pin.getConstraintsJacobian(cm.model, data, legacy, datas)
    assert np.abs(np.asarray(jac) + mine).max() < 1e-10


def test_mechanism_from_constraint_models_gives_the_limb_mechanism():
    """Mechanism.from_constraint_models on the seed robot's stack: cut into limbs again, the same classes
    and sensitivities as robots/r2rps_ups (urdf set, parameters renamed by the loops' names)."""
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    cm = mech.constraint_models()
    actuated = [cm.model.names[1 + a] for a in cm.actuated]
    again = Mechanism.from_constraint_models(
        cm.model,
        cm.constraints,
        actuated,
        cm.model.frames[cm.platform_frame].name,
        reference_point_m=mech.reference_point_m,
        task_space=mech.task_space,
        home=np.concatenate([lb.home for lb in mech.limbs]),
        limb_names=[lb.name for lb in mech.limbs],
    )
    assert [lb.nq for lb in again.limbs] == [lb.nq for lb in mech.limbs]
    a, b = error_table(mech, "urdf"), error_table(again, "urdf")
    assert sorted(a.classes) == sorted(b.classes)
    assert np.sort(a.sensitivity) == pytest.approx(np.sort(b.sensitivity), abs=1e-10)


def test_bad_constraint_models_are_named():
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    cm = mech.constraint_models()
    platform = cm.model.frames[cm.platform_frame].name
    with pytest.raises(ClosedLoopError, match="not a loop pkmtol takes"):
        tree_from_constraint_models(cm.model, [object()], ["limb1_p3"], platform)
    with pytest.raises(UnknownMotorError, match="limb9_p3"):
        tree_from_constraint_models(cm.model, cm.constraints, ["limb9_p3"], platform)


def test_delta_epr_runs_the_limb_pipeline_with_the_deltas_classes():
    """robots/delta_epr through mechanism.toml ([closed_loop], cut into limbs): robots/delta's classes and
    sensitivities (1e-9) under the cut's names (arm2.loop1.dx = arm2.arm2_platform_attach.dx ...)."""
    a = error_table(load_mechanism(ROOT / "robots" / "delta"), "urdf")
    epr = load_mechanism(EPR)
    b = error_table(epr, "urdf")
    ren = {}
    for name in b.pset.names:
        limb, rest = name.split(".", 1)
        origin, comp = rest.rsplit(".", 1)
        if origin == epr.limb(limb).attach_name:
            origin = f"{limb}_platform_attach"
        elif origin in [lp.name for lp in epr.limb(limb).loops]:
            origin = "rod2"
        ren[name] = f"{limb}.{origin}.{comp}"
    idx = [b.pset.names.index(n) for n in sorted(ren, key=lambda n: a.pset.names.index(ren[n]))]
    assert [ren[b.pset.names[i]] for i in idx] == a.pset.names
    assert [b.classes[i] for i in idx] == a.classes
    assert np.abs(b.sensitivity[idx] - a.sensitivity).max() < 1e-9
    assert parameter_set(epr, "urdf").names == b.pset.names


def test_delta_epr_allocates_as_the_delta():
    """robots/delta_epr and robots/delta allocate alike: classes, toleranced errors, worst pose,
    tolerances (and the traditional method's) and the linear verification, to 1e-9."""
    assert_same_allocation(load_mechanism(ROOT / "robots" / "delta"), load_mechanism(EPR))


def test_delta_epr_is_what_its_script_writes():
    """robots/delta_epr is scripts/limbs_to_epr.py's output from robots/delta (kept in step)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("limbs_to_epr", ROOT / "scripts" / "limbs_to_epr.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main([str(ROOT / "robots" / "delta"), str(EPR), "--check"]) == 0


def test_legacy_rigid_constraint_models_read_as_the_anchors():
    """The Delta's stack as legacy RigidConstraintModel (CONTACT_6D / 3D): the same loops and poses."""
    mech = load_mechanism(ROOT / "robots" / "delta")
    cm = mech.constraint_models()
    actuated = [cm.model.names[1 + a] for a in cm.actuated]
    platform = cm.model.frames[cm.platform_frame].name
    home = np.concatenate([lb.home for lb in mech.limbs])
    a = tree_from_constraint_models(
        cm.model, cm.constraints, actuated, platform, mech.reference_point_m, home=home
    )
    b = tree_from_constraint_models(
        cm.model, cm.rigid_constraints(), actuated, platform, mech.reference_point_m, home=home
    )
    assert [lp.kind for lp in b.loops] == [lp.kind for lp in a.loops] == ["6d", "6d", "3d", "3d", "3d"]
    target = mech.task_space.grid()[7][None]
    qa = TreeBatch(a).inverse(target, a.home[None]).q
    qb = TreeBatch(b).inverse(target, b.home[None]).q
    assert np.abs(qa - qb).max() < 1e-12
