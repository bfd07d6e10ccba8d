"""Output folders hold one whole run: all or nothing, no file of an earlier run, one writer at a time,
figures optional without matplotlib; and the printouts a new user reads (units, no -0.0, ±0.0000)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pkmtol import DesignOptions, allocate, load_mechanism, write_outputs
from pkmtol.cli import main
from pkmtol.exceptions import OutputError, OutputLockedError, ViewerError
from pkmtol.present.figures import FIGURES as FIGURE_STEMS
from pkmtol.present.run_folder import MANIFEST, RunFolder
from pkmtol.present.tables import _fmt_tol, summary_text, table_rows

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
SMALL = ["--samples", "300", "--exact-samples", "0", "--verification-poses", "30", "--no-progress"]
TABLES = ["allocation.csv", "allocation.json", "allocation.md"]
FIGURES = [f"{s}.{f}" for s in FIGURE_STEMS for f in ("png", "svg")]


@pytest.fixture(scope="module")
def result():
    return allocate(load_mechanism(SEED), DesignOptions(samples=300, verification_poses=30, exact_samples=0))


def test_reused_out_without_figures_keeps_no_figure_of_the_earlier_run(tmp_path, capsys):
    out = tmp_path / "out"
    (tmp_path / "out").mkdir()
    (out / "notes.txt").write_text("mine")  # not a run file: left alone
    assert main(["allocate", str(SEED), "--out", str(out), *SMALL]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(TABLES + FIGURES + [MANIFEST, "notes.txt"])
    assert main(["allocate", str(SEED), "--out", str(out), "--no-figures", *SMALL]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(TABLES + [MANIFEST, "notes.txt"])
    manifest = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
    assert manifest["files"] == ["allocation.json", "allocation.csv", "allocation.md"]
    capsys.readouterr()


def test_files_a_manifest_listed_are_removed_when_a_run_does_not_write_them(result, tmp_path):
    out = tmp_path / "o"
    write_outputs(result, out, extra={"extra.txt": b"x"})
    assert (out / "extra.txt").is_file()
    write_outputs(result, out)
    assert not (out / "extra.txt").exists()
    assert sorted(p.name for p in out.iterdir()) == sorted(TABLES + [MANIFEST])


def test_write_outputs_with_figures_writes_what_the_command_writes(result, tmp_path):
    written = write_outputs(result, tmp_path / "o", figures=True)
    assert sorted(p.name for p in written) == sorted(TABLES + FIGURES)


def test_a_second_run_into_a_locked_folder_is_refused_before_computing(tmp_path, capsys):
    out = tmp_path / "busy"
    with RunFolder(out):
        assert main(["allocate", str(SEED), "--out", str(out), *SMALL]) == 2
        err = capsys.readouterr().err
        assert "is writing a run into this folder" in err
        assert list(out.iterdir()) == []
        with pytest.raises(OutputLockedError) as info:
            with RunFolder(out):
                pass
        assert info.value.path == out
    with RunFolder(out):  # released
        pass


def test_two_processes_into_one_out(tmp_path):
    """A real second process: the lock is an OS lock on the folder, not a file a crash leaves behind."""
    out = tmp_path / "o"
    code = (
        "import sys, time; from pkmtol.present.run_folder import RunFolder\n"
        f"with RunFolder({str(out)!r}):\n    print('locked', flush=True); time.sleep(30)\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        proc = subprocess.run(
            [sys.executable, "-m", "pkmtol.cli", "allocate", str(SEED), "--out", str(out), *SMALL],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 2
        assert "is writing a run into this folder" in proc.stderr
    finally:
        holder.kill()
        holder.wait()
    with RunFolder(out):  # the killed holder's lock went with it
        pass


def test_failing_html_writes_nothing(tmp_path, capsys, monkeypatch):
    import pkmtol.present.viewer.export as export

    def broken(*args, **kwargs):
        raise ViewerError("meshcat server did not start (test)")

    monkeypatch.setattr(export, "render_html", broken)
    out = tmp_path / "out"
    assert main(["allocate", str(SEED), "--out", str(out), "--html", str(tmp_path / "s.html"), *SMALL]) == 2
    assert "meshcat server did not start" in capsys.readouterr().err
    assert list(out.iterdir()) == []
    assert not (tmp_path / "s.html").exists()


def test_failing_write_leaves_the_previous_run(result, tmp_path):
    out = tmp_path / "o"
    write_outputs(result, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(OutputError):
        with RunFolder(out) as run:
            run.write({"allocation.json": b"{}"}, outside={tmp_path / "missing" / "s.html": b"x"})
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_without_matplotlib_one_warning_line_and_the_tables(tmp_path):
    out = tmp_path / "out"
    code = (
        "import sys; sys.modules['matplotlib'] = None\n"
        "from pkmtol.cli import main\n"
        f"sys.exit(main(['allocate', {str(SEED)!r}, '--out', {str(out)!r}, *{SMALL!r}]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("pkmtol: warning: no figures: the figures need matplotlib")
    assert "--no-figures" in lines[0]
    assert sorted(p.name for p in out.iterdir()) == sorted(TABLES + [MANIFEST])


def test_units_um_and_never_zero_for_a_nonzero_tolerance(result, tmp_path, capsys):
    rows_mm, rows_um = table_rows(result), table_rows(result, "um")
    k = next(i for i, r in enumerate(rows_mm) if r[1] == "δa_{3,4}")
    assert rows_mm[k][2] == "mm" and rows_um[k][2] == "µm"
    col = rows_mm[0].index("β=2")
    i = result.pset.names.index("δa_{3,4}")
    sigma = result.tolerances[i, result.design_column]
    assert rows_um[k][col] == f"±{sigma * 1e6:.4f}" and rows_mm[k][col] == f"±{sigma * 1e3:.4f}"
    assert _fmt_tol(3.2e-8, "m") == "±3.2e-05" and _fmt_tol(1.28e-5, "m") == "±0.0128"
    assert _fmt_tol(4.56e-7, "rad") == "±0.000456" and _fmt_tol(0.0, "m") == "±0.0000"
    argv = ["allocate", str(SEED), "--out", str(tmp_path / "u"), "--units", "um", "--no-figures", *SMALL]
    assert main(argv) == 0
    assert "δa_{3,4}    µm" in capsys.readouterr().out


def test_summary_wording(result):
    text = summary_text(result)
    assert "m per unit error (m or rad) analytic" in text
    assert "median traditional/new 0.540" in text
    assert "-0.0" not in text
    worst = np.array([-1e-7, 0.6, 1.0])  # a coordinate that rounds to -0.0
    from pkmtol.present.tables import _point

    assert _point(worst) == "(0.0, 600.0, 1000.0) mm"


def test_check_shows_a_progress_bar_when_asked(capsys):
    from pkmtol.kinematics.check import check_mechanism

    report = check_mechanism(load_mechanism(SEED), progress=True)
    assert report.n_reachable == 147
    err = capsys.readouterr().err
    assert "check" in err and "147" in err  # tqdm's bar: "check: 100%|...| 147/147"


def test_progress_only_on_a_terminal(monkeypatch):
    from pkmtol.cli.common import show_progress

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert show_progress(False) is True and show_progress(True) is False
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert show_progress(False) is False


def test_out_of_memory_is_one_line_not_a_traceback(monkeypatch, capsys, tmp_path):
    import pkmtol.cli.allocate as cli_allocate

    def exhausted(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(cli_allocate, "allocate", exhausted)
    assert main(["allocate", str(SEED), "--out", str(tmp_path / "o"), *SMALL]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pkmtol: error: out of memory") and "Traceback" not in err
    assert list((tmp_path / "o").iterdir()) == []


def test_memory_estimate_matches_the_measured_scale():
    """The estimate for 100,000 samples on the seed robot is within 2× of the 291 MB measured (budget.py)."""
    from pkmtol.design.budget import available_memory, estimate_memory

    est = estimate_memory(load_mechanism(SEED), DesignOptions(samples=100_000))
    assert est.uncompensatable == 14 and est.parameters == 108
    assert 291e6 / 2 < est.total_bytes < 2 * 291e6
    # chunked: ten times the samples add their kept Δλ and Δα only (64 bytes a sample)
    more = estimate_memory(load_mechanism(SEED), DesignOptions(samples=1_000_000))
    assert more.total_bytes - est.total_bytes == pytest.approx(900_000 * 64)
    assert available_memory() is None or available_memory() > 0


def test_warnings_print_as_one_line(tmp_path, capsys):
    import shutil

    folder = tmp_path / "robot"
    shutil.copytree(SEED, folder)
    urdf = folder / "limb4.urdf"
    urdf.write_text(
        urdf.read_text(encoding="utf-8").replace(
            '<sphere radius="0.03" />', '<mesh filename="gone.stl" />', 1
        ),
        encoding="utf-8",
    )
    assert main(["check", str(folder), "--no-progress"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pkmtol: warning: limb 'limb4'") and "gone.stl" in err[0]
