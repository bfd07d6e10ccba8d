"""The study's honest figures: machine-level intervals, unconverged machines, linear validity, plans."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pkmtol.calibration.study as study_mod
from pkmtol.calibration.intervals import machine_bootstrap
from pkmtol.calibration.plan import candidate_pool
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.calibration.study import LINEAR_WARNING, CaseResult, ErrorSummary, StudyCase
from pkmtol.calibration.workflow import design_sigma, machine_plans, simulate
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import CalibrationError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism
from pkmtol.present.calibration_tables import study_json, study_text
from pkmtol.statistics import wilson_interval

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def seed():
    mech = load_mechanism(ROOT / "robots" / "r2rps_ups")
    pset = parameter_set(mech, "dh")
    classes = sweep(mech, pset, mech.task_space.grid(), ClosedChain(mech)).classify()
    settings = CalibrationSettings(candidates=40, poses=20)
    sigma = design_sigma(pset, classes, settings, None)
    sigma[[i for i, c in enumerate(classes) if c == "uncompensatable"]] = 2e-5
    return mech, pset, classes, settings, sigma


def _study(seed, machines, **kw):
    mech, pset, classes, settings, sigma = seed
    return simulate(
        mech,
        pset,
        classes,
        settings,
        sigma,
        mech.target_m,
        machines=machines,
        holdout=15,
        controllers=("compensatable",),
        selections=kw.pop("selections", ("d-optimal",)),
        **kw,
    )


def test_machine_bootstrap_is_wider_than_treating_every_pose_as_independent():
    """All failures on 2 of 20 machines: the pooled Wilson interval is far too narrow."""
    failed = np.zeros((20, 200), dtype=bool)
    failed[3, :120] = failed[11, :80] = True
    valid = np.ones_like(failed)
    f, lo, hi = machine_bootstrap(failed, valid)
    w_lo, w_hi = wilson_interval(int(failed.sum()), failed.size)
    assert f == pytest.approx(0.05)
    assert lo <= w_lo and hi > 2 * w_hi  # the Wilson interval ends near 5.7 %, the machines' near 12 %
    assert machine_bootstrap(np.zeros((100, 5), dtype=bool), np.ones((100, 5), dtype=bool)) == pytest.approx(
        (0.0, 0.0, 1 - 0.05 ** (1 / 100))
    )


def test_unconverged_machines_are_named_and_left_out(seed, monkeypatch):
    real = study_mod.identify_with
    calls = {"n": 0}

    def flaky(*a, **k):
        out = real(*a, **k)
        calls["n"] += 1
        if calls["n"] == 2:  # the second machine's fit "does not converge"
            return study_mod.Identification(**{**out.__dict__, "converged": False})
        return out

    monkeypatch.setattr(study_mod, "identify_with", flaky)
    rep = _study(seed, 12)
    case = rep.study.cases[0]
    assert [k for k, _ in case.unconverged] == [1]
    assert case.exact.machines == 11 and case.exact.dlambda_m.size == 11 * 15
    text = study_text(rep)
    assert "1 of 12 machines left out" in text and "#1" in text
    assert study_json(rep)["cases"][0]["unconverged_machines"][0]["machine"] == 1


def test_a_study_where_many_machines_do_not_converge_fails(seed, monkeypatch):
    monkeypatch.setattr("pkmtol.calibration.gauss_newton.MAX_ITERATIONS", 1)
    with pytest.raises(CalibrationError, match=r"did not converge \(#0, #1"):
        _study(seed, 4)


def test_a_linear_row_far_from_its_exact_row_is_flagged():
    rng = np.random.default_rng(0)
    d = np.abs(rng.normal(20e-6, 5e-6, 400))

    def row(x):
        return ErrorSummary("r", x, np.full(x.size, np.nan), np.full(x.size, np.nan), 50e-6, 4)

    case = CaseResult(
        StudyCase("compensatable", "d-optimal", 10), None, row(d), row(d * 1.2), np.ones(4), np.ones(4), 0.0
    )
    assert not case.linear_valid and case.linear_gap_m > 2.5e-6
    near = CaseResult(
        StudyCase("compensatable", "d-optimal", 10), None, row(d), row(d + 1e-6), np.ones(4), np.ones(4), 0.0
    )
    assert near.linear_valid
    assert LINEAR_WARNING == "linear model not valid here; use the exact figure"


def test_machine_plans_differ_from_machine_to_machine(seed):
    mech, pset, classes, settings, sigma = seed
    pool = candidate_pool(mech, pset, settings, ClosedChain(mech))
    for how in ("random", "d-optimal"):
        plans = machine_plans(mech, pset, classes, settings, pool, sigma, how, 3)
        assert len({tuple(p.chosen) for p in plans}) == 3 and all(p.poses == 20 for p in plans)


def test_plans_per_machine_give_every_machine_its_own_plan_and_the_spread(seed):
    rep = _study(seed, 4, plans_per_machine=True, selections=("random",))
    case = rep.study.cases[0]
    assert rep.study.plans_per_machine and len(case.plan_spread) == 4
    text = study_text(rep)
    assert "plan-to-plan spread" in text and "a new plan per machine" in text
