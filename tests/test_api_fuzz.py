# ruff: noqa: E501  (the case tables: one case per line)
"""The Python API refuses bad arguments with a PkmtolError: the seeded fuzzer and the refusals it led to.

``tests/api_fuzzing.py`` calls every public callable with one bad argument at a time; here a seeded
subset of its cases runs (``scripts/fuzz_api.py`` runs all of them). The named tests below are the
issue's examples and the silent acceptances it lists, each failing on the code before the fix.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from api_fuzzing import TARGETS, Fixtures, Target, callables_in_api, check_good_calls, fuzz

import pkmtol
from pkmtol import exceptions as E

REPO = Path(__file__).resolve().parents[1]
SEED = REPO / "robots" / "r2rps_ups"
MJCF = REPO / "tests" / "data" / "r2rps_ups_mjcf" / "robot.xml"
#: Cases of the seeded run in CI, about 5 s (``scripts/fuzz_api.py --light`` runs all 7,072 in 25–70 s).
CI_CALLS = 4000


@pytest.fixture(scope="module")
def fx(tmp_path_factory) -> Fixtures:
    return Fixtures(tmp_path_factory.mktemp("api_fuzz"))


def test_every_good_call_of_the_table_succeeds(fx) -> None:
    """A case mutates a call that works: otherwise its refusals would prove nothing."""
    assert check_good_calls(fx) == {}


def test_the_table_holds_every_public_callable() -> None:
    names = {t.name for t in TARGETS}
    in_api = callables_in_api()
    assert len(in_api) > 90
    assert in_api - names == set()


def test_seeded_fuzzing_finds_no_escape(fx) -> None:
    rep = fuzz(fx, seed=0, limit=CI_CALLS, light=True)
    assert rep.calls == CI_CALLS
    assert len(rep.targets) >= 90
    assert rep.outcomes["InvalidArgumentError"] > CI_CALLS // 2  # the checks at the top answer most
    assert rep.escapes == 0, "\n".join(f"{k}: {v[:3]}" for k, v in rep.bugs.items())
    assert rep.outcomes["HANG"] == 0, rep.slow


def test_the_fuzzer_reports_an_escape(fx, monkeypatch) -> None:
    """A callable that lets a TypeError out is counted as an escape, at its place."""

    def leaky(value: object) -> float:
        return 1.0 + value  # type: ignore[operator]

    monkeypatch.setattr("api_fuzzing.TARGETS", [Target("leaky", lambda f: (leaky, [1.0], {}))])
    rep = fuzz(fx, seed=0)
    assert rep.escapes > 0
    assert any(place.startswith("TypeError at ") for place in rep.bugs)
    assert rep.outcomes["ok"] > 0  # 5, 2.5, True … are numbers


# --- the examples ---------------------------------------------------------------------


def _case_ids(cases: list) -> list[str]:
    return [c[0] for c in cases]


CASES = [
    ("ClosedChain.inverse(None)", lambda f: f.chain.inverse(None), "target_m"),
    ("sign_off(None)", lambda f: pkmtol.sign_off(None), "result"),
    ("write_report(result, None)", lambda f: pkmtol.write_report(f.result, None), "path"),
    ("mech.constraint_models(5)", lambda f: f.mech.constraint_models(5), "models"),
    ("verify(distribution='normal')", lambda f: _verify(f, distribution="normal"), "distribution"),
    ("load_mechanism(folder, urdf_texts=5)", lambda f: pkmtol.load_mechanism(SEED, urdf_texts=5), "urdf_texts"),
    ("load_mjcf(keyframe=[])", lambda f: pkmtol.load_mjcf(MJCF, reference_point_m=[0, 0, 0.3], task_space=f.task, keyframe=[]), "keyframe"),
    ("perturbed_limb_models(mech, None)", lambda f: pkmtol.perturbed_limb_models(f.mech, None), "eps"),
    ("DrawingSettings(k=None)", lambda f: pkmtol.DrawingSettings(k=None), "DrawingSettings.k"),
    ("DrawingSettings(k=1e308)", lambda f: pkmtol.DrawingSettings(k=1e308), "DrawingSettings.k"),
    ("fosm_tolerances(betas=1e308)", lambda f: pkmtol.fosm_tolerances(np.ones(3), 5e-5, 1e308), "betas"),
    ("verify(target_m=nan)", lambda f: _verify(f, target_m=float("nan")), "target_m"),
    ("TaskSpace.sample(rng, 10**12)", lambda f: f.task.sample(np.random.default_rng(0), 10**12), "count"),
    ("search_sensitive_pose(J, 10**12, rng)", lambda f: pkmtol.search_sensitive_pose(f.grid.J, 10**12, np.random.default_rng(0)), "samples"),
    ("TreeBatch.inverse(targets, 'x')", lambda f: f.tbatch.inverse(f.points, "x"), "guesses"),
    ("HybridChain.inverse(1e308 …)", lambda f: f.hchain.inverse(np.full(3, 1e308), f.axis), "tcp_m"),
    ("sweep(mech, pset, [])", lambda f: pkmtol.sweep(f.mech, f.pset, np.zeros((0, 3))), "points_m"),
    ("write_outputs(result, 'a\\0b')", lambda f: pkmtol.write_outputs(f.result, "a\x00b"), "out_dir"),
]  # fmt: skip


def _verify(f: Fixtures, **changes: object):
    r = f.result
    col = list(r.betas).index(r.design_beta)
    kw = dict(
        mechanism=f.mech, pset=f.pset, sweep_random=f.grid, columns=r.uncompensatable,
        sigma=r.tolerances[r.uncompensatable, col], target_m=5e-5, distribution="gaussian",
        samples=50, exact_samples=0, rng=np.random.default_rng(0),
    )  # fmt: skip
    kw.update(changes)
    return pkmtol.verify(**kw)


@pytest.mark.parametrize("what, call, argument", CASES, ids=_case_ids(CASES))
def test_a_bad_argument_is_refused_by_name(fx, what, call, argument) -> None:
    with pytest.raises(E.InvalidArgumentError) as err:
        call(fx)
    assert err.value.argument == argument
    assert argument in str(err.value)


def test_verify_with_a_good_target_still_reports_its_reliability(fx) -> None:
    """The refusal of ``target_m=nan`` (which returned R = 1) leaves finite targets working."""
    v = _verify(fx)
    assert 0.0 < v.linear.reliability <= 1.0 and v.linear.samples == 50


# --- ClosedChain.forward and the joint limits -------------------------------------------------


def test_forward_refuses_an_actuator_beyond_its_limits_as_inverse_does(fx) -> None:
    chain, pose = fx.chain, fx.pose  # P at the centre of the task space: limb 1's slide at 0.65 m
    idx = chain.actuated_idx
    u = pose.q_all[idx].copy()
    u[0] = chain.lower[idx[0]] - 0.01  # 10 mm below the slide's lower limit (0.4 m)
    with pytest.raises(E.InvalidArgumentError) as err:
        chain.forward(u, pose.q_all)
    assert err.value.argument == "q_actuated"
    assert "limb1_p3" in str(err.value) and "0.39" in str(err.value) and "[0.4, 1.6]" in str(err.value)
    # an offset that takes the actual value beyond the limit is refused too
    offsets = np.zeros(pose.q_all.size)
    offsets[idx[0]] = u[0] - pose.q_all[idx[0]]
    with pytest.raises(E.InvalidArgumentError, match="limb1_p3"):
        chain.forward(pose.q_all[idx], pose.q_all, offsets)
    # the chain of a perturbed machine (check_limits=False) still drives it there
    loose = pkmtol.ClosedChain(fx.mech, check_limits=False)
    assert loose.forward(u, pose.q_all).p_m[2] < fx.target[2] - 0.1


def test_forward_within_the_limits_returns_the_inverse_pose(fx) -> None:
    chain, pose = fx.chain, fx.pose
    back = chain.forward(pose.q_all[chain.actuated_idx], pose.q_all)
    assert np.abs(back.p_m - fx.target).max() < 1e-9


# --- visual geometry --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "old, new, words",
    [
        ('<sphere radius="0.03" />', '<sphere radius="nan" />', ("<sphere> radius", "'nan'")),
        ('<sphere radius="0.03" />', '<sphere radius="inf" />', ("<sphere> radius", "'inf'")),
        ('<sphere radius="0.03" />', '<sphere radius="-0.03" />', ("<sphere> radius", "≥ 0")),
        ("<visual>\n      <geometry>", '<visual>\n      <origin xyz="0 nan 0" />\n      <geometry>', ("origin xyz",)),
    ],
)  # fmt: skip
def test_visual_geometry_that_is_not_finite_is_refused_naming_the_link(tmp_path, old, new, words) -> None:
    folder = tmp_path / "robot"
    shutil.copytree(SEED, folder)
    urdf = folder / "limb4.urdf"
    text = urdf.read_text(encoding="utf-8")
    assert old in text
    urdf.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(E.URDFError) as err:
        pkmtol.load_mechanism(folder)
    assert err.value.limb == "limb4"
    assert "link 'limb4_l1'" in str(err.value)
    for w in words:
        assert w in str(err.value)


@pytest.mark.parametrize(
    "new, words",
    [
        ('type="sphere" size="nan"', ("size = 'nan'", "≥ 0")),
        ('type="sphere" size="0.03" pos="0 inf 0"', ("pos = '0 inf 0'",)),
    ],
)
def test_mjcf_geometry_that_is_not_finite_is_refused_naming_the_body(tmp_path, new, words) -> None:
    folder = tmp_path / "mjcf"
    shutil.copytree(MJCF.parent, folder)
    xml = folder / "robot.xml"
    text = xml.read_text(encoding="utf-8")
    old = 'type="sphere" size="0.03"'
    assert old in text
    xml.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(E.MJCFError) as err:
        pkmtol.load_mechanism(folder)
    assert "'limb1_l1'" in str(err.value) and "<geom 'limb1_l1_visual'>" in str(err.value)
    for w in words:
        assert w in str(err.value)


def test_hybrid_forward_refuses_a_wrist_joint_beyond_its_limits(fx) -> None:
    h, home = fx.hchain, fx.hhome
    u = home.module.q_all[h.chain.actuated_idx]
    q = home.q_tool.copy()
    q[0] = h._upper[0] + 0.1  # wrist_c 0.1 rad beyond π
    with pytest.raises(E.JointLimitError) as err:
        h.forward(u, q, home.module.q_all)
    assert err.value.joint == "wrist_c" and err.value.value == pytest.approx(np.pi + 0.1)
    pose, oMt = h.forward(u, home.q_tool, home.module.q_all)  # at home: the home TCP
    assert np.abs(oMt.translation - home.oMt.translation).max() < 1e-9


# --- TreeChain.forward / TreeBatch.forward and the joint limits (as ClosedChain.forward) -------


def test_tree_forward_refuses_an_actuator_beyond_its_limits_as_closed_chain_does(fx) -> None:
    chain, home = fx.tchain, fx.tchain.home()
    idx = chain.batch.actuated_idx
    u = home[idx].copy()
    u[0] = chain.batch.lower[idx[0]] - 0.01  # 10 mm below the slide's lower limit (0.4 m)
    with pytest.raises(E.InvalidArgumentError) as err:
        chain.forward(u, home)
    assert err.value.argument == "q_actuated"
    words = str(err.value)
    assert "limb1_p3" in words and "0.39" in words and "[0.4, 1.6]" in words and "check_limits=False" in words
    # the batch names the problem; an offset that takes the actual value beyond the limit is refused too
    offsets = np.zeros((2, home.size))
    offsets[1, idx[0]] = u[0] - home[idx[0]]
    with pytest.raises(E.InvalidArgumentError, match=r"row 1, entry 0, actuator 'limb1_p3'"):
        chain.batch.forward(np.tile(home[idx], (2, 1)), np.tile(home, (2, 1)), offsets)
    # a solver built with check_limits=False (a perturbed machine) still drives it there
    loose = pkmtol.TreeBatch(fx.tree, check_limits=False)
    sols = loose.forward(u[None], home[None])
    assert sols.errors[0] is None and np.isclose(sols.q[0, idx[0]], 0.39)


def test_tree_forward_gives_a_joint_limit_error_for_a_passive_joint_beyond_its_limits(fx) -> None:
    batch = pkmtol.TreeBatch(fx.tree)
    home = batch.chain.home()
    idx = batch.actuated_idx
    passive = next(i for i in range(home.size) if i not in set(idx.tolist()) and abs(home[i]) > 1e-3)
    batch.upper = batch.upper.copy()
    batch.upper[passive] = home[passive] - 1e-3  # the solution at home is now beyond it
    sols = batch.forward(np.tile(home[idx], (2, 1)), np.tile(home, (2, 1)))
    assert all(isinstance(e, E.JointLimitError) for e in sols.errors)
    assert sols.errors[0].joint == fx.tree.joint_names[passive]
    with pytest.raises(E.JointLimitError):
        batch.chain.forward(home[idx], home)
    back = fx.tchain.forward(home[idx], home)  # the unchanged solver: the home pose, within limits
    assert np.abs(back.q_all - home).max() < 1e-9
