"""Fuzz ``pkmtol calibrate``'s data path: mutated measurement CSVs, plans and allocation files.

Every case starts from a good file of the seed robot (a simulated session: 30 D-optimal poses,
machine errors, 10 µm noise) and applies one seeded mutation. The oracles:

* **no traceback**: the readers (:func:`read_measurements`, :func:`read_tolerances`) and the
  command line raise or print only pkmtol errors (``pkmtol: error: …``, exit 2);
* **nothing written on refusal**: a run that exits non-zero leaves its ``--out`` folder without a
  file;
* **no exit 0 on data that cannot be right**: mutations that make the data wrong by construction
  (units, zeros, a repeated point, a frame offset, an outlier pose, a plan instead of
  measurements, garbage) must not give a calibrated machine.

A command-line case is ``pkmtol calibrate --measurements case.csv`` (a mutated measurement
file), or ``--measurements good.csv --prior --tolerances case.json`` (a mutated allocation file:
the prior's σ come from it). It runs ``pkmtol.cli.main(argv)`` in process, the real command line
down to the files it writes; the process keeps what the command line keeps between runs (the
parser, each loaded robot and its grid sweep: :mod:`pkmtol.cli.robot_cache`), so a case costs
about 0.1 s instead of 1–4 s. ``run_cli_subprocess`` runs a case as ``python -m pkmtol.cli``.

Usage:
    python scripts/fuzz_calibrate.py --cases 20000 --seed 0          # the readers, every case
    python scripts/fuzz_calibrate.py --cases 2000 --cli-every 1       # and every case through the CLI

``tests/test_fuzz_calibrate.py`` runs 1,000 reader cases, 1,000 command-line cases in process
and a few as subprocesses in CI.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEED_ROBOT = ROOT / "robots" / "r2rps_ups"


@dataclass(frozen=True)
class Case:
    """One mutated input: its kind (``csv``, ``allocation``), text, and whether it cannot be right."""

    mutation: str
    kind: str
    text: str
    wrong: bool


def session() -> tuple[object, str, str, str]:
    """The seed robot, a good measurement CSV, its plan CSV and a minimal allocation.json (urdf set)."""
    from pkmtol.calibration.identification import model_positions
    from pkmtol.calibration.machine import Machine
    from pkmtol.calibration.measurement_files import measurements_csv, plan_csv
    from pkmtol.calibration.plan import candidate_pool, make_plan
    from pkmtol.calibration.settings import CalibrationSettings
    from pkmtol.error_model.parameters import parameter_set
    from pkmtol.error_model.sweep import sweep
    from pkmtol.kinematics.closed_chain import ClosedChain
    from pkmtol.model.loader import load_mechanism

    mech = load_mechanism(SEED_ROBOT)
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
    good = measurements_csv(mech, plan.maps.commands, y)
    names = pset.names
    allocation = json.dumps(
        {
            "mechanism": mech.name,
            "parameter_set": "urdf",
            "beta": [1.0, 2.0],
            "design_beta": 2.0,
            "parameters": [
                {"name": n, "tolerance": [2e-5, 1e-5], "class_in_mode": "uncompensatable"} for n in names[-4:]
            ],
        }
    )
    return mech, good, plan_csv(mech, plan.maps.commands, plan.maps.points_m), allocation


def _table(text: str) -> tuple[list[str], list[list[str]]]:
    lines = text.splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def _join(header: list[str], rows: list[list[str]]) -> str:
    return "\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n"


def _xyz(header: list[str]) -> list[int]:
    return [j for j, h in enumerate(header) if h.split(" ")[0] in ("x", "y", "z")]


def _edit_xyz(text: str, fn: Callable[[np.ndarray], np.ndarray]) -> str:
    header, rows = _table(text)
    cols = _xyz(header)
    m = np.array([[float(r[j]) for j in cols] for r in rows])
    m = fn(m)
    for r, v in zip(rows, m, strict=True):
        for j, x in zip(cols, v, strict=True):
            r[j] = repr(float(x))
    return _join(header, rows)


GARBAGE = [
    "",
    "x",
    "nan",
    "inf",
    "-inf",
    "1e300",
    "-1e309",
    "0x10",
    "1,5",
    "١٢",
    "\x00",
    "1e",
    "--1",
    "+",
    "None",
    "[]",
]


def mutate(rng: np.random.Generator, good: str, plan: str, allocation: str) -> Case:
    """One seeded mutation of the good files (see the module docstring)."""
    header, rows = _table(good)
    k = int(rng.integers(0, 22))
    if k == 0:  # a cell replaced by garbage
        r, j = int(rng.integers(0, len(rows))), int(rng.integers(0, len(header)))
        rows[r][j] = GARBAGE[int(rng.integers(0, len(GARBAGE)))]
        return Case("garbage cell", "csv", _join(header, rows), wrong=j != 0)  # a pose label may be anything
    if k == 1:  # a header cell changed
        j = int(rng.integers(0, len(header)))
        was = header[j]
        header[j] = str(
            rng.choice(
                ["x", "x [deg]", "z [km]", "", "pose", "target", header[(j + 1) % len(header)], "q [mm]"]
            )
        )
        return Case("header cell", "csv", _join(header, rows), wrong=header[j] != was)  # "pose" for "pose"
    if k == 2:  # a row cut short or made longer
        r = int(rng.integers(0, len(rows)))
        rows[r] = rows[r][: int(rng.integers(0, len(rows[r])))] if rng.random() < 0.5 else rows[r] + ["1"]
        # a row cut to nothing is a blank line: the file then just lacks that pose
        return Case("row length", "csv", _join(header, rows), wrong=bool("".join(rows[r]).strip()))
    if k == 3:  # the file cut at a random byte
        return Case("truncated", "csv", good[: int(rng.integers(0, len(good)))], wrong=False)
    if k == 4:  # random bytes
        data = rng.integers(0, 256, size=int(rng.integers(0, 400)), dtype=np.uint8).tobytes()
        return Case("random bytes", "csv", data.decode("latin-1"), wrong=True)
    if k == 5:
        return Case("all zeros", "csv", _edit_xyz(good, lambda m: 0 * m), wrong=True)
    if k == 6:
        f = float(rng.choice([1e-3, 1e3, 25.4, 1 / 25.4, 10.0]))
        return Case("units", "csv", _edit_xyz(good, lambda m: f * m), wrong=True)
    if k == 7:
        return Case("one point", "csv", _edit_xyz(good, lambda m: 0 * m + m[0]), wrong=True)
    if k == 8:
        t = rng.standard_normal(3)
        t = 50.0 * t / np.linalg.norm(t)  # mm
        return Case("frame offset", "csv", _edit_xyz(good, lambda m: m + t), wrong=True)
    if k == 9:
        r = int(rng.integers(0, len(rows)))

        def outlier(m: np.ndarray) -> np.ndarray:
            m = m.copy()
            m[r] += rng.choice([-1, 1], size=3) * 5.0  # 5 mm at one pose
            return m

        return Case("outlier pose", "csv", _edit_xyz(good, outlier), wrong=True)
    if k == 10:  # a duplicated row
        r = int(rng.integers(0, len(rows)))
        return Case("duplicated row", "csv", _join(header, rows + [list(rows[r])]), wrong=True)
    if k == 11:  # rows dropped: fewer poses
        keep = int(rng.integers(0, len(rows)))
        return Case("rows dropped", "csv", _join(header, rows[:keep]), wrong=False)
    if k == 12:  # a command scaled: the nominal machine does not reach it, or not there
        j = int(rng.integers(1, 4))
        r = int(rng.integers(0, len(rows)))
        rows[r][j] = repr(float(rows[r][j]) * float(rng.choice([0.0, -1.0, 2.0, 1e3])))
        return Case("command", "csv", _join(header, rows), wrong=True)
    if k == 13:
        return Case("plan as measurements", "csv", plan, wrong=True)
    if k == 14:  # a target index out of range or not an integer
        r = int(rng.integers(0, len(rows)))
        rows[r][header.index("target")] = str(rng.choice(["1", "-1", "0.0", "a", "99", ""]))
        return Case("target index", "csv", _join(header, rows), wrong=True)
    if k == 15:  # columns swapped
        a, b = rng.choice(len(header), size=2, replace=False)
        header[a], header[b] = header[b], header[a]
        return Case("columns swapped", "csv", _join(header, rows), wrong=a != b)
    if k == 16:  # the noise of a good file: fine (the oracle of exit 0 is not asked)
        return Case("good", "csv", good, wrong=False)
    if k == 17:  # BOM, CRLF, quotes, blank lines
        return Case("formatting", "csv", "\ufeff" + good.replace("\n", "\r\n\r\n"), wrong=False)
    # allocation files (calibrate --tolerances ... --prior)
    doc = json.loads(allocation)
    if k == 18:
        key = str(rng.choice(["beta", "design_beta", "parameter_set", "parameters", "mechanism"]))
        doc[key] = [None, "x", 5, {}, [], 1e308, -1][int(rng.integers(0, 7))]
        return Case("allocation field", "allocation", json.dumps(doc), wrong=key != "mechanism")
    if k == 19:
        p = doc["parameters"][int(rng.integers(0, len(doc["parameters"])))]
        key = str(rng.choice(["name", "tolerance"]))
        p[key] = [None, "x", [1], [float("nan"), 1], 7, ["a", "b"]][int(rng.integers(0, 6))]
        # a null tolerance is an allocation's "not toleranced" (a compensatable or absorbed error)
        return Case(
            "allocation row", "allocation", json.dumps(doc), wrong=not (key == "tolerance" and p[key] is None)
        )
    if k == 20:
        doc["mechanism"] = "tricept"
        return Case("another robot", "allocation", json.dumps(doc), wrong=True)
    text = allocation[: int(rng.integers(0, len(allocation)))]
    return Case("allocation truncated", "allocation", text, wrong=True)


def run_reader(case: Case, mech: object, folder: Path) -> str:
    """``refused``, ``read`` or ``ESCAPE <exception>`` for the case's reader."""
    from pkmtol.calibration.measurement_files import read_measurements
    from pkmtol.calibration.settings import CalibrationSettings
    from pkmtol.calibration.tolerance_file import read_tolerances
    from pkmtol.error_model.parameters import parameter_set
    from pkmtol.exceptions import PkmtolError

    path = folder / ("case.csv" if case.kind == "csv" else "allocation.json")
    path.write_text(case.text, encoding="utf-8", errors="surrogatepass")
    try:
        if case.kind == "csv":
            read_measurements(path, mech, 1)
        else:
            read_tolerances(path, mech.name, parameter_set(mech, "urdf"), CalibrationSettings())
    except PkmtolError:
        return "refused"
    except Exception as err:  # noqa: BLE001 - what the fuzzer looks for
        return f"ESCAPE {type(err).__name__}: {err}"
    return "read"


def _argv(case: Case, folder: Path, good: str) -> list[str]:
    """Write the case's files into ``folder``; the ``pkmtol calibrate`` arguments that read them."""
    path = folder / ("case.csv" if case.kind == "csv" else "allocation.json")
    path.write_text(case.text, encoding="utf-8", errors="surrogatepass")
    argv = ["calibrate", str(SEED_ROBOT), "--set", "urdf", "--out", str(folder / "out")]
    if case.kind == "csv":
        return [*argv, "--measurements", str(path)]
    (folder / "good.csv").write_text(good, encoding="utf-8")
    return [*argv, "--measurements", str(folder / "good.csv"), "--prior", "--tolerances", str(path)]


def _written(folder: Path) -> list[str]:
    out = folder / "out"
    return sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()) if out.exists() else []


def run_cli(case: Case, folder: Path, good: str) -> tuple[int | str, str, list[str]]:
    """``pkmtol calibrate`` on the case, in process: its exit code, its stderr and the files it wrote."""
    from pkmtol.cli import main

    shutil.rmtree(folder / "out", ignore_errors=True)
    argv = _argv(case, folder, good)
    err = io.StringIO()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            code: int | str = main(argv)
    except BaseException as exc:  # noqa: BLE001 - a traceback is what the fuzzer looks for
        code = f"ESCAPE {type(exc).__name__}: {exc}"
    return code, err.getvalue(), _written(folder)


def run_cli_subprocess(case: Case, folder: Path, good: str) -> tuple[int | str, str, list[str]]:
    """As :func:`run_cli`, as ``python -m pkmtol.cli`` in a process of its own."""
    shutil.rmtree(folder / "out", ignore_errors=True)
    argv = _argv(case, folder, good)
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.run(
        [sys.executable, "-m", "pkmtol.cli", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        stdin=subprocess.DEVNULL,
    )
    return proc.returncode, proc.stderr, _written(folder)


def cli_problem(case: Case, code: int | str, err: str, written: list[str]) -> str | None:
    """What is wrong with a command-line outcome (None: nothing)."""
    if not isinstance(code, int):
        return str(code)
    if "Traceback" in err:
        return f"traceback: {err[-300:]}"
    if code not in (0, 2):
        return f"exit {code}: {err[-300:]}"
    if code == 2 and "pkmtol: error: " not in err:
        return f"exit 2 without a pkmtol error message: {err[-300:]!r}"
    if code != 0 and written:
        return f"exit {code}, yet it wrote {', '.join(written[:5])}"
    if code == 0 and case.wrong:
        return "exit 0 on data that cannot be right"
    if code == 0 and not written:
        return "exit 0 without writing the run's files"
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=20_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--cli-every", type=int, default=0, help="run every Nth case through the CLI too (0: none)"
    )
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "src"))
    mech, good, plan, allocation = session()
    rng = np.random.default_rng(args.seed)
    outcomes: Counter[str] = Counter()
    bad: list[str] = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for i in range(args.cases):
            case = mutate(rng, good, plan, allocation)
            got = run_reader(case, mech, folder)
            outcomes[f"reader {got.split(':')[0]}"] += 1
            if got.startswith("ESCAPE"):
                bad.append(f"case {i} ({case.mutation}): reader {got}")
            if args.cli_every and i % args.cli_every == 0:
                code, err, written = run_cli(case, folder, good)
                outcomes[f"cli exit {code if isinstance(code, int) else 'ESCAPE'}"] += 1
                problem = cli_problem(case, code, err, written)
                if problem is not None:
                    bad.append(f"case {i} ({case.mutation}): cli {problem}")
    print(f"{args.cases} cases, seed {args.seed}, {time.perf_counter() - t0:.1f} s")
    for key, n in sorted(outcomes.items()):
        print(f"  {key}: {n}")
    print(f"{len(bad)} problems")
    for line in bad[:50]:
        print("  " + line)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
