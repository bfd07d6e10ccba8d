"""Hybrid machines: the tool chain, the machine's inverse kinematics and its derivatives (docs/hybrid.md)."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hybrid_checks import error_twist

from pkmtol import load_mechanism
from pkmtol.error_model.tool_chain import hybrid_parameter_set
from pkmtol.error_model.tool_sweep import hybrid_sweep, tool_task_grid, tool_task_sample
from pkmtol.exceptions import MechanismFormatError, UnknownJointError, URDFError
from pkmtol.kinematics.hybrid import HybridChain
from pkmtol.kinematics.hybrid_continuation import hybrid_continuation
from pkmtol.kinematics.tool_chain import ToolKinematics, perturbed_tool_model, tool_frames, tool_regressor

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
SEED = ROBOTS / "r2rps_ups_wrist"
HYBRIDS = ["r2rps_ups_wrist", "tricept_wrist"]


@pytest.fixture(scope="module")
def seed():
    return load_mechanism(SEED)


def test_stacked_tool_kinematics_are_pinocchios(seed) -> None:
    q = np.random.default_rng(0).uniform(-2.0, 2.0, (6, seed.tool.nq))
    rot, pos, jac = ToolKinematics(seed.tool).frames(q)
    data = seed.tool.model.createData()
    for k in range(len(q)):
        pmt, j = tool_frames(seed.tool, seed.tool.model, data, q[k])
        assert np.abs(pmt.rotation - rot[k]).max() < 1e-14
        assert np.abs(pmt.translation - pos[k]).max() < 1e-14
        assert np.abs(j - jac[k]).max() < 1e-14


def test_tool_regressor_matches_finite_differences(seed) -> None:
    tool = seed.tool
    q = np.array([0.4, 0.7])
    data = tool.model.createData()
    cols = tool_regressor(tool, tool.model, data, q)
    x0 = tool_frames(tool, tool.model, data, q)[0]
    h = 1e-7
    n_eps = 6 * (tool.nq + 1)
    assert cols.shape == (6, n_eps + tool.nq)
    for k in range(cols.shape[1]):
        raw = np.zeros(cols.shape[1])
        raw[k] = h
        model = perturbed_tool_model(tool, raw[:n_eps])
        x = tool_frames(tool, model, model.createData(), q + raw[n_eps:])[0]
        fd = pin.log6(x0.actInv(x)).vector / h
        assert np.abs(fd - cols[:, k]).max() < 1e-6, k


@pytest.mark.parametrize("name", HYBRIDS)
def test_twist_jacobian_and_module_tangent_match_finite_differences(name) -> None:
    mech = load_mechanism(ROBOTS / name)
    hc = HybridChain(mech)
    tcp, axes = tool_task_grid(mech)
    pose = hc.inverse(tcp[30], axes[30], hc.home())
    h = 1e-6
    for k in range(3):
        dp = np.eye(3)[k] * h
        moved = hc.chain.inverse(pose.module.p_m + dp, pose.module.q_all)
        assert np.abs((moved.q_all - pose.module.q_all) / h - pose.tangent[:, k]).max() < 1e-5
        x = hc.evaluate(moved, pose.q_tool).oMt
        assert np.abs(error_twist(pose.oMt, x) / h - pose.twist_jacobian[:, k]).max() < 1e-5
    for j, a in enumerate(mech.tool.actuated):
        q = pose.q_tool.copy()
        q[a] += h
        x = hc.evaluate(pose.module, q).oMt
        assert np.abs(error_twist(pose.oMt, x) / h - pose.twist_jacobian[:, 3 + j]).max() < 1e-5


@pytest.mark.parametrize("name", HYBRIDS)
def test_inverse_kinematics_reaches_every_target_per_pose_and_batched(name) -> None:
    mech = load_mechanism(ROBOTS / name)
    hc = HybridChain(mech)
    tcp, axes = tool_task_grid(mech)
    batched = hybrid_continuation(hc, tcp, axes)
    assert len(batched) == len(tcp) == 75 * 7
    for k in (0, 77, 300, 524):
        b = batched[k]
        one = hc.inverse(tcp[k], axes[k], batched[0])
        assert np.abs(b.tcp_m - tcp[k]).max() < 1e-11 and np.abs(b.axis - axes[k]).max() < 1e-11
        assert np.abs(one.module.q_all - b.module.q_all).max() < 1e-9
        assert np.abs(one.q_tool - b.q_tool).max() < 1e-9
    worst = max(
        max(np.abs(s.tcp_m - t).max(), np.abs(s.axis - a).max())
        for s, t, a in zip(batched, tcp, axes, strict=True)
    )
    assert worst < 1e-11
    assert max(s.condition for s in batched) < 100.0  # no singular pose (A stays away from its pole)


def test_tool_length_moves_the_tcp_along_the_tool_axis(seed) -> None:
    hc = HybridChain(seed)
    pose = hc.home()
    longer = dataclasses.replace(seed, tool=seed.tool.with_length(0.25))
    moved = HybridChain(longer).evaluate(pose.module, pose.q_tool)
    assert np.abs(moved.tcp_m - pose.tcp_m - 0.1 * pose.axis).max() < 1e-15
    assert seed.tool.length_m == 0.15


def test_tool_directions_grid_and_sample_lie_in_the_cone(seed) -> None:
    cone = seed.tool_directions
    g = cone.grid()
    a = np.array(cone.axis)
    assert g.shape == (7, 3) and np.allclose(np.linalg.norm(g, axis=1), 1.0)
    assert np.allclose(np.degrees(np.arccos(np.clip(g[1:] @ a, -1, 1))), 15.0)
    tcp, axes = tool_task_sample(seed, np.random.default_rng(1), 4000)
    ang = np.degrees(np.arccos(np.clip(axes @ a, -1, 1)))
    assert ang.max() <= 15.0 + 1e-9 and ang.min() >= 0.0
    # uniform over the cap: half the solid angle lies within acos((1 + cos 15°)/2)
    half = np.degrees(np.arccos((1 + np.cos(np.radians(15.0))) / 2))
    assert abs(np.mean(ang <= half) - 0.5) < 0.03
    assert tcp.shape == (4000, 3)


def test_parameters_name_their_sub_assembly(seed) -> None:
    ps = hybrid_parameter_set(seed, "urdf")
    names = ps.names
    tool_part = names[ps.tool_slice]
    assert tool_part[:6] == [f"wrist.wrist_c.{c}" for c in ("dx", "dy", "dz", "rx", "ry", "rz")]
    assert "tool.tcp.dz" in tool_part and "wrist.wrist_a.offset" in tool_part
    groups = {ps.sub_assembly(i) for i in range(len(ps))}
    assert groups == {"module", "wrist", "tool"}
    assert ps.sub_assembly(names.index("tool.tcp.dz")) == "tool"
    assert ps.sub_assembly(names.index("wrist.wrist_a.offset")) == "wrist"
    assert ps.parameters[names.index("wrist.wrist_a.offset")].actuator


def test_classes_of_the_seed_hybrid(seed) -> None:
    """Wrist free: every error reaching the task is compensatable; the module's split leaves 14 + tool."""
    ps = hybrid_parameter_set(seed, "dh")
    tcp, axes = tool_task_grid(seed)
    idx = np.arange(0, len(tcp), 25)
    machine = hybrid_sweep(seed, ps, tcp[idx], axes[idx]).classify()
    module = hybrid_sweep(seed, ps, tcp[idx], axes[idx], scope="module").classify()
    assert machine.count("uncompensatable") == 0
    n0 = ps.module_count
    # the module's own uncompensatable errors (Table IV: limb 4's 14) stay so under its own split
    assert module[:n0].count("uncompensatable") == 14
    assert module.count("absorbed") == machine.count("absorbed")
    assert machine[ps.names.index("wrist.δθ_e")] == "absorbed"  # the spin about the tool axis


def _variant(tmp_path: Path, edit) -> Path:
    dst = tmp_path / "robot"
    shutil.copytree(SEED, dst)
    text = (dst / "mechanism.toml").read_text()
    (dst / "mechanism.toml").write_text(edit(text))
    return dst


@pytest.mark.parametrize(
    ("edit", "error", "words"),
    [
        (
            lambda t: t.replace('kind = "tool"', 'kind = "position"'),
            MechanismFormatError,
            "task.kind = 'tool'",
        ),
        (
            lambda t: t.replace('nose_frame = "spindle_nose"', 'nose_frame = "nose"'),
            URDFError,
            "spindle nose",
        ),
        (
            lambda t: t.replace('actuated = ["wrist_c", "wrist_a"]', 'actuated = ["wrist_c"]'),
            URDFError,
            "neither",
        ),
        (
            lambda t: t.replace('actuated = ["wrist_c", "wrist_a"]', 'actuated = ["wrist_c", "wrist_b"]'),
            UnknownJointError,
            "wrist_b",
        ),
        (lambda t: t.replace('length = "150 mm"', "length = 0.15"), MechanismFormatError, "unit"),
        (lambda t: t.replace('cone = "15 deg"', 'cone = "95 deg"'), MechanismFormatError, "half-angle"),
        (
            lambda t: t.replace(
                'actuated = ["wrist_c", "wrist_a"]', 'actuated = ["wrist_c"]\nlocked = { wrist_a = "45 deg" }'
            ),
            MechanismFormatError,
            "actuate 0 or 2",
        ),
        (
            lambda t: t.replace(
                'actuated = ["wrist_c", "wrist_a"]',
                'actuated = []\nlocked = { wrist_a = "45 deg", wrist_c = "90 deg" }',
            ),
            MechanismFormatError,
            "locked",
        ),
    ],
)
def test_bad_tool_tables_get_named_errors(tmp_path, edit, error, words) -> None:
    with pytest.raises(error, match=words):
        load_mechanism(_variant(tmp_path, edit))


def test_locked_wrist_is_a_three_row_task(tmp_path) -> None:
    def lock(t: str) -> str:
        t = t.replace(
            'actuated = ["wrist_c", "wrist_a"]',
            'actuated = []\nlocked = { wrist_a = "45 deg", wrist_c = "90 deg" }',
        )
        t = t.replace("axis = [0.70710678, 0.0, 0.70710678]", "").replace('cone = "15 deg"', "")
        return t.replace("rings = [6]                # the axis", "# rings: the axis")

    mech = load_mechanism(_variant(tmp_path, lock))
    assert mech.tool.actuated == () and mech.tool_directions is None
    hc = HybridChain(mech)
    assert hc.rows == 3
    tcp, axes = tool_task_grid(mech)
    assert axes is None and len(tcp) == 75
    pose = hc.inverse(tcp[5])
    assert np.abs(pose.tcp_m - tcp[5]).max() < 1e-11
    assert np.allclose(np.degrees(pose.q_tool), [90.0, 45.0])


def test_decoupled_and_general_inverse_kinematics_agree(seed) -> None:
    """The seed's wrist meets at P (one module solve a pose); the general Newton finds the same poses."""
    fast = HybridChain(seed)
    assert fast.wrist_offset_m == pytest.approx(0.27, abs=1e-12)  # A axis → nose 0.12 m + tool 0.15 m
    general = HybridChain(seed)
    general.wrist_offset_m = None
    tcp, axes = tool_task_grid(seed)
    idx = np.arange(0, len(tcp), 9)
    a = hybrid_continuation(fast, tcp[idx], axes[idx])
    b = hybrid_continuation(general, tcp[idx], axes[idx])
    for x, y in zip(a, b, strict=True):
        assert np.abs(x.module.q_all - y.module.q_all).max() < 1e-9
        assert np.abs(x.q_tool - y.q_tool).max() < 1e-9
    one = fast.inverse(tcp[40], axes[40], a[0])
    assert np.abs(one.tcp_m - tcp[40]).max() < 1e-11 and np.abs(one.axis - axes[40]).max() < 1e-11


def test_a_wrist_with_offsets_takes_the_general_newton(tmp_path) -> None:
    """A spindle 20 mm off the A axis: the TCP is no longer on a line through P, so no decoupling."""

    def offset(text: str) -> str:  # the URDF is edited, so it is no longer its [tool.dh] table's
        start = text.index("[tool.dh]")
        end = text.index("limits = [[-180.0, 180.0], [-100.0, 100.0]]", start)
        return text[:start] + text[text.index("\n", end) :]

    folder = _variant(tmp_path, offset)
    urdf = (folder / "wrist.urdf").read_text()
    moved = urdf.replace('<origin xyz="0 0.12 0"', '<origin xyz="0.02 0.12 0"')
    assert moved != urdf
    (folder / "wrist.urdf").write_text(moved)
    mech = load_mechanism(folder)
    hc = HybridChain(mech)
    assert hc.wrist_offset_m is None
    tcp, axes = tool_task_grid(mech)
    idx = np.arange(0, len(tcp), 13)
    sols = hybrid_continuation(hc, tcp[idx], axes[idx])
    for s, t, a in zip(sols, tcp[idx], axes[idx], strict=True):
        assert np.abs(s.tcp_m - t).max() < 1e-11 and np.abs(s.axis - a).max() < 1e-11
    one = hc.inverse(tcp[idx][3], axes[idx][3], sols[0])
    assert np.abs(one.q_tool - sols[3].q_tool).max() < 1e-9


def test_wrist_dh_columns_match_finite_differences_of_its_table(seed) -> None:
    """The wrist's D–H parameters (``[tool.dh]``) are the table's own: each column against the table
    perturbed by 1e-7 and its forward kinematics (the TCP ``length`` beyond the nose)."""
    from pkmtol.model.dh import DHTable, forward

    ps = hybrid_parameter_set(seed, "dh")
    tool, t = seed.tool, seed.tool.dh
    q = np.array([0.4, 0.9])
    cols = tool_regressor(tool, tool.model, tool.model.createData(), q) @ ps.tool_selection
    tcp = pin.SE3(np.eye(3), np.array([0.0, 0.0, tool.length_m]))
    x0 = forward(t, q) * tcp
    h, k = 1e-7, 0
    for j in range(len(t.links)):
        for c in range(4):
            links = t.links.copy()
            links[j, c] += h
            x = forward(DHTable(links, t.end, t.joint_types, t.joint_names, t.limits), q) * tcp
            assert np.abs(pin.log6(x0.actInv(x)).vector / h - cols[:, k]).max() < 1e-6, ps.names[
                ps.tool_slice
            ][k]
            k += 1
    for e in range(2):
        end = list(t.end)
        end[e] += h
        x = forward(DHTable(t.links, (end[0], end[1]), t.joint_types, t.joint_names, t.limits), q) * tcp
        assert np.abs(pin.log6(x0.actInv(x)).vector / h - cols[:, k]).max() < 1e-6
        k += 1
    assert ps.names[ps.tool_slice][k:] == [
        "tool.tcp.dx",
        "tool.tcp.dy",
        "tool.tcp.dz",
        "tool.tcp.rx",
        "tool.tcp.ry",
    ]


def test_pkmtol_new_writes_a_checked_hybrid_variant(tmp_path) -> None:
    from pkmtol.kinematics.robot_folder import new_robot

    made = new_robot("r2rps_ups_wrist", tmp_path / "h", tool_length=0.2, nose=0.1)
    assert [p.name for p in made.files] == [
        "mechanism.toml",
        "limb1.urdf",
        "limb2.urdf",
        "limb3.urdf",
        "limb4.urdf",
        "wrist.urdf",
    ]
    assert not made.report.problems and made.report.tool is not None
    mech = load_mechanism(made.folder)
    assert mech.tool.length_m == pytest.approx(0.2) and mech.tool.dh is not None
    assert HybridChain(mech).wrist_offset_m == pytest.approx(0.3, abs=1e-12)  # nose 0.1 + tool 0.2
