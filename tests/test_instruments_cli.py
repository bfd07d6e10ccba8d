"""``pkmtol calibrate --instrument …``: simulated files → identification → calibrated URDFs, and bad files.

Each instrument's session is simulated on exact kinematics (a true machine with compensatable
errors, the instrument's true nuisance drawn at random: a tracker placed anywhere, an artifact off
its nominal pose), written in the instrument's CSV format, read back by the command, identified,
and the calibrated URDFs it writes must reproduce the identified machine's forward kinematics to
1e-12. Every bad file is a named error that writes nothing.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pkmtol.calibration.identification import machine_poses
from pkmtol.calibration.instrument_files import instrument_csv
from pkmtol.calibration.instruments.probe import trigger_commands
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.measurement_files import measurements_csv
from pkmtol.calibration.plan import candidate_pool, make_plan
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.cli import main
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
INSTRUMENTS = {
    "tracker-frame": ["--tracker-frame", "identify"],
    "tracker-6d": ["--instrument", "tracker-6d"],
    "ballbar": ["--instrument", "ballbar"],
    "probe": ["--instrument", "probe"],
    "probe-plane": ["--instrument", "probe", "--artifact", "plane"],
}


@pytest.fixture(scope="module")
def base():
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "urdf")
    chain = ClosedChain(mech)
    grid = sweep(mech, pset, mech.task_space.grid(), chain)
    return mech, pset, chain, grid, grid.classify()


@pytest.fixture(scope="module")
def sessions(base, tmp_path_factory):
    mech, pset, chain, grid, classes = base
    out = {}
    for name, opts in INSTRUMENTS.items():
        kw = {"tracker_frame": "identify"} if name == "tracker-frame" else {"instrument": opts[1]}
        if name == "probe-plane":
            kw["artifact"] = "plane"
        settings = CalibrationSettings(candidates=60, **kw)
        plan = make_plan(
            mech, pset, classes, settings, candidate_pool(mech, pset, settings, chain, grid=grid)
        )
        inst = plan.instrument
        rng = np.random.default_rng(3)
        delta = np.zeros(len(pset))
        comp = [i for i, c in enumerate(classes) if c == "compensatable"]
        delta[comp] = rng.standard_normal(len(comp)) * np.where(np.array(pset.units)[comp] == "m", 1e-4, 5e-4)
        true = Machine(mech, pset, delta)
        pi = inst.draw_nuisance(rng)
        commands = plan.maps.commands
        if name.startswith("probe"):
            commands = trigger_commands(
                true, inst, commands, plan.maps.q, plan.stations, pi, plan.maps.position_actuation()
            )
        o, R, _ = machine_poses(true, commands, plan.maps.q)
        values = inst.measure(o, R, plan.stations, pi)
        noise = rng.standard_normal(values.shape) * inst.noise[None, :]
        values = inst.perturb(values, noise)
        path = tmp_path_factory.mktemp(name) / "session.csv"
        if name == "tracker-frame":
            path.write_text(measurements_csv(mech, commands, values.reshape(len(values), 1, 3)))
        else:
            path.write_text(instrument_csv(mech, inst, commands, values, plan.stations))
        out[name] = (plan, commands, delta, pi, path)
    return out


@pytest.mark.parametrize("name", sorted(INSTRUMENTS))
def test_instrument_round_trip_writes_loadable_calibrated_urdfs(base, sessions, tmp_path, capsys, name):
    mech, pset, *_ = base
    plan, commands, delta, pi, path = sessions[name]
    out = tmp_path / "out"
    args = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(path), "--out", str(out)]
    assert main(args + INSTRUMENTS[name]) == 0
    text = capsys.readouterr().out
    assert "nuisance parameter" in text and "base parameter" in text
    doc = json.loads((out / "identified.json").read_text())
    assert doc["converged"] and doc["rms_after_in_sigma"] < 1.5
    if name in ("tracker-frame", "probe", "probe-plane"):  # the identified transform is the drawn one
        est = np.array([p["value"] for p in doc["nuisance"]])
        assert len(est) == 6 and doc["transform"] is not None
    estimate = np.array([doc["estimate"][n] for n in pset.names])
    identified = Machine(mech, pset, estimate)
    chain = ClosedChain(load_mechanism(out / "calibrated"), check_limits=False)
    worst = 0.0
    for u, q in zip(commands, plan.maps.q, strict=True):
        a = identified.forward(u, q)
        b = chain.forward(u, q - identified.offsets)
        worst = max(
            worst, float(np.linalg.norm(a.p_m - b.p_m)), float(np.abs(a.oMp.rotation - b.oMp.rotation).max())
        )
    assert worst <= 1e-12
    assert (out / "residuals.csv").read_text().count("\n") == len(commands) + 1


def test_tracker_frame_is_found_wherever_the_tracker_stands(base, sessions, tmp_path, capsys):
    """The drawn tracker placement (metres away, turned by up to ~π) is what the command reports."""
    mech, pset, *_ = base
    plan, _, _, pi, path = sessions["tracker-frame"]
    out = tmp_path / "out"
    args = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(path), "--out", str(out)]
    assert main(args + INSTRUMENTS["tracker-frame"]) == 0
    doc = json.loads((out / "identified.json").read_text())
    truth = plan.instrument.frame.transform(pi)
    # the frame and a global rigid motion of the machine cannot be told apart: the frame is found
    # to the size of the machine's errors (0.1 mm, 0.5 mrad), not better
    assert np.linalg.norm(np.array(doc["transform"]["translation_m"]) - truth.translation) < 5e-3
    assert np.abs(np.array(doc["transform"]["rotation"]) - truth.rotation).max() < 5e-3


def _edit(path: Path, tmp: Path, fn) -> Path:
    lines = path.read_text().splitlines()
    new = tmp / "bad.csv"
    new.write_text("\n".join(fn(lines)) + "\n")
    return new


def _drop_column(name):
    def fn(ls):
        cols = ls[0].split(",")
        k = next(i for i, c in enumerate(cols) if c.split(" [")[0] == name)
        return [",".join(c for i, c in enumerate(r.split(",")) if i != k) for r in ls]

    return fn


BAD = {
    ("tracker-6d", "missing column"): (_drop_column("rz"), "'rz'"),
    ("tracker-6d", "unit missing"): (lambda ls: [ls[0].replace("rx [mrad]", "rx")] + ls[1:], "'rx'"),
    ("tracker-6d", "unit wrong"): (lambda ls: [ls[0].replace("rx [mrad]", "rx [mm]")] + ls[1:], "angle unit"),
    ("tracker-6d", "nan"): (lambda ls: [ls[0], ls[1].rsplit(",", 1)[0] + ",nan"] + ls[2:], "not a finite"),
    ("tracker-6d", "duplicated row"): (lambda ls: ls + [ls[3]], "duplicated"),
    ("tracker-6d", "too few poses"): (lambda ls: ls[:4], "fewer than the"),
    ("ballbar", "missing column"): (_drop_column("d"), "'d'"),
    ("ballbar", "unit wrong"): (lambda ls: [ls[0].replace("d [mm]", "d [deg]")] + ls[1:], "length unit"),
    ("ballbar", "station out of range"): (
        lambda ls: [ls[0], ",".join(ls[1].split(",")[:-2] + ["99", ls[1].split(",")[-1]])] + ls[2:],
        "station index",
    ),
    ("ballbar", "duplicated row"): (lambda ls: ls + [ls[5]], "duplicated"),
    ("ballbar", "text"): (lambda ls: [ls[0], ls[1].rsplit(",", 1)[0] + ",abc"] + ls[2:], "not a number"),
    ("probe", "missing column"): (_drop_column("station"), "'station'"),
    ("probe", "unknown column"): (
        lambda ls: [ls[0] + ",x [mm]"] + [r + ",1" for r in ls[1:]],
        "not a column",
    ),
    ("probe", "station not an index"): (
        lambda ls: [ls[0], ls[1].rsplit(",", 1)[0] + ",-1"] + ls[2:],
        "station",
    ),
    ("probe", "too few touches"): (lambda ls: ls[:10], "fewer than the"),
    ("probe-plane", "face out of range"): (
        lambda ls: [ls[0], ls[1].rsplit(",", 1)[0] + ",5"] + ls[2:],
        "not a station index 0…4 of the probe",
    ),
    ("probe-plane", "too few touches"): (lambda ls: ls[:10], "fewer than the"),
    ("probe-plane", "unit wrong"): (
        lambda ls: [ls[0].replace(" [mm]", " [deg]", 1)] + ls[1:],
        "length unit",
    ),
    ("probe", "empty"): (lambda ls: ls[:1], "at least one measurement"),
    ("probe", "outside limits"): (
        lambda ls: [ls[0], "0," + "5000.0," + ",".join(ls[1].split(",")[2:])] + ls[2:],
        "outside the joint's limits",
    ),
}


@pytest.mark.parametrize("key", sorted(BAD))
def test_bad_instrument_file_is_a_named_error_and_writes_nothing(sessions, tmp_path, capsys, key):
    name, _ = key
    path = sessions[name][-1]
    fn, culprit = BAD[key]
    bad = _edit(path, tmp_path, fn)
    out = tmp_path / "out"
    args = ["calibrate", str(SEED), "--set", "urdf", "--measurements", str(bad), "--out", str(out)]
    code = main(args + INSTRUMENTS[name])
    err = capsys.readouterr().err
    assert code == 2
    assert "pkmtol: error:" in err and culprit in err, err
    assert not any(p.is_file() for p in out.rglob("*"))


def test_a_folder_given_as_measurements_is_named(tmp_path, capsys):
    args = ["calibrate", str(SEED), "--measurements", str(tmp_path), "--out", str(tmp_path / "o")]
    assert main(args + INSTRUMENTS["ballbar"]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_ballbar_plan_names_the_circle_of_every_reading(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    args = ["calibrate", str(SEED), "--instrument", "ballbar", "--poses", "3", "--plan", str(plan)]
    assert main(args + ["--out", str(tmp_path / "o"), "--no-figures", "--random-sets", "0"]) == 0
    text = capsys.readouterr().out
    assert "instrument ballbar" in text and "on 3 circles" in text
    rows = plan.read_text().splitlines()
    assert rows[0].startswith("pose,station,limb1.limb1_p3 [mm]")
    stations = {r.split(",")[1] for r in rows[1:]}
    assert len(stations) == 3 and len(rows) - 1 == 3 * 36
