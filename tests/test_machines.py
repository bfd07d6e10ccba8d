"""The machines of the paper's introduction: the structure the theory predicts for each.

* Tricept (3-UPS&UP): the UPS legs exert no constraint; only the passive UP limb carries
  uncompensatable errors.
* Sprint Z3 (3-PRS): each PRS limb exerts exactly one constraint force (through its S centre,
  along its R axis) and uncompensatable errors lie in all three limbs.
* Exechon (2-UPR&SPR): 3 actuation + 5 constraint wrenches of rank 6 — linearly dependent, the
  redundancy reported; the pose error is the least-squares solution and the rest (assembly error)
  reported per parameter (docs/theory.md, docs/robots.md).

The grid sweeps are shared per machine and parameter set (module scope).
"""

from __future__ import annotations

import sys
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from truth_checks import compensatable_residual_ratios

from pkmtol.design.job import DesignOptions, allocate
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.separation import null_space
from pkmtol.error_model.sweep import sweep
from pkmtol.kinematics.check import check_mechanism
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.families import draft
from pkmtol.model.loader import load_mechanism
from pkmtol.present.tables import summary_text, to_json_dict

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
from dh_to_urdf import generate  # noqa: E402

MACHINES = ("tricept", "sprint_z3", "exechon")
CONSTRAINTS = {"tricept": [0, 0, 0, 3], "sprint_z3": [1, 1, 1], "exechon": [2, 1, 2]}


@cache
def machine(name: str):
    mech = load_mechanism(REPO / "robots" / name)
    return mech, ClosedChain(mech)


@cache
def grid_sweep(name: str, kind: str):
    mech, chain = machine(name)
    ps = parameter_set(mech, kind)
    sw = sweep(mech, ps, mech.task_space.grid(), chain)
    return ps, sw, sw.classify()


def limbs_with(name: str, kind: str, cls: str) -> set[str]:
    mech, _ = machine(name)
    ps, _, classes = grid_sweep(name, kind)
    return {mech.limbs[ps.parameters[i].limb].name for i, c in enumerate(classes) if c == cls}


# --- every machine --------------------------------------------------------------------------


@pytest.mark.parametrize("name", MACHINES)
def test_tables_are_the_derived_ones_and_urdfs_are_generated(name):
    """mechanism.toml holds what the family derives from its dimensions; the URDFs are dh_to_urdf.py's."""
    mech, _ = machine(name)
    derived = draft(name).limbs
    assert [d.name for d in derived] == [lb.name for lb in mech.limbs]
    for d, limb in zip(derived, mech.limbs, strict=True):
        np.testing.assert_allclose(limb.dh.links, d.table.links, atol=1e-7)
        np.testing.assert_allclose(limb.dh.end, d.table.end, atol=1e-7)
        np.testing.assert_allclose(limb.home, d.home, atol=5e-6)
    for path, text in generate(REPO / "robots" / name).items():
        assert path.read_text(encoding="utf-8") == text, f"{path} is stale: run scripts/dh_to_urdf.py"


@pytest.mark.parametrize("name", MACHINES)
def test_check_mobility_constraints_and_reach(name):
    mech, _ = machine(name)
    rep = check_mechanism(mech)
    assert rep.mobility == mech.n_actuators == 3
    assert [lb.constraint_count for lb in rep.limbs] == CONSTRAINTS[name]
    assert rep.n_reachable == len(rep.points) == 147
    assert not rep.problems


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("kind", ["dh", "urdf"])
def test_actuator_offsets_are_compensatable(name, kind):
    ps, _, classes = grid_sweep(name, kind)
    act = [c for p, c in zip(ps.parameters, classes, strict=True) if p.actuator]
    assert act == ["compensatable"] * 3


# --- Tricept ----------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["dh", "urdf"])
def test_tricept_only_the_passive_up_limb_is_uncompensatable(kind):
    assert limbs_with("tricept", kind, "uncompensatable") == {"centre"}
    _, sw, classes = grid_sweep("tricept", kind)
    assert sw.redundancy == 0
    if kind == "dh":  # the 14 structure errors of the UP limb: Table IV of the seed's limb 4
        from test_error_model import TABLE_IV_ETA_C

        ps, _, _ = grid_sweep("tricept", kind)
        assert [n for n, c in zip(ps.names, classes, strict=True) if c == "uncompensatable"] == TABLE_IV_ETA_C


# --- Sprint Z3 --------------------------------------------------------------------------------


def test_sprint_z3_one_constraint_force_per_limb_through_s_along_r():
    mech, _ = machine("sprint_z3")
    _, sw, _ = grid_sweep("sprint_z3", "urdf")
    assert sw.redundancy == 0
    for sep in sw.separations:
        assert sorted(sep.constraint_limb.tolist()) == [0, 1, 2]
        o = sep.pose.oMp.translation
        for k, i in enumerate(sep.constraint_limb):
            limb = mech.limbs[i]
            data = limb.model.createData()
            pin.forwardKinematics(limb.model, data, sep.pose.q[i])
            r_axis = data.oMi[2].rotation[:, 2]  # joint 2: the R on the slider
            s_centre = data.oMi[3].translation  # joints 3-5: the S
            w = sep.W_c[:, k]
            f, tau = w[:3], w[3:]
            assert np.linalg.norm(f) > 0.5  # a force (W_c columns are unit 6-vectors)
            assert np.linalg.norm(np.cross(f, r_axis)) < 1e-9  # along the R axis
            np.testing.assert_allclose(tau, np.cross(s_centre - o, f), atol=1e-9)  # through the S centre


@pytest.mark.parametrize("kind", ["dh", "urdf"])
def test_sprint_z3_uncompensatable_errors_in_all_three_limbs(kind):
    assert limbs_with("sprint_z3", kind, "uncompensatable") == {"leg1", "leg2", "leg3"}


@pytest.mark.parametrize("kind", ["dh", "urdf"])
def test_sprint_z3_compensatable_errors_vanish_after_correction(kind):
    """Limbs both actuated and constrained: with the documented actuation-wrench choice, errors
    classed compensatable leave ≤ 1e-3 of their pose error after Eq. 25 (exact kinematics)."""
    mech, chain = machine("sprint_z3")
    ps, _, classes = grid_sweep("sprint_z3", kind)
    rng = np.random.default_rng(11)
    ratios = compensatable_residual_ratios(mech, chain, ps, classes, mech.task_space.sample(rng, 5), rng)
    assert max(ratios) <= 1e-3


# --- Exechon ----------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["dh", "urdf"])
def test_exechon_wrenches_are_dependent_and_the_redundancy_reported(kind):
    ps, sw, _ = grid_sweep("exechon", kind)
    assert sw.redundancy == 2
    for sep in sw.separations:
        assert sep.W_a.shape == (6, 3) and sep.W_c.shape == (6, 5)
        assert sep.constraint_limb.tolist() == [0, 0, 1, 2, 2]
        assert np.linalg.matrix_rank(sep.W_c, tol=1e-9) == 3  # 5 constraint wrenches, rank 3
        W = np.hstack([sep.W_a, sep.W_c])
        assert np.linalg.matrix_rank(W, tol=1e-9) == 6
        assert sep.redundancy == 2
        # least squares: the twist explains Y up to the incompatible part, which is orthogonal to
        # everything a rigid motion can produce and has the rank of the redundancy
        Y = np.vstack([sep.Y_a, sep.Y_c])
        np.testing.assert_allclose(W.T @ sep.twist_map + sep.incompatible_map, Y, atol=1e-12)
        np.testing.assert_allclose(W @ sep.incompatible_map, 0.0, atol=1e-10)
        s = np.linalg.svd(sep.incompatible_map, compute_uv=False)
        assert int(np.sum(s > 1e-9 * s[0])) == 2


def test_exechon_assembly_errors_are_the_upr_loop_conditions():
    """The SPR leg's errors are all compatible; in the UPR legs the slide not ⟂ the U's second axis
    (δφ_3) and the platform R not parallel to it (δθ_4, δφ_4) are pure assembly errors, and the
    base U-axis errors are compatible only when both UPR legs' axes move together."""
    mech, _ = machine("exechon")
    ps, sw, _ = grid_sweep("exechon", "dh")
    inc = sw.incompatible()
    assert not any(inc[i] for i, p in enumerate(ps.parameters) if mech.limbs[p.limb].name == "leg2")
    assert int(inc.sum()) == 24
    compatible = null_space(np.vstack([s.incompatible_map for s in sw.separations]))
    assert compatible.shape[1] == len(ps) - 14  # 14 independent assembly conditions over the grid
    part = np.linalg.norm(compatible.T, axis=0)  # size of each parameter's compatible part
    for leg in (1, 3):
        for sym in (f"δφ_{{3,{leg}}}", f"δθ_{{4,{leg}}}", f"δφ_{{4,{leg}}}"):
            assert part[ps.names.index(sym)] < 1e-9, sym
        for sym in ("δθ", "δd", "δa", "δφ"):
            assert part[ps.names.index(f"{sym}_{{1,{leg}}}")] == pytest.approx(np.sqrt(0.5), abs=1e-6)
    both = np.zeros(len(ps))
    both[[ps.names.index("δd_{1,1}"), ps.names.index("δd_{1,3}")]] = 1.0  # lift both U axes
    assert np.linalg.norm(compatible.T @ both) == pytest.approx(np.sqrt(2.0))


def test_exechon_allocate_runs_and_reports_the_overconstraint():
    mech, _ = machine("exechon")
    opts = DesignOptions(samples=300, verification_poses=20, exact_samples=2, claim_poses=20, seed=1)
    result = allocate(mech, opts)
    text = summary_text(result)
    assert "over-constrained: redundancy 2" in text
    doc = to_json_dict(result)
    assert doc["redundancy"] == 2
    assert sum(p["assembly_error"] for p in doc["parameters"]) == 24
    # random errors include assembly errors: exact kinematics cannot close them, reported as such
    assert all(v.exact_unassembled == 2 and v.exact is None for v in result.verification.values())
