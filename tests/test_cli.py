"""`pkmtol errors` and `pkmtol allocate` end to end (in-process), and the D–H → URDF generator."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from pkmtol.cli import main
from pkmtol.model.dh import forward, to_urdf
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
SMALL = ["--samples", "400", "--exact-samples", "5", "--verification-poses", "40", "--no-progress"]


def test_errors_command_table_and_json(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines to match (piped output wraps at 100)
    out = tmp_path / "errors.json"
    assert main(["errors", str(SEED), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "108 parameters — 60 absorbed, 34 compensatable, 14 uncompensatable" in text
    doc = json.loads(out.read_text(encoding="utf-8"))
    params = doc["parameters"]
    assert len(params) == 108
    assert {p["class"] for p in params} == {"absorbed", "compensatable", "uncompensatable"}
    unc = [p for p in params if p["class"] == "uncompensatable"]
    assert all(p["sensitivity"] > 0 for p in unc)
    assert all(p["sensitivity"] == 0 for p in params if p["class"] != "uncompensatable")
    assert set(p) >= {"name", "unit", "class", "sensitivity"} if (p := params[0]) else False


def test_errors_command_urdf_set(capsys):
    assert main(["errors", str(SEED), "--set", "urdf"]) == 0
    text = capsys.readouterr().out
    assert "parameter set 'urdf': 171 parameters" in text
    assert "limb4.limb4_platform_attach.rz" in text


def test_allocate_command_writes_everything(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["allocate", str(SEED), "--out", str(out), "--seed", "4", *SMALL]) == 0
    text = capsys.readouterr().out
    assert "Tolerances of the uncompensatable errors" in text
    assert "Claimed vs true reliability" in text
    names = {p.name for p in out.iterdir()}
    assert {"allocation.json", "allocation.csv", "allocation.md"} <= names
    doc = json.loads((out / "allocation.json").read_text(encoding="utf-8"))
    for key in ("target_m", "beta", "reliability", "worst_point_m", "parameters", "verification"):
        assert key in doc
    assert doc["target_m"] == pytest.approx(5e-5)
    p = next(p for p in doc["parameters"] if p["class"] == "uncompensatable")
    assert len(p["tolerance"]) == len(doc["beta"])
    for dist in ("uniform_sigma", "uniform_sqrt3_sigma", "gaussian"):
        v = doc["verification"][dist]
        assert set(v) >= {"mean_m", "std_m", "failure_fraction"}
    rows = list(csv.reader((out / "allocation.csv").read_text(encoding="utf-8").splitlines()))
    assert len(rows) == 1 + 108
    assert (out / "allocation.md").read_text(encoding="utf-8").startswith("# pkmtol allocation")


def test_allocate_target_and_beta_options(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["allocate", str(SEED), "--out", str(out), "--target", "20um", "--beta", "3", *SMALL]) == 0
    doc = json.loads((out / "allocation.json").read_text(encoding="utf-8"))
    assert doc["target_m"] == pytest.approx(2e-5)
    assert doc["design_beta"] == 3.0


def test_allocate_same_seed_same_bytes(tmp_path, capsys):
    for name in ("a", "b"):
        assert main(["allocate", str(SEED), "--out", str(tmp_path / name), "--seed", "5", *SMALL]) == 0
    for f in ("allocation.json", "allocation.csv", "allocation.md"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()


def test_allocate_method_exact(tmp_path, capsys):
    out = tmp_path / "x"
    assert (
        main(["allocate", str(SEED), "--out", str(out), "--method", "exact", "--criterion", "worst", *SMALL])
        == 0
    )
    doc = json.loads((out / "allocation.json").read_text(encoding="utf-8"))
    md = doc["method_design"]
    assert md["method"] == "exact" and md["criterion"] == "worst"
    assert doc["verified_design"] == "exact"


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--target=-1mm"], "Δλ* must be positive"),
        (["--target", "0mm"], "Δλ* must be positive"),
        (["--target", "5 furlongs"], "unknown unit"),
        (["--beta", "0"], "β must be positive"),
        (["--samples", "0"], "--samples 0: must be ≥ 2"),
        (["--seed", "-1"], "--seed -1: must be ≥ 0"),
        (["--target", "50"], "--target 50: '50' has no unit"),
        (["--criterion", "worst", "--method", "fosm"], "--criterion worst: only --method exact reads it"),
        (["--samples", "1000000000000"], "--samples 1000000000000: needs about"),
    ],
)
def test_allocate_bad_requests_exit_2_and_write_nothing(tmp_path, capsys, args, needle):
    out = tmp_path / "never"
    assert main(["allocate", str(SEED), "--out", str(out), *SMALL, *args]) == 2
    assert needle in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_allocate_not_a_robot_folder(tmp_path, capsys):
    assert main(["allocate", str(tmp_path), *SMALL]) == 2
    assert "mechanism.toml" in capsys.readouterr().err


def test_allocate_unwritable_output(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["allocate", str(SEED), "--out", str(blocker / "out"), *SMALL]) == 2
    assert "cannot write" in capsys.readouterr().err


def test_dh_to_urdf_in_process_matches_files_and_kinematics():
    """The generator's output is the committed URDF, and the URDF's kinematics is the D–H table's."""
    mech = load_mechanism(SEED)
    rng = np.random.default_rng(0)
    for limb in mech.limbs:
        assert limb.dh is not None and limb.urdf_path is not None
        text = to_urdf(limb.dh, limb.name, "base", "platform", limb.name)
        assert text == limb.urdf_path.read_text(encoding="utf-8")
        import pinocchio as pin

        data = limb.model.createData()
        for _ in range(5):
            q = rng.uniform(-1, 1, limb.nq)
            pin.framesForwardKinematics(limb.model, data, q)
            m_dh = forward(limb.dh, q)
            np.testing.assert_allclose(
                data.oMf[limb.platform_frame].homogeneous, m_dh.homogeneous, atol=1e-12
            )


def test_allocate_writes_figures_and_html(tmp_path, capsys):
    out = tmp_path / "f"
    html = tmp_path / "scene.html"
    assert main(["allocate", str(SEED), "--out", str(out), "--html", str(html), *SMALL]) == 0
    for stem in ("sensitivity", "dlambda_histogram", "tolerances"):
        assert (out / f"{stem}.png").stat().st_size > 1000
        assert (out / f"{stem}.svg").stat().st_size > 1000
    assert "<html" in html.read_text(encoding="utf-8")[:2000].lower()
    assert "147 error spheres" in capsys.readouterr().out


def test_show_html(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines to match (piped output wraps at 100)
    html = tmp_path / "show.html"
    assert main(["show", str(SEED), "--html", str(html), "--samples", "300"]) == 0
    assert html.stat().st_size > 100_000
    out = capsys.readouterr().out
    assert f"wrote {html} ({html.stat().st_size} bytes, 147 error spheres)" in out
