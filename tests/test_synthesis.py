"""`pkmtol sweep`: key parsing and its errors, the numbers of the wrist-offset study it replaces,
D–H variants with their URDFs made in memory, and the same variants on every executor."""

from __future__ import annotations

import csv
import io
import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pkmtol.cli import main
from pkmtol.design.synthesis import parse_vary, set_number, synthesize, variant_mechanism
from pkmtol.exceptions import SweepSpecError
from pkmtol.executor import Executor
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
WRIST = "reference_point.position_m[2]=0.1:0.5:5"

#: `python scripts/sweep_wrist_offset.py` (the special case this command replaces), as it printed
#: on main before it was removed: l [m] → (|x|, |y|, z) of the worst P [mm], σ[Δλ] with unit
#: errors [m/unit], σ[Δλ] with the l = 0.3 m tolerances [µm]. The worst points come in mirror pairs
#: (y → −y) of equal σ on this robot; the script's pick among a pair was decided by round-off.
WRIST_SUMMARY = {
    0.1: ((0.0, 600.0, 900.0), 0.6529, 16.92),
    0.2: ((155.3, 579.6, 900.0), 0.5978, 15.66),
    0.3: ((300.0, 519.6, 900.0), 0.5407, 14.45),
    0.4: ((300.0, 519.6, 900.0), 0.4954, 14.47),
}
#: The uncompensatable parameters of every reachable variant. The script's tolerance table left the
#: ones without effect at the worst pose free; the sweep now runs allocate's allocation, which
#: tolerances them at their own most sensitive pose (issue 29.1; tests/test_pipeline.py compares
#: the sweep with allocate on a variant), so the script's numbers are no longer the sweep's.
WRIST_NAMES = (
    "δθ_{1,4}", "δd_{1,4}", "δa_{1,4}", "δφ_{1,4}", "δd_{2,4}", "δa_{2,4}", "δφ_{2,4}",
    "δd_{3,4}", "δa_{3,4}", "δφ_{3,4}", "δθ_{4,4}", "δa_{4,4}", "δφ_{4,4}", "δθ_{e,4}",
)  # fmt: skip


@pytest.fixture(scope="module")
def doc():
    return tomllib.loads((SEED / "mechanism.toml").read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def wrist():
    return synthesize(SEED, [parse_vary(WRIST)])


# --- keys and their errors ----------------------------------------------------------------------


def test_vary_values_are_evenly_spaced():
    assert parse_vary("a.b[1]=0:1:3").values == (0.0, 0.5, 1.0)
    assert parse_vary(" x = 2 : 2 : 1 ").values == (2.0,)


@pytest.mark.parametrize(
    "spec, says",
    [
        ("nothing", "expected KEY=START:STOP:N"),
        ("a=1:2", "expected KEY=START:STOP:N"),
        ("a=x:2:3", "START and STOP must be numbers"),
        ("a=1:2:0", "N must be an integer ≥ 1"),
        ("a=1:2:2.5", "N must be an integer ≥ 1"),
        ("a=1:inf:2", "N must be an integer ≥ 1 and START, STOP finite"),
    ],
)
def test_bad_specs_are_refused(spec, says):
    with pytest.raises(SweepSpecError) as info:
        parse_vary(spec)
    assert info.value.spec == spec and says in str(info.value)


@pytest.mark.parametrize(
    "key, says",
    [
        ("reference_point.offset", "no key 'reference_point.offset' (there: position_m)"),
        ("reference_point.position_m[3]", "position_m[3] is out of range (length 3)"),
        ("limbs[limb9].home[0]", "no entry 'limb9' in limbs (names: limb1, limb2, limb3, limb4)"),
        ("name", "holds 'r2rps_ups', not a number"),
        ("task_space", "not a number"),
        ("reference_point[0]", "reference_point is not a list"),
        ("a..b", "cannot read the key"),
    ],
)
def test_bad_keys_are_named(doc, key, says):
    with pytest.raises(SweepSpecError) as info:
        set_number(dict(doc), key, 1.0)
    assert says in str(info.value)


def test_a_dh_key_names_its_limb(doc):
    import copy

    d = copy.deepcopy(doc)
    assert set_number(d, "limbs[limb1].dh.links[0][2]", 0.45) == "limb1"
    assert set_number(d, "limbs[3].home[2]", 0.8) is None
    assert d["limbs"][0]["dh"]["links"][0][2] == 0.45 and d["limbs"][3]["home"][2] == 0.8


# --- the numbers of the wrist-offset study ----------------------------------------------------------


def test_reproduces_the_wrist_offset_study(wrist):
    assert [v.values[WRIST.split("=")[0]] for v in wrist.variants] == [0.1, 0.2, 0.3, 0.4, 0.5]
    for var in wrist.variants[:4]:
        l_m = var.values[WRIST.split("=")[0]]
        point, sigma_unit, _ = WRIST_SUMMARY[l_m]  # σ with the reference tolerances: see WRIST_NAMES
        p = var.worst_point_m * 1e3
        assert (round(abs(p[0]), 1), round(abs(p[1]), 1), round(p[2], 1)) == point
        assert round(var.sigma_unit_m, 4) == sigma_unit
        assert var.names == WRIST_NAMES
        assert set(var.units) <= {"m", "rad"}
        assert np.all(np.isfinite(var.tolerances)) and np.all(var.tolerances > 0), l_m
        assert var.cost > 0
    last = wrist.variants[4]
    assert not last.reachable and last.reason == "joint limb1_p3 out of its limits"
    assert wrist.reference.names == WRIST_NAMES
    np.testing.assert_array_equal(wrist.reference.tolerances, wrist.variants[2].tolerances)


# --- D–H variants ---------------------------------------------------------------------------------


def test_dh_variant_regenerates_the_urdf_and_recloses_home(doc):
    texts = {lb.name: lb.urdf_path.read_text(encoding="utf-8") for lb in load_mechanism(SEED).limbs}
    same = variant_mechanism(SEED, doc, texts, {"limbs[limb1].dh.links[0][2]": 0.5})  # the file's value
    nominal = load_mechanism(SEED)
    for a, b in zip(same.limbs[0].model.jointPlacements, nominal.limbs[0].model.jointPlacements, strict=True):
        np.testing.assert_allclose(a.homogeneous, b.homogeneous, atol=1e-15)
    wider = variant_mechanism(SEED, doc, texts, {"limbs[limb1].dh.links[0][2]": 0.6})
    # a_1 = α b_1: the first U joint of limb 1 sits 0.6 m out instead of 0.5 m
    np.testing.assert_allclose(
        wider.limbs[0].model.jointPlacements[1].translation, [0.6, 0.0, 0.0], atol=1e-12
    )
    # the nominal home no longer closes by 0.1 m; the variant's home does
    placements = []
    for lb in wider.limbs:
        data = lb.model.createData()
        pin.framesForwardKinematics(lb.model, data, lb.home)
        placements.append(data.oMf[lb.platform_frame])
    assert max(np.linalg.norm(pin.log6(placements[0].actInv(m)).vector) for m in placements[1:]) < 1e-10


def test_a_grid_of_variants_on_every_executor():
    varies = [parse_vary("limbs[limb1].dh.links[0][2]=0.45:0.55:2"), parse_vary("design.design_beta=1:2:2")]
    serial = synthesize(SEED, varies, method="fosm")  # FOSM: σ ∝ 1/β below
    assert len(serial.variants) == 4
    assert [tuple(v.values.values()) for v in serial.variants] == [
        (0.45, 1.0),
        (0.45, 2.0),
        (0.55, 1.0),
        (0.55, 2.0),
    ]
    # a variant's design β sets its tolerances' β (σ ∝ 1/β) ...
    np.testing.assert_allclose(serial.variants[0].tolerances, 2 * serial.variants[1].tolerances, rtol=1e-12)
    # ... the base radius does
    assert not np.allclose(serial.variants[0].tolerances, serial.variants[2].tolerances)
    parallel = synthesize(SEED, varies, executor=Executor(workers=2), method="fosm")
    for a, b in zip(serial.variants, parallel.variants, strict=True):
        np.testing.assert_array_equal(a.tolerances, b.tolerances)
        assert (a.sigma_unit_m, a.sigma_reference_m, a.cost) == (b.sigma_unit_m, b.sigma_reference_m, b.cost)


# --- the command ----------------------------------------------------------------------------------


def test_sweep_command_prints_and_writes_the_tables(tmp_path, capsys, wrist):
    out = tmp_path / "sweep"
    assert (
        main(
            [
                "sweep",
                str(SEED),
                "--vary",
                "reference_point.position_m[2]=0.2:0.5:2",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "pkmtol sweep — r2rps_ups: 2 variants, parameter set 'dh', β = 2, serial" in text
    assert re.search(r"^0\.2\s+yes\s", text, re.M) or "yes  (155.3, 579.6, 900.0)" in text
    assert "no: joint limb1_p3 out of its limits" in text
    names = [
        "pkmtol-run.json",
        "sweep.csv",
        "sweep.json",
        "sweep.png",
        "sweep.svg",
    ]  # a run folder (issue 25)
    assert sorted(p.name for p in out.iterdir()) == names
    rows = list(csv.reader(io.StringIO((out / "sweep.csv").read_text(encoding="utf-8"))))
    assert rows[0][:3] == ["reference_point.position_m[2]", "reachable", "reason"]
    assert rows[1][1] == "1" and rows[2][1] == "0"
    assert float(rows[1][rows[0].index("sigma_unit_m")]) == pytest.approx(0.5978, abs=5e-5)
    doc = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    assert doc["variants"][0]["reachable"] and not doc["variants"][1]["reachable"]
    l02 = wrist.variants[1]  # l = 0.2 m, the library's answer (tests/test_pipeline.py: = allocate's)
    assert doc["variants"][0]["tolerances_si"]["δd_{1,4}"] == l02.tolerances[l02.names.index("δd_{1,4}")]
    assert doc["reference"]["worst_point_m"] == pytest.approx([0.3, 0.5196152, 0.9], abs=1e-6)


@pytest.mark.parametrize(
    "args, says",
    [
        (["--vary", "x=1:2:3"], "--vary 'x=1:2:3': mechanism.toml has no key 'x'"),
        (["--vary", "design.target=1:2"], "expected KEY=START:STOP:N"),
        (
            ["--vary", "task_space.radius_m=0.5:0.6:2", "--vary", "task_space.radius_m=0.5:0.6:2"],
            "varied twice",
        ),
        (["--vary", "task_space.radius_m=0.5:0.6:2", "--workers", "0"], "workers: 0 is not a number"),
    ],
)
def test_sweep_command_refuses_bad_input(tmp_path, capsys, args, says):
    assert main(["sweep", str(SEED), "--out", str(tmp_path / "o"), "--no-progress", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pkmtol: error: ") and says in err
    assert not (tmp_path / "o").exists()


def test_sweep_command_names_an_unreachable_scheduler_before_any_work(tmp_path, capsys, monkeypatch):
    pytest.importorskip("dask.distributed")
    import pkmtol.executor

    monkeypatch.setattr(pkmtol.executor, "DASK_TIMEOUT_S", 1.0)
    args = ["sweep", str(SEED), "--vary", "task_space.radius_m=0.5:0.6:2", "--dask", "tcp://127.0.0.1:9"]
    assert main([*args, "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "pkmtol: error: dask: no Dask scheduler answers at 'tcp://127.0.0.1:9'" in err
    assert "dask scheduler" in err and not (tmp_path / "o").exists()
