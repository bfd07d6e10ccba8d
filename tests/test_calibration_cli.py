"""``pkmtol calibrate``: the plan, the study, real data round trip, and bad measurement files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pkmtol.calibration.fit_check import PoorFitError
from pkmtol.calibration.identification import model_positions
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.measurement_files import measurements_csv, read_measurements
from pkmtol.calibration.plan import candidate_pool, make_plan
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.cli import main, run
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import MeasurementFileError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A simulated measurement session of the seed robot: 30 D-optimal poses, P measured."""
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    classes = sweep(mech, pset, mech.task_space.grid(), chain).classify()
    settings = CalibrationSettings(candidates=50)
    plan = make_plan(mech, pset, classes, settings, candidate_pool(mech, pset, settings, chain), poses=30)
    rng = np.random.default_rng(3)
    delta = np.zeros(len(pset))
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
    y, _ = model_positions(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q, plan.targets_m)
    y = y + rng.standard_normal(y.shape) * 1e-5
    folder = tmp_path_factory.mktemp("session")
    path = folder / "measurements.csv"
    path.write_text(measurements_csv(mech, plan.maps.commands, y))
    return mech, pset, plan, delta, path


def test_real_data_round_trip_writes_loadable_calibrated_urdfs(session, tmp_path, capsys):
    mech, pset, plan, delta, path = session
    out = tmp_path / "out"
    assert (
        main(["calibrate", str(SEED), "--set", "urdf", "--measurements", str(path), "--out", str(out)]) == 0
    )
    text = capsys.readouterr().out
    assert "residual RMS per coordinate" in text and "base parameter" in text
    doc = json.loads((out / "identified.json").read_text())
    assert doc["converged"] and doc["rms_after_m"] < 1.2e-5 < doc["rms_before_m"]
    estimate = np.array([doc["estimate"][n] for n in pset.names])
    identified = Machine(mech, pset, estimate)
    calibrated = load_mechanism(out / "calibrated")
    chain = ClosedChain(calibrated, check_limits=False)
    worst = 0.0
    for u, q in zip(plan.maps.commands, plan.maps.q, strict=True):
        a = identified.forward(u, q)
        b = chain.forward(u, q - identified.offsets)
        worst = max(
            worst, float(np.linalg.norm(a.p_m - b.p_m)), float(np.abs(a.oMp.rotation - b.oMp.rotation).max())
        )
    assert worst <= 1e-12
    # the calibration is real: held at these poses the identified machine is within the noise
    assert (out / "residuals.csv").read_text().count("\n") == 31


def _rewrite(path: Path, tmp: Path, edit) -> Path:
    lines = path.read_text().splitlines()
    new = tmp / "bad.csv"
    new.write_text("\n".join(edit(lines)) + "\n")
    return new


BAD = {
    "missing column": (
        lambda ls: (
            [",".join(c for c in ls[0].split(",") if not c.startswith("z"))]
            + [",".join(r.split(",")[:-1]) for r in ls[1:]]
        ),
        "'z'",
    ),
    "unknown joint": (
        lambda ls: [ls[0].replace("limb2.limb2_p3", "limb2.limb2_p9")] + ls[1:],
        "limb2.limb2_p9",
    ),
    "nan": (lambda ls: [ls[0], ls[1].rsplit(",", 1)[0] + ",nan"] + ls[2:], "not a finite number"),
    "unit missing": (lambda ls: [ls[0].replace("x [mm]", "x")] + ls[1:], "'x'"),
    "unit wrong": (lambda ls: [ls[0].replace("x [mm]", "x [deg]")] + ls[1:], "deg"),
    "duplicated row": (lambda ls: ls + [ls[3]], "duplicated"),
    "too few poses": (lambda ls: ls[:6], "fewer than the 23 identifiable"),
    "outside limits": (
        lambda ls: [ls[0], "0," + "5000.0," + ",".join(ls[1].split(",")[2:])] + ls[2:],
        "outside the joint's limits",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_measurement_file_is_a_named_error_and_writes_nothing(session, tmp_path, capsys, case):
    _, _, _, _, path = session
    edit, culprit = BAD[case]
    bad = _rewrite(path, tmp_path, edit)
    out = tmp_path / "out"
    code = main(["calibrate", str(SEED), "--set", "urdf", "--measurements", str(bad), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert "pkmtol: error:" in err and culprit in err, err
    assert not any(p.is_file() for p in out.rglob("*"))


def test_reader_groups_rows_into_poses_and_checks_targets(session, tmp_path):
    mech, _, plan, _, path = session
    m = read_measurements(path, mech, 1)
    np.testing.assert_allclose(m.commands, plan.maps.commands, rtol=0, atol=1e-12)
    assert m.measured_m.shape == (30, 1, 3)
    with pytest.raises(MeasurementFileError, match="lacks target"):
        read_measurements(path, mech, 2)


def test_plan_command_writes_the_poses_for_the_session(tmp_path, capsys):
    out = tmp_path / "plan"
    code = main(
        [
            "calibrate",
            str(SEED),
            "--set",
            "urdf",
            "--poses",
            "20",
            "--random-sets",
            "3",
            "--candidates",
            "40",
            "--out",
            str(out),
            "--plan",
            str(out / "plan.csv"),
            "--no-figures",
        ]
    )
    text = capsys.readouterr().out
    assert code == 0
    assert "rank 23 of 46" in text and "lower predicted p99 than" in text
    rows = (out / "plan.csv").read_text().splitlines()
    assert rows[0].startswith("pose,limb1.limb1_p3 [mm]") and len(rows) == 21
    doc = json.loads((out / "calibration_plan.json").read_text())
    assert doc["identifiability"]["rank"] == 23 and len(doc["random_plans"]) == 3


def test_simulate_command_reports_every_row(tmp_path, capsys):
    out = tmp_path / "sim"
    code = main(
        [
            "calibrate",
            str(SEED),
            "--set",
            "urdf",
            "--simulate",
            "--machines",
            "2",
            "--holdout",
            "20",
            "--poses",
            "25",
            "--random-sets",
            "1",
            "--candidates",
            "40",
            "--out",
            str(out),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0
    for row in (
        "before calibration",
        "Eq. 25, ideal compensation (exact)",
        "compensatable, 25 d-optimal poses",
        "full, 25 random poses",
        "linear prediction",
    ):
        assert row in text
    doc = json.loads((out / "study.json").read_text())
    assert len(doc["cases"]) == 4
    for case in doc["cases"]:
        exact, lin = case["exact"], case["linear_prediction"]
        assert abs(exact["mean_dlambda_m"] - lin["mean_dlambda_m"]) < 0.05 * lin["mean_dlambda_m"]
    assert (out / "calibration_histogram.png").is_file() and (out / "p99_against_poses.svg").is_file()


def test_study_is_the_same_serially_and_on_two_processes(tmp_path):
    """Machines are seeded one by one: the executor and its worker count change no number."""
    from pkmtol.calibration.holdout import holdout_poses
    from pkmtol.calibration.study import StudyCase, run_study, study_context
    from pkmtol.executor import Executor

    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    classes = sweep(mech, pset, mech.task_space.grid(), chain).classify()
    settings = CalibrationSettings(candidates=20)
    plan = make_plan(mech, pset, classes, settings, candidate_pool(mech, pset, settings, chain), poses=20)
    sigma = settings.manufacturing_sigma(pset)
    sigma[[i for i, c in enumerate(classes) if c != "compensatable"]] = 0.0
    ho = holdout_poses(mech, pset, 15, np.random.default_rng(2), chain)
    ctx = study_context(
        mech,
        pset,
        sigma,
        ho.maps,
        ho.correction,
        ho.ideal,
        [(StudyCase("compensatable", "d-optimal", 20), plan)],
        5e-5,
    )
    serial = run_study(ctx, 4, seed=3, chunk=1)
    parallel = run_study(ctx, 4, seed=3, chunk=3, executor=Executor(workers=2))
    for a, b in ((serial.before, parallel.before), (serial.cases[0].exact, parallel.cases[0].exact)):
        np.testing.assert_array_equal(a.dlambda_m, b.dlambda_m)
    assert serial.cases[0].exact.mean_m > 0


# --- impossible data: no calibrated machine ---------------------------------------------------

IMPOSSIBLE = {
    # the measured points, from the session's: the cause the refusal must name, and a needle
    "all coordinates 0": (lambda y: 0.0 * y, "zeros", "every measured coordinate is 0"),
    "metres under [mm] headers": (lambda y: 1e-3 * y, "units", "metres written under [mm]"),
    "one point for every pose": (lambda y: 0.0 * y + y[0], "repeated point", "the same point"),
    "a 50 mm offset": (lambda y: y + np.array([0.05, 0.0, 0.0]), "frame offset", "--tracker-frame identify"),
    "two outlier poses": (
        lambda y: y + np.where(np.isin(np.arange(len(y)), [4, 17])[:, None, None], 3e-3, 0.0),
        "outliers",
        "'4', line 6",
    ),
}


def _measured(session) -> tuple[np.ndarray, np.ndarray]:
    mech, _, plan, _, path = session
    m = read_measurements(path, mech, 1)
    return m.commands, m.measured_m


@pytest.mark.parametrize("case", sorted(IMPOSSIBLE))
def test_impossible_data_is_refused_and_writes_nothing(session, tmp_path, capsys, case):
    mech = session[0]
    commands, y = _measured(session)
    edit, cause, needle = IMPOSSIBLE[case]
    bad = tmp_path / "bad.csv"
    bad.write_text(measurements_csv(mech, commands, edit(y)))
    out = tmp_path / "out"
    argv = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(bad), "--out", str(out)]
    with pytest.raises(PoorFitError) as info:
        run(argv)
    assert info.value.cause == cause, str(info.value)
    assert needle in str(info.value)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Nothing was written" in err and "--accept-poor-fit" in err
    assert not out.exists() or not any(p.is_file() for p in out.rglob("*"))


def test_accept_poor_fit_writes_and_says_it_was_overridden(session, tmp_path, capsys):
    mech = session[0]
    commands, y = _measured(session)
    bad = tmp_path / "bad.csv"
    bad.write_text(measurements_csv(mech, commands, y + np.array([0.05, 0.0, 0.0])))
    out = tmp_path / "out"
    argv = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(bad), "--out", str(out)]
    assert main([*argv, "--accept-poor-fit"]) == 0
    captured = capsys.readouterr()
    assert "poor fit accepted by --accept-poor-fit" in captured.err
    doc = json.loads((out / "identified.json").read_text())
    assert doc["fit_check"]["poor"] and doc["fit_check"]["overridden_by_accept_poor_fit"]
    assert doc["fit_check"]["cause"] == "frame offset"
    assert "--accept-poor-fit overrode the check" in (out / "identified.md").read_text()
    assert (out / "calibrated" / "mechanism.toml").is_file()


def test_good_data_passes_the_fit_check(session, tmp_path):
    out = tmp_path / "out"
    argv = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(session[4]), "--out", str(out)]
    assert main(argv) == 0
    check = json.loads((out / "identified.json").read_text())["fit_check"]
    assert not check["poor"] and check["rms_after_m"] < check["limit_m"] == pytest.approx(5e-5)


# --- the reader: sizes, folders, grouping in linear time ------------------------------------------


def test_a_huge_coordinate_is_refused_where_it_is_read(session, tmp_path, capsys):
    bad = _rewrite(session[4], tmp_path, lambda ls: [ls[0], ls[1].rsplit(",", 1)[0] + ",1e300"] + ls[2:])
    out = tmp_path / "out"
    code = main(["calibrate", str(SEED), "--set", "urdf", "--measurements", str(bad), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "line 2 column 'z'" in err and "not a measurement" in err, err
    assert "Traceback" not in err and not any(p.is_file() for p in out.rglob("*"))


def test_measurements_naming_a_folder_is_refused(tmp_path, capsys):
    code = main(["calibrate", str(SEED), "--measurements", str(tmp_path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "is a folder; give the measurement CSV file" in err, err


def test_grouping_into_poses_agrees_with_the_row_by_row_comparison():
    from pkmtol.calibration.measurement_files import SAME_POSE, _group, _group_rows

    rng = np.random.default_rng(5)
    base = rng.uniform(0.5, 1.5, size=(200, 3))
    edge = 0.5e-6  # a bin edge of the binned grouping (1000 × SAME_POSE wide)
    base[:20, 0] = edge + rng.uniform(-0.3, 0.3, size=20) * SAME_POSE  # rows of a pose in two bins
    rows = np.repeat(base, 3, axis=0) + rng.uniform(-0.2, 0.2, size=(600, 3)) * SAME_POSE
    rows = rows[rng.permutation(600)]
    got = _group(rows)
    np.testing.assert_array_equal(got, _group_rows(rows))
    # every pose once: a pose's rows agree within SAME_POSE, different poses do not
    assert got.max() + 1 == 200  # the edge poses' rows found each other across the edge
    assert len({tuple(np.flatnonzero(got == got[k])) for k in range(600)}) == 200
    first_rows = [rows[got == k][0] for k in range(got.max() + 1)]
    assert [int(np.flatnonzero(got == k)[0]) for k in range(got.max() + 1)] == sorted(
        int(np.flatnonzero(got == k)[0]) for k in range(got.max() + 1)
    )
    assert all(np.abs(rows[got == k] - first_rows[k]).max() < SAME_POSE for k in range(len(first_rows)))


# --- options and files that were read silently or crashed ---------------------------------------


def _allocation(tmp_path: Path, **changes) -> Path:
    """A minimal allocation.json of the seed robot (dh set): one uncompensatable tolerance."""
    mech = load_mechanism(SEED)
    names = parameter_set(mech, "dh").names
    doc = {
        "mechanism": "r2rps_ups",
        "parameter_set": "dh",
        "beta": [1.0, 2.0],
        "design_beta": 2.0,
        "parameters": [
            {"name": names[-1], "tolerance": [2e-5, 1e-5], "class_in_mode": "uncompensatable"},
            {"name": names[0], "tolerance": [None, None], "class_in_mode": "compensatable"},
        ],
    }
    doc.update(changes)
    path = tmp_path / "allocation.json"
    path.write_text(json.dumps(doc))
    return path


def test_tolerances_of_this_robot_are_read_at_the_design_beta(tmp_path):
    from pkmtol.calibration.tolerance_file import read_tolerances

    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "dh")
    tol, source = read_tolerances(_allocation(tmp_path), "r2rps_ups", pset, CalibrationSettings())
    assert tol[-1] == 1e-5 and np.isnan(tol[0]) and np.isnan(tol[1:-1]).all()
    assert "FOSM design-β tolerances" in source


def test_tolerances_of_a_real_allocation_are_read(tmp_path):
    """allocate's own allocation.json (a non-toleranced parameter's tolerance is null) is read whole."""
    from pkmtol.calibration.tolerance_file import read_tolerances

    out = tmp_path / "alloc"
    args = ["allocate", str(SEED), "--samples", "500", "--verification-poses", "50", "--exact-samples", "0"]
    assert main([*args, "--no-figures", "--no-progress", "--out", str(out)]) == 0
    doc = json.loads((out / "allocation.json").read_text())
    assert any(row["tolerance"] is None for row in doc["parameters"])  # the format this test is about
    pset = parameter_set(load_mechanism(SEED), doc["parameter_set"])
    tol, source = read_tolerances(out / "allocation.json", "r2rps_ups", pset, CalibrationSettings())
    design = dict(zip(doc["method_design"]["parameters"], doc["method_design"]["tolerance"], strict=True))
    assert {pset.names[i]: tol[i] for i in np.flatnonzero(np.isfinite(tol))} == pytest.approx(design)
    assert "'exact' design" in source


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        ({"mechanism": "tricept"}, "an allocation of 'tricept', not of 'r2rps_ups'"),
        ({"parameters": [{"name": "nothing.here", "tolerance": [1e-5, 1e-5]}]}, "names 'nothing.here'"),
        ({"parameters": [{"name": "x", "tolerance": "tight"}]}, "parameters[0].tolerance"),
        ({"parameters": [{"name": "x", "tolerance": [1e-5]}]}, "expected a list of 2 numbers"),
        ({"beta": "2"}, "key 'beta'"),
        ({"design_beta": None}, "key 'design_beta'"),
        ({"design_beta": 5}, "5 is not one of the file's β"),
        ({"parameters": [5]}, "parameters[0]"),
        ({"method_design": {"method": "cost", "parameters": ["a"], "tolerance": ["x"]}}, "method_design"),
    ],
)
def test_a_wrong_tolerances_file_is_refused_naming_what_is_wrong(tmp_path, capsys, changes, needle):
    path = _allocation(tmp_path, **changes)
    code = main(
        ["calibrate", str(SEED), "--tolerances", str(path), "--random-sets", "0", "--out", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code == 2 and needle in err and "Traceback" not in err, err


def test_tolerances_with_measurements_but_no_prior_is_refused(session, tmp_path, capsys):
    path = _allocation(tmp_path)
    argv = ["calibrate", str(SEED), "--measurements", str(session[4]), "--tolerances", str(path)]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "--tolerances" in err and "give --prior" in err


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["calibrate", str(SEED), "--noise", "1e300mm"], "--noise 1e300mm: an instrument's noise σ"),
        (["errors", str(SEED), "--compensation", "calibrated", "--noise", "1e300mm"], "--noise 1e300mm"),
        (["allocate", str(SEED), "--compensation", "calibrated", "--noise", "1e300mm"], "--noise 1e300mm"),
        (["allocate", str(SEED), "--drawing-k", "1e308"], "--drawing-k 1e+308"),
        (["calibrate", str(SEED), "--poses", "0"], "--poses 0: give an integer ≥ 1"),
        (["calibrate", str(SEED), "--rank-tolerance", "2"], "--rank-tolerance 2.0"),
        (["calibrate", str(SEED), "--random-sets", "-1"], "--random-sets -1"),
        (["calibrate", str(SEED), "--holdout", "10000000000"], "--holdout 10000000000: needs about"),
        (["calibrate", str(SEED), "--simulate", "--machines", "10**11"], "--machines"),
        (["allocate", str(SEED), "--poses", "5"], "--poses 5: a calibration-plan option"),
        (["errors", str(SEED), "--noise", "1mm"], "--noise 1mm: a calibration-plan option"),
    ],
)
def test_a_bad_option_is_named_as_the_option(tmp_path, capsys, argv, needle):
    argv = [a.replace("10**11", "100000000000") for a in argv]
    assert main(argv + ([] if argv[0] == "errors" else ["--out", str(tmp_path / "out")])) == 2
    err = capsys.readouterr().err
    assert needle in err and "key 'calibration'" not in err and "Traceback" not in err, err
    assert not any(p.is_file() for p in (tmp_path / "out").rglob("*"))


def test_a_measurement_error_without_a_line_has_no_empty_place():
    err = MeasurementFileError("m.csv", 0, "", "file not found")
    assert str(err) == "m.csv: file not found"
    assert str(MeasurementFileError("m.csv", 3, "x", "bad")) == "m.csv: line 3 column 'x': bad"


def test_a_yaml_alias_bomb_and_a_deep_nesting_give_short_named_errors(tmp_path):
    import shutil
    import time

    from pkmtol.exceptions import MechanismFormatError

    for kind in ("bomb", "deep"):
        folder = tmp_path / kind
        shutil.copytree(ROOT / "tests" / "data" / "r2rps_ups_closed", folder)
        side = folder / "robot.yaml"
        text = "\n".join(line for line in side.read_text().splitlines() if not line.startswith("type:"))
        if kind == "bomb":
            text += '\na0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
            text += "".join(f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]\n" for i in range(1, 9))
            text += "type: *a8\n"
        else:
            text += "\ntype: " + "[" * 10_000 + "]" * 10_000 + "\n"
        side.write_text(text)
        t0 = time.perf_counter()
        with pytest.raises(MechanismFormatError) as info:
            load_mechanism(folder)
        assert time.perf_counter() - t0 < 30 and len(str(info.value)) < 400, str(info.value)[:400]
        assert "robot.yaml" in str(info.value)
