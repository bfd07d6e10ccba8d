"""The fit check names its cause for every instrument it applies to (issue 25).

A ballbar's lengths and a tracker's points in its own (identified) frame get the causes a
registered tracker has: all-zero values, a unit (1/1000, 1/25.4 …), the same value at every pose,
then outliers; a probe's touches (no measured value) the outliers. The first three are found before
any fit (:func:`data_verdict`), so ``pkmtol calibrate`` refuses such a file without fitting it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol.calibration.fit_check import PoorFitError, data_verdict, fit_verdict
from pkmtol.calibration.identification import machine_poses
from pkmtol.calibration.instrument_files import instrument_csv
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.measurement_files import measurements_csv
from pkmtol.calibration.plan import candidate_pool, make_plan
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.cli import main, run
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import InvalidRequestError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
NOISE = 1e-5  # [m]
RNG = np.random.default_rng(7)
#: Nominal points spread over a task space (30 poses) [m], and lengths about a 150 mm bar [m].
POINTS = RNG.uniform([-0.6, -0.6, 0.9], [0.6, 0.6, 1.2], size=(30, 1, 3))
LENGTHS = 0.15 + RNG.uniform(-2e-3, 2e-3, size=(30, 1))
#: A tracker frame: turned by 0.7 rad about a tilted axis, 2 m away.
FRAME = pin.exp6(np.array([2.0, -1.0, 0.5, 0.3, -0.5, 0.4]))


def _in_frame(p: np.ndarray) -> np.ndarray:
    return (p.reshape(-1, 3) @ FRAME.rotation.T + FRAME.translation).reshape(p.shape)


@pytest.mark.parametrize(
    "values, measured, nominal, cause, words",
    [
        ("distances", 0 * LENGTHS, LENGTHS, "zeros", "every measured length is 0"),
        ("distances", LENGTHS / 1e3, LENGTHS, "units", "metres written under [mm]"),
        ("distances", LENGTHS / 25.4, LENGTHS, "units", "inches written under [mm]"),
        ("distances", 0 * LENGTHS + LENGTHS[0], LENGTHS, "repeated point", "the same length"),
        ("frame points", 0 * POINTS, POINTS, "zeros", "every measured coordinate is 0"),
        ("frame points", _in_frame(POINTS / 1e3), POINTS, "units", "1/1000 of"),
        ("frame points", _in_frame(POINTS * 25.4), POINTS, "units", "from inches to millimetres twice"),
        ("frame points", 0 * POINTS + _in_frame(POINTS)[0], POINTS, "repeated point", "the same point"),
        ("points", POINTS / 1e3, POINTS, "units", "metres written under [mm]"),
        ("points", POINTS * 1e3, POINTS, "units", "or micrometres under [mm]"),
    ],
)  # fmt: skip
def test_values_that_cannot_be_right_are_named_before_any_fit(
    values, measured, nominal, cause, words
) -> None:
    verdict = data_verdict(measured, nominal, NOISE, values)
    assert verdict.poor and verdict.cause == cause, verdict.problem
    assert words in verdict.problem and "before any fit" in verdict.problem
    # and after a fit that did not converge, the same cause (not "outliers")
    after = fit_verdict(
        False, 40, 1e-2, NOISE, measured - nominal, measured, measured - nominal, values=values
    )
    assert after.poor and after.cause == cause


@pytest.mark.parametrize(
    "values, measured, nominal",
    [
        ("distances", LENGTHS + 3e-6, LENGTHS),  # a good ballbar session: µm from nominal
        ("frame points", _in_frame(POINTS), POINTS),  # a tracker anywhere: its frame is identified
        ("points", POINTS + 2e-5, POINTS),
        ("", POINTS / 1e3, POINTS),  # a probe's values (the artifact's radius): no such cause
    ],
)
def test_good_values_or_an_instrument_without_such_causes_go_to_the_fit(values, measured, nominal) -> None:
    assert not data_verdict(measured, nominal, NOISE, values).poor


def test_a_registered_tracker_check_does_not_take_a_moved_frame_for_a_unit() -> None:
    """The registered check compares coordinates; the frame check compares spreads (a frame keeps them)."""
    moved = _in_frame(POINTS)
    assert not data_verdict(moved, POINTS, NOISE, "points").poor  # an offset: the fit's frame-offset cause
    assert data_verdict(_in_frame(POINTS / 10), POINTS, NOISE, "frame points").cause == "units"


def test_a_probe_fit_names_the_outlier_touches() -> None:
    res = np.zeros((30, 1))
    res[11] = 2e-3
    verdict = fit_verdict(True, 5, 4e-4, NOISE, res, labels=tuple(f"t{k}" for k in range(30)), values="")
    assert verdict.cause == "outliers" and "'t11'" in verdict.problem and "2 mm" in verdict.problem
    assert "per value against an instrument noise of 10 µm" in verdict.problem


def test_an_unknown_kind_of_values_is_refused() -> None:
    with pytest.raises(InvalidRequestError, match="'distances'"):
        data_verdict(LENGTHS, LENGTHS, NOISE, "lengths")


# --- through the command line ------------------------------------------------------------------


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """A ballbar session and a tracker session in the tracker's own frame (simulated, exact kinematics)."""
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    grid = sweep(mech, pset, mech.task_space.grid(), chain)
    classes = grid.classify()
    out = {}
    for name, kw in (
        ("ballbar", {"instrument": "ballbar"}),
        ("tracker-frame", {"tracker_frame": "identify"}),
    ):
        settings = CalibrationSettings(candidates=40, **kw)
        plan = make_plan(
            mech, pset, classes, settings, candidate_pool(mech, pset, settings, chain, grid=grid)
        )
        inst = plan.instrument
        rng = np.random.default_rng(3)
        delta = np.zeros(len(pset))
        comp = [i for i, c in enumerate(classes) if c == "compensatable"]
        delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
        o, R, _ = machine_poses(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q)
        pi = inst.draw_nuisance(rng)
        values = inst.perturb(
            inst.measure(o, R, plan.stations, pi), rng.standard_normal((len(o), inst.noise.size)) * inst.noise
        )
        out[name] = (mech, inst, plan, values, tmp_path_factory.mktemp(name))
    return out


def _file(session, edit) -> Path:
    mech, inst, plan, values, folder = session
    path = folder / "bad.csv"
    v = edit(values)
    if inst.name == "ballbar":
        path.write_text(instrument_csv(mech, inst, plan.maps.commands, v, plan.stations))
    else:
        path.write_text(measurements_csv(mech, plan.maps.commands, v.reshape(len(v), 1, 3)))
    return path


OPTIONS = {"ballbar": ["--instrument", "ballbar"], "tracker-frame": ["--tracker-frame", "identify"]}
CASES = {
    ("ballbar", "zeros"): (lambda v: 0 * v, "every measured length is 0"),
    ("ballbar", "units"): (lambda v: v / 1e3, "metres written under [mm] headers"),
    ("tracker-frame", "zeros"): (lambda v: 0 * v, "every measured coordinate is 0"),
    ("tracker-frame", "units"): (lambda v: v / 25.4, "inches written under [mm] headers"),
    ("tracker-frame", "repeated point"): (lambda v: 0 * v + v[0], "every pose measured the same point"),
}


@pytest.mark.parametrize("key", sorted(CASES))
def test_an_instrument_file_that_cannot_be_right_is_refused_with_its_cause(sessions, tmp_path, capsys, key):
    name, cause = key
    edit, words = CASES[key]
    path = _file(sessions[name], edit)
    out = tmp_path / "out"
    argv = [
        "calibrate",
        str(SEED),
        "--set",
        "urdf",
        "--measurements",
        str(path),
        "--out",
        str(out),
        *OPTIONS[name],
    ]
    with pytest.raises(PoorFitError) as info:
        run(argv)
    assert info.value.cause == cause and words in str(info.value), str(info.value)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Nothing was written" in err and "--accept-poor-fit" in err
    assert not any(p.is_file() for p in out.rglob("*"))


def test_the_good_instrument_files_still_calibrate(sessions, tmp_path, capsys):
    for name in OPTIONS:
        out = tmp_path / name
        path = _file(sessions[name], lambda v: v)
        argv = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(path), "--out", str(out)]
        assert main([*argv, *OPTIONS[name]]) == 0, capsys.readouterr().err
        assert (out / "calibrated" / "mechanism.toml").is_file()
