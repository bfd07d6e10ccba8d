"""The generators of docs/tutorial.md and docs/machines.md (see scripts/make_docs.py)."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

from docs_run import ROOT, SEED, between, fenced, run

from pkmtol.present.terminal import fit_text

# --- the tutorial's generators ------------------------------------------------------------------------------


def _machines(tmp: Path) -> dict[str, str]:
    out, _, _ = run(MACHINES)
    return {"machines": out.rstrip("\n") + "\n"}


def _check(tmp: Path) -> dict[str, str]:
    out, _, _ = run(f"pkmtol check {SEED} --no-progress")
    return {"tutorial-check": fenced(out)}


def _mobility(tmp: Path) -> dict[str, str]:
    folder = tmp / "r2rps_ups"
    shutil.copytree(ROOT / SEED, folder)
    toml = folder / "mechanism.toml"
    toml.write_text(
        toml.read_text(encoding="utf-8").replace('actuated = ["limb3_p3"]', "actuated = []"), "utf-8"
    )
    out, _, _ = run(f"pkmtol check {folder} --no-progress", columns=1000)  # its last line, whole
    return {"tutorial-mobility": fenced(fit_text(out.rstrip("\n").splitlines()[-1], 100))}


def _errors(tmp: Path) -> dict[str, str]:
    out, _, _ = run(f"pkmtol errors {SEED}")
    lines = out.rstrip("\n").splitlines()
    rule = next(k for k, line in enumerate(lines) if line.startswith("---------"))
    rows = lines[rule + 1 :]
    limb4 = [line for line in rows if ",4}" in line.split()[0]]  # limb 4's rows (D–H names δx_{j,4})
    shown = [*lines[: rule + 1], f"…  ({len(rows) - len(limb4)} rows of limbs 1–3)", *limb4]
    return {"tutorial-errors": fenced("\n".join(shown))}


def _allocate(tmp: Path) -> dict[str, str]:
    """Sections 4 and 6 of the tutorial: the default design, the calibrated design and its study."""
    out, _, _ = run(f"{ALLOCATE} --out {tmp}/out", columns=1000)  # whole lines to read; shown at 100
    lines = [line.replace(f"{tmp}/out", "out/r2rps_ups") for line in out.rstrip("\n").splitlines()]
    head = between(lines, "pkmtol allocation", "Contributions to")
    wrote = [line for line in lines if line.startswith("wrote ")]
    note = [
        "…  (contributions, stack-up, capability and drawing tolerances — docs/report.md —, claimed-vs-true",
        "   reliability, the 'exact' design's table, traditional method, stage times)",
        "",
    ]
    claim = next(line for line in lines if line.startswith("claim ("))
    made = {"tutorial-allocate": fenced(fit_text("\n".join([*head[:-1], *note, *wrote, "", claim]), 100))}
    fosm, _, _ = run(f"{ALLOCATE} --method fosm --no-figures --out {tmp}/fosm", columns=1000)
    fosm_min = re.search(r"over the task space: min R = ([\d.]+) % \(grid pose (\d+)\)", fosm)
    n = re.search(r"(\d+) uncompensatable,", out)
    ratio = re.search(r"median traditional/new ([\d.]+)", out)
    doc = json.loads((tmp / "out" / "allocation.json").read_text())
    scale = _exact_scale(doc)
    made["tutorial-allocate-prose"] = (
        "How to read the table: each row is an uncompensatable error with its sensitivity at the most\n"
        "error-sensitive point; each column is a reliability index β, with R = Φ(β) above the table. The "
        f"entry is the paper's FOSM tolerance σ_i = Δλ*/(√n ω_i β) (n = {n.group(1) if n else '?'}), made at "
        "one pose; σ_i·β is the same in every column of a row. The `exact design` column is the design the "
        "command verifies and claims (the default `--method exact`): the same shape scaled by "
        f"{scale:.3f} so that the exact reliability of the linear model is at least R = Φ(2) = 97.72 % at "
        "every grid pose, not only at the design point"
        + (
            f" (the FOSM design reaches {fosm_min.group(1)} % at grid pose {fosm_min.group(2)})"
            if fosm_min
            else ""
        )
        + ". In the design case the distance `δa_{3,4}` of limb 4 must be held to "
        f"{_cell(lines, 'δa_{3,4}', 'exact design')} mm and the twist angle `δφ_{{4,4}}` to "
        f"{_cell(lines, 'δφ_{4,4}', 'exact design')} mrad. The verification then draws errors at those "
        "tolerances at random task-space poses, with the linear model and with exact kinematics of the "
        f"perturbed mechanism: the paper's uniform ±σ errors fail in {_failures(lines, 'uniform_sigma')} % "
        "of the linear samples; Gaussian errors of standard deviation σ_i in "
        f"{_failures(lines, 'gaussian')} %, inside the 2.28 % the claim allows at every pose. The last "
        "line is the claim and where it holds ([claims.md](claims.md)); `--method fosm` gives the paper's "
        'one-pose design, and its claim line says "at the design point only" with the minimum over the '
        "task space beside it. The rest of the output compares FOSM's claims with the exact reliability "
        "and with the traditional method (every error, no compensation), whose shared tolerances are "
        f"{float(ratio.group(1)) if ratio else float('nan'):.2f} × as wide as FOSM's.\n"
    )
    made.update(_calibrated(tmp, _row(lines, "δd_{1,4}")[3]))
    return made


def _exact_scale(doc: dict) -> float:
    """The exact design's tolerances over the FOSM design-β ones (one number: the shape is kept)."""
    md = doc["method_design"]
    column = doc["beta"].index(doc["design_beta"])
    fosm = {row["name"]: row["tolerance"][column] for row in doc["parameters"] if row["tolerance"]}
    ratios = [
        t / fosm[name] for name, t in zip(md["parameters"], md["tolerance"], strict=True) if name in fosm
    ]
    return sum(ratios) / len(ratios) if ratios else float("nan")


def _cell(lines: list[str], name: str, column: str) -> str:
    """The cell of row ``name`` under the header ``column`` (in whichever panel of the table holds it)."""
    k = next(i for i, line in enumerate(lines) if line.startswith("No.") and column in line)
    at = lines[k].index(column)
    rule = lines[k + 1]
    left = rule.rfind(" ", 0, at) + 1
    right = rule.find(" ", at)
    right = len(rule) if right < 0 else right
    row = next(line for line in lines[k + 2 :] if len(line.split()) > 1 and line.split()[1] == name)
    return row[left:right].strip()


def _exact_count(lines: list[str]) -> str:
    """The sample count of the Gaussian exact row of the verification table."""
    return next(line.split() for line in lines if line.split()[:2] == ["gaussian", "exact"])[2]


def _row(lines: list[str], name: str) -> list[str]:
    return next(line.split() for line in lines if len(line.split()) > 2 and line.split()[1] == name)


def _tolerance(lines: list[str], name: str) -> str:
    """The β = 2 tolerance of ``name`` in the first panel of the tolerance table."""
    header = next(line.split() for line in lines if line.startswith("No.") and "β=2" in line)
    return _row(lines, name)[header.index("β=2") + 1]  # the sensitivity cell is two words


def _failures(lines: list[str], errors: str) -> str:
    """The linear failure rate [%] of ``errors`` in the verification table."""
    return next(line.split() for line in lines if line.split()[:2] == [errors, "linear"])[5]


def _calibrated(tmp: Path, sens4: str) -> dict[str, str]:
    out, wall, cpu = run(CALIBRATED + f" --out {tmp}/cal", columns=1000)
    lines = out.rstrip("\n").splitlines()
    shown = [lines[0], "…", *between(lines, "compensation:", "Traditional"), "…"]
    stages = next((line for line in lines if line.startswith("stage times:")), "")
    exact = re.search(r"exact design ([\d.]+) s", stages)
    part = f", {float(exact.group(1)):.0f} s of it the exact design" if exact else ""
    plan = re.search(r"'compensatable' \((\d+) parameters, rank (\d+)\), (\d+) d-optimal poses", out)
    noise = re.search(r"tracker noise ([\d.]+) mm per coordinate", out)
    classes = re.search(r"classes: (\d+) identified, \d+ absorbed, (\d+) toleranced", out)
    floor = re.search(r"leaves σ = ([\d.]+) µm", out)
    if not (plan and noise and classes and floor):
        raise SystemExit("make_docs: the calibrated allocate output changed; update _calibrated")
    made = {
        "tutorial-allocate-calibrated": fenced(fit_text("\n".join(shown), 100)),
        "tutorial-allocate-calibrated-prose": (
            f"What changed against section 4: the calibration plan ({plan.group(3)} D-optimal poses, "
            f"tracker noise {noise.group(1)} mm per coordinate, the controller's {plan.group(1)} "
            f"compensatable parameters of which {plan.group(2)} are identifiable) identifies "
            f"{classes.group(1)} parameters, so only {classes.group(2)} remain to be toleranced, and their "
            f"sensitivities after calibration are much smaller: `δd_{{1,4}}` goes from {sens4} to "
            f"{_row(lines, 'δd_{1,4}')[3]} µm/µm. The tracker noise alone leaves σ = "
            f"{float(floor.group(1)):.1f} µm at the design point, a floor no tolerance can buy back (a "
            "target below β·σ is refused with `NoiseFloorError`). `--method exact` spends the rest of the "
            "budget per parameter on the exact distribution of Δλ, and `--orientation-target` adds the "
            "tool axis' tilt Δα as a second requirement: the orientation section gives the joint "
            "probability of missing either. The Gaussian errors at the exact design fail in "
            f"{_failures(lines, 'gaussian')} % of the linear samples; the exact rows are "
            f"{_exact_count(lines)} machines, each calibrated on exact kinematics, enough for an interval "
            "that tells 2.3 % from 4.6 % (the run took "
            f"{wall:.0f} s, {cpu:.0f} s of CPU, when this page was generated{part}). The study below "
            "checks the machines built at these tolerances over held-out random poses:\n"
        ),
    }
    made.update(_study(tmp))
    return made


def _study(tmp: Path) -> dict[str, str]:
    # whole rows to read the numbers from; the page shows them fitted to 100 columns, as printed
    out, wall, cpu = run(STUDY.replace("out/r2rps_ups", f"{tmp}/cal") + f" --out {tmp}/study", columns=1000)
    lines = out.rstrip("\n").splitlines()
    k = next(i for i, line in enumerate(lines) if line.lstrip().startswith("mean Δλ [µm]"))
    end = next((i for i in range(k + 2, len(lines)) if not lines[i].strip()), len(lines))
    table = lines[k:end]
    shown = [*table[:2], *(line for line in table[2:] if line.startswith(STUDY_ROWS)), "…"]
    names = [re.split(r"\s{2,}", line.strip())[0] for line in table[2:]]
    ideal = _beyond(table, next(n for n in names if n.startswith("Eq. 25")))
    after = _beyond(table, next(n for n in names if n.startswith("after calibration: compensatable")))
    gaps = [
        abs(a - b)
        for name in names
        if name.startswith("after calibration: ")
        and "linear prediction: " + name.removeprefix("after calibration: ") in names
        for a, b in zip(
            _microns(table, name),
            _microns(table, "linear prediction: " + name.removeprefix("after calibration: ")),
            strict=True,
        )
    ]
    return {
        "tutorial-allocate-study": (
            "draws 100 machines at these tolerances (the errors the calibration identifies, compensatable "
            "or not, at the manufacturing σ of the `[calibration]` table, by default 0.1 mm and 0.5 mrad), "
            "measures each at the planned poses on exact kinematics with tracker noise, identifies, "
            f"compensates and measures held-out random poses ({wall:.0f} s, {cpu:.0f} s of CPU, when this "
            "page was generated):\n\n" + fenced(fit_text("\n".join(shown), 100)) + "\n"
            f"The tolerances that Eq. 25 would call far too loose ({ideal:.1f} % of the poses beyond Δλ* if "
            "the controller only knew the compensatable errors) meet the requirement on the really "
            f"calibrated machines in all but {after:.2f} % of the held-out poses, and the linear "
            "post-calibration model predicts the exact result to within "
            f"{max(gaps, default=float('nan')):.1f} µm (mean, p95, p99 and max of Δλ). "
            "[compensation.md](compensation.md) has the method and the cost comparison.\n"
        )
    }


STUDY_ROWS = (
    "before calibration",
    "Eq. 25",
    "after calibration: compensatable",
    "linear prediction: compensatable",
)


def _cells(table: list[str], name: str) -> list[str]:
    """The cells of row ``name`` (split at runs of two or more spaces), without the name."""
    row = next(line for line in table[2:] if line.strip().startswith(name))
    return re.split(r"\s{2,}", row.strip())[1:]


def _microns(table: list[str], name: str) -> list[float]:
    return [float(c) for c in _cells(table, name)[:4]]


def _beyond(table: list[str], name: str) -> float:
    return float(_cells(table, name)[4].split()[0])


ALLOCATE = f"pkmtol allocate {SEED}"
MACHINES = (
    "scripts/compare_machines.py robots/r2rps_ups robots/tricept robots/exechon robots/sprint_z3 "
    "--beta 2 --appendix"
)
CALIBRATED = (
    f"pkmtol allocate {SEED} --compensation calibrated --method exact --orientation-target 0.5mrad "
    "--no-figures --no-progress"
)
STUDY = (
    f"pkmtol calibrate {SEED} --simulate --machines 100 --tolerances out/r2rps_ups/allocation.json "
    "--no-figures"
)
OTHERS = ("robots/tricept/*", "robots/exechon/*", "robots/sprint_z3/*")
