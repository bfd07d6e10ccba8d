"""The generators of docs/compensation.md, docs/figaroh-crosscheck.md and docs/scale.md (see
scripts/make_docs.py): the output of scripts/compare_compensation.py, scripts/crosscheck_figaroh.py
and of a sweep, and the numbers the pages' prose reads from it."""

from __future__ import annotations

import json
import re
from pathlib import Path

from docs_run import SEED, fenced, run

from pkmtol.present.terminal import fit_text

COMPENSATION = f"scripts/compare_compensation.py {SEED} --poses 15 40 100 --noise 0.01mm"
COST_CALIBRATED = (
    f"pkmtol allocate {SEED} --compensation calibrated --method cost --samples 2000 --exact-samples 20 "
    "--no-figures --no-progress"
)
COST_STUDY = f"pkmtol calibrate {SEED} --simulate --machines 40 --holdout 100 --no-figures"
FIGAROH = "scripts/crosscheck_figaroh.py"
#: The commands as the pages' blocks name them.
COMPENSATION_SHOWN = f"python {COMPENSATION}; {COST_CALIBRATED}; {COST_STUDY}"
FIGAROH_SHOWN = f"python {FIGAROH} [--noise-um 10] [--error-scale 0.1] [--names]"


def _split(line: str) -> list[str]:
    """A text table row's cells (split at runs of two or more spaces)."""
    return re.split(r"\s{2,}", line.strip())


def _markdown_rows(text: str, header_start: str) -> tuple[list[str], list[list[str]]]:
    """The header and rows' cells of the Markdown table whose header starts with ``header_start``."""
    lines = text.splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith(header_start))
    cells = [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines[k:]]
    end = next((i for i, line in enumerate(lines[k:]) if not line.startswith("|")), len(lines) - k)
    return cells[0], cells[2:end]


def _factor(cell: str) -> float | None:
    m = re.search(r"\(([\d.]+)×\)", cell)
    return float(m.group(1)) if m else None


def _value(cell: str) -> float | None:
    m = re.match(r"([\d.]+)", cell)
    return float(m.group(1)) if m else None


def _compensation(tmp: Path) -> dict[str, str]:
    out, _, _ = run(COMPENSATION)
    body = out.split("\n", 1)[1].lstrip("\n")  # the page keeps its own title
    header, rows = _markdown_rows(out, "| parameter |")
    params = [r for r in rows if not r[0].startswith("**")]
    cost = next(r for r in rows if r[0].startswith("**cost**"))
    col = {name: k for k, name in enumerate(header)}
    d40, r40, none = col["cal. 40 d"], col["cal. 40 r"], col["none"]
    kept = [(r[0], _factor(r[d40])) for r in params if _factor(r[d40]) is not None]
    lo, hi = min(kept, key=lambda x: x[1] or 0), max(kept, key=lambda x: x[1] or 0)
    longest = max(_value(r[d40]) or 0 for r in params if r[1] == "mm")
    random = [f for r in params if (f := _factor(r[r40])) is not None]
    lengths = [v for r in params if r[1] == "mm" and (v := _value(r[none])) is not None]
    angles = [v for r in params if r[1] == "mrad" and (v := _value(r[none])) is not None]
    _, fosm = _markdown_rows(out, "| plan |")
    toleranced = next(r for r in rows if r[0].startswith("**toleranced**"))
    by_plan = {r[0]: r for r in fosm}
    d_opt = [r for name, r in by_plan.items() if "d-optimal" in name and not name.startswith("15 ")]
    every_d = all(r[2] == "100.000" for r in d_opt)
    rnd = by_plan["40 random poses"]
    reading = (
        "* After a calibration on 40 D-optimal poses at 10 µm, every tolerance the cost-optimal design "
        f"keeps\n  loosens against the ideal mode's — by {lo[1]:.1f}× ({lo[0]}) to {hi[1]:.1f}× ({hi[0]}) "
        "— and the "
        f"total cost\n  falls from {cost[col['ideal']]} to {cost[d40]}. The largest length tolerances "
        f"({longest:.2f} mm) approach the cost model's\n  default upper process limit of 1 mm: the "
        "calibration, not the machining, carries the accuracy.\n"
        f"* The plan matters as much as the pose count: 40 random poses give tolerances of "
        f"{min(random):.2f}× to {max(random):.1f}×\n  the ideal ones (cost {cost[r40]}), while 15 random "
        "poses cannot reach Δλ* at all — the noise amplified by\n  that plan alone exceeds the target at "
        "some grid pose (named error, with the floor).\n"
        "* δθ_{4,4} and δθ_{e,4}, uncompensatable under Eq. 25, are *identified* after calibration: their\n"
        "  effect at P lies in the span of the compensatable errors' columns at every pose, so the fit\n"
        "  removes it. The identified parameters are drawn at their manufacturing σ in verification; their\n"
        "  columns of L vanish.\n"
        "* The paper's FOSM β = 2 design (Table III) is "
        + ("far more than enough" if every_d else "not always enough")
        + " after a D-optimal calibration:\n  its exact reliability at the worst grid pose is "
        + " and ".join(f"{r[2]} % for {r[0]}" for r in d_opt)
        + f". With 40 random poses\n  it is {rnd[2]} % at the worst grid pose (claimed 97.72 %).\n"
        f"* Without compensation (`none`, the traditional method) the {toleranced[none]} "
        "non-absorbed errors must be held\n  to "
        f"{min(lengths):.4g}–{max(lengths):.4g} mm and {min(angles):.4g}–{max(angles):.4g} mrad "
        f"(cost {cost[none]}).\n"
    )
    made = {"compensation-table": body.rstrip("\n") + "\n", "compensation-reading": reading}
    made.update(_cost_study(tmp))
    return made


def _cost_study(tmp: Path) -> dict[str, str]:
    run(COST_CALIBRATED + f" --out {tmp}/A")
    out, _, _ = run(COST_STUDY + f" --tolerances {tmp}/A/allocation.json --out {tmp}/S", columns=1000)
    lines = out.splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("calibration study on exact kinematics"))
    end = next(i for i in range(k, len(lines)) if lines[i].startswith("case"))
    study = lines[k:end]
    while study and not study[-1].strip():
        study.pop()
    gap_line = next(i for i in range(end, len(lines)) if "max |Δλ exact" in lines[i])
    header = re.split(r"\s{2,}", lines[gap_line].strip())
    row = re.split(r"\s{2,}", lines[gap_line + 2].strip())
    gap = row[header.index(next(h for h in header if h.startswith("max |Δλ exact")))]
    tilt = next(
        re.split(r"\s{2,}", line.strip())
        for line in study
        if line.startswith("after calibration: compensatable")
    )
    head = next(re.split(r"\s{2,}", line.strip()) for line in study if "mean tilt" in line)
    mean_tilt = tilt[head.index("mean tilt [µrad]") + 1]
    return {
        "compensation-study": fenced(fit_text("\n".join(study), 100)),
        "compensation-study-prose": (
            "The design holds after the calibration it was made for (largest exact-vs-linear difference "
            f"{gap} µm),\nand only then: compare the Eq. 25 row. The tool axis tilts by {mean_tilt} µrad on "
            "average after\nthe calibration: tolerances this loose are only acceptable with an orientation "
            "target beside Δλ*\n(`--orientation-target`, [theory.md](theory.md#orientation-accuracy)).\n"
        ),
    }


def _figaroh(tmp: Path) -> dict[str, str]:
    plain, _, _ = run(FIGAROH)
    noisy, _, _ = run(FIGAROH + " --noise-um 10")
    small, _, _ = run(FIGAROH + " --noise-um 10 --error-scale 0.1")
    names, _, _ = run(FIGAROH + " --names")
    named = names.splitlines()
    k = next(i for i, line in enumerate(named) if line.startswith("pkmtol base parameters:"))
    tail = [line for line in small.splitlines() if line.strip()][-5:]
    stop = next((i for i in range(k, len(named)) if named[i].startswith("limb1 of")), len(named))
    names_of_first_run = [line for line in named[k:stop] if line.strip()]

    def value(text: str, label: str) -> str:
        """The first number after ``label`` on its line (pkmtol's column where both tools have one)."""
        line = next(line for line in text.splitlines() if line.strip().startswith(label))
        rest = line.strip()[len(label) :]
        return re.findall(r"\d\.\d+e[-+]\d+|\d+(?:\.\d+)?", rest)[0]

    rank = value(plain, "base parameters (rank)")
    return {
        "figaroh-run": fenced(plain.rstrip("\n") + "\n\n" + noisy),
        "figaroh-small": fenced("\n".join(tail)),
        "figaroh-names": fenced("\n".join(names_of_first_run)),
        "figaroh-result": (
            f"- both find **{rank} base parameters**, and their base columns span the same space (largest\n"
            f"  principal angle {value(plain, 'largest principal angle')} rad);\n"
            "- without noise both reproduce the truth at held-out configurations to "
            f"{value(plain, 'held-out max |P - P_true|')} m (pkmtol),\n  and agree with each other to "
            f"{value(plain, 'held-out max |P_pkmtol - P_FIGAROH|')} m;\n"
            "- with 10 µm noise, pkmtol's model solved to the least-squares minimum predicts the same "
            "held-out\n  positions as FIGAROH to "
            f"{value(noisy, 'pkmtol' + chr(39) + 's model at the least-squares minimum')} m. The "
            "frozen-Jacobian Gauss–Newton that pkmtol's calibration\n  uses stops "
            f"{value(noisy, 'held-out max |P_pkmtol - P_FIGAROH|')} m away (see "
            "[below](#what-the-comparison-found));\n"
            "- pkmtol's base combinations `β = δ_B + K' δ_D`, evaluated on FIGAROH's estimate, agree with\n"
            "  pkmtol's own estimate to first order. The difference is "
            f"{value(noisy, 'pkmtol' + chr(39) + 's β on FIGAROH')} of the parameter scale, and\n  "
            f"{value(small, 'pkmtol' + chr(39) + 's β on FIGAROH')} when the errors fall 10-fold.\n"
        ),
    }


# --- docs/scale.md: the sweep on 2 local workers, and the projection to a cluster --------------------

SWEEP = (
    f"pkmtol sweep {SEED} --vary limbs[limb1].dh.links[0][2]=0.45:0.55:16 "
    "--vary task_space.radius_m=0.55:0.6:4 --no-progress"
)
#: Dask distributed's overhead per task, from its documentation ("about 1 ms").
DASK_TASK_S = 1e-3


def _scale(tmp: Path) -> dict[str, str]:
    _, serial_wall, serial_cpu = run(SWEEP + f" --out {tmp}/serial")
    _, pool_wall, pool_cpu = run(SWEEP + f" --out {tmp}/pool --workers 2")
    variants = json.loads((tmp / "serial" / "sweep.json").read_text(encoding="utf-8"))["variants"]
    pooled = json.loads((tmp / "pool" / "sweep.json").read_text(encoding="utf-8"))["variants"]

    def without_seconds(rows: list[dict]) -> list[dict]:
        return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]

    same = without_seconds(variants) == without_seconds(pooled)
    seconds = [float(v["seconds"]) for v in variants]
    per_variant = sum(seconds) / len(seconds)
    serial_part = max(0.0, serial_wall - sum(seconds))
    n, workers = 10_000, 64
    compute = n * per_variant / workers
    share = (
        "dominates a sweep this small"
        if serial_part > sum(seconds)
        else f"is {serial_part / serial_wall:.0%} of the serial run"
    )
    return {
        "scale-sweep": (
            f"**Measured on 2 local workers** (when this page was generated, on the machine that generated "
            f"it): the {len(variants)}-variant\nsweep above took {pool_wall:.1f} s wall with `--workers 2` "
            f"against {serial_wall:.1f} s serially, for {pool_cpu:.1f} s of CPU against {serial_cpu:.1f} s"
            + (", and the same tables (only the `seconds` fields differ)" if same else "")
            + f". A\nvariant costs {per_variant:.3f} s (the mean of `seconds` in `sweep.json`; "
            f"{min(seconds):.3f} s the fastest); the command's serial\npart (start-up, the reference "
            f"design, writing the tables: {serial_part:.1f} s) {share}; the speed-up\ngrows with the "
            "number of variants. With other jobs on a shared machine the second worker may find no\nfree "
            "core: measure on your own machine before raising the default.\n"
        ),
        "scale-projection": (
            f"From the sweep above ({per_variant:.3f} s per variant, serial), for 10⁴ variants on {workers} "
            "single-threaded\nworkers of the same speed:\n\n"
            f"* compute: 10⁴ × {per_variant:.3f} s / {workers} ≈ **{compute:.0f} s**;\n"
            '* scheduling: "each task suffers about 1 ms of overhead" on Dask distributed (its '
            f"documentation),\n  mostly on the scheduler: ≈ {n * DASK_TASK_S:.0f} s for 10⁴ tasks, "
            "overlapping the compute;\n"
            "* serial part: the command's start-up and reference design, the workers' start-up, and the "
            "table of\n  10⁴ rows.\n\n"
            f"So about **{max(compute, n * DASK_TASK_S):.0f} s** and more wall for the sweep, against "
            f"10⁴ × {per_variant:.3f} s ≈ {n * per_variant / 60:.1f} min serially on one core;\n"
            "when the scheduler's share is the larger, chunks of several variants per task are the next "
            "step.\n"
        ),
    }


# --- docs/robots.md: what `pkmtol check` and `pkmtol errors` say of each bundled machine ----------

ROBOTS = ("tricept", "exechon", "sprint_z3", "delta")
ROBOT_FILES = (f"{SEED}/*", *(f"robots/{r}/*" for r in ROBOTS))


def _robots(tmp: Path) -> dict[str, str]:
    seed, _, _ = run(f"pkmtol check {SEED} --no-progress", columns=1000)
    made = {"robots-r2rps_ups": fenced(fit_text(seed, 100))}
    for name in ROBOTS:
        check, _, _ = run(f"pkmtol check robots/{name} --no-progress", columns=1000)
        errors, _, _ = run(f"pkmtol errors robots/{name}", columns=1000)
        lines = check.rstrip("\n").splitlines()
        k = next(i for i, line in enumerate(lines) if line.startswith("mobility:"))
        head = errors.splitlines()[:3]
        made[f"robots-{name}"] = fenced(fit_text("\n".join([*lines[k:], "", *head]), 100))
    made["robots-delta-calibration"] = _delta_calibration()
    return made


def _delta_calibration() -> str:
    """The Delta's predicted calibration with the compensatable and with the full controller."""
    rows = {}
    for controller in ("compensatable", "full"):
        out, _, _ = run(f"pkmtol calibrate robots/delta --controller {controller} --no-figures", columns=1000)
        lines = out.splitlines()
        k = next(i for i, line in enumerate(lines) if line.startswith("predicted after calibration"))
        head = re.search(r"(\d+) held-out random poses", lines[k])
        header = re.split(r"\s{2,}", lines[k + 1].strip())
        row = next(_split(line) for line in lines[k + 3 :] if line.startswith("d-optimal"))
        poses = re.search(r"(\d+) d-optimal poses", out)
        rows[controller] = (dict(zip(header, row, strict=True)), head.group(1) if head else "?", poses)
    comp, held, poses = rows["compensatable"]
    full = rows["full"][0]
    n = poses.group(1) if poses else "?"
    return (
        "A rod's length alone is uncompensatable, but the *mean* length of an arm's two rods moves P as a\n"
        "compensatable error would: a controller that identifies only the compensatable parameters cannot\n"
        f"remove it (`pkmtol calibrate robots/delta --controller compensatable`, {n} D-optimal poses, the\n"
        f"linear prediction: {comp['beyond Δλ* [%]']} % of {held} held-out poses beyond Δλ* after "
        f"calibration, p99 {comp['p99 Δλ [µm]']} µm);\nidentifying every parameter (`controller = "
        f'"full"`, the robot\'s `[calibration]` table: rank {full["rank"]}) leaves '
        f"{full['beyond Δλ* [%]']} % (p99 {full['p99 Δλ [µm]']} µm).\n"
    )


# --- docs/hybrid.md: the module alone and the whole machine, side by side ---------------------------

WRIST = "robots/r2rps_ups_wrist"
HYBRID_RUNS = (
    ("module", SEED, ""),
    ("wmod", WRIST, "--compensate-with module"),
    ("wmod_tilt", WRIST, "--compensate-with module --orientation-target 0.1mrad"),
    ("wlock", WRIST, "--lock-wrist wrist_c=90deg,wrist_a=45deg"),
    ("wmach", WRIST, ""),
)
HYBRID_SHOWN = (
    "pkmtol allocate <the runs of docs/hybrid.md> --out R/<run>; python scripts/hybrid_comparison.py R"
)


def _gaussian_exact(out: str) -> list[str]:
    """The cells of the verification's Gaussian exact row: errors, model, samples, mean, std, failures."""
    return next(line.split() for line in out.splitlines() if line.split()[:2] == ["gaussian", "exact"])


def _hybrid(tmp: Path) -> dict[str, str]:
    printed = {}
    for name, robot, options in HYBRID_RUNS:
        command = f"pkmtol allocate {robot} {options} --no-figures --no-progress --out {tmp}/R/{name}"
        printed[name], _, _ = run(" ".join(command.split()), columns=1000)
    tables, _, _ = run(f"scripts/hybrid_comparison.py {tmp}/R")
    parts = tables.strip("\n").split("\n\n")
    machine, module = _gaussian_exact(printed["wmod"]), _gaussian_exact(printed["module"])
    return {
        "hybrid-module": "\n\n".join(parts[:2]) + "\n",
        "hybrid-verification": (
            "The verification of the whole machine's design (`R/wmod/allocation.md`, Gaussian errors at "
            f"the\nverified design's tolerances, {machine[2]} samples on exact kinematics): mean Δλ "
            f"{machine[3]} µm, {machine[5]} % beyond Δλ*;\nthe module alone {module[5]} % "
            "(`R/module/allocation.md`).\n"
        ),
        "hybrid-wrist": "\n\n".join(parts[2:]) + "\n",
    }
