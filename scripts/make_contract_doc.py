"""Write docs/contract.md: each design's claim against machines measured on exact kinematics.

For each robot and compensation mode it allocates the task-space design
(``DesignOptions(method="exact", criterion="every")``) and today's one-pose FOSM design, builds
``--machines`` machines at each design's tolerances and checks the claim at every grid pose
(:func:`pkmtol.design.contract.check_contract`). Last, the negative control of the test: the seed
robot's FOSM design with the urdf set under ``calibrated`` (issue 24's setting), and the Exechon
(over-constrained: its drawn machines cannot be assembled) on 20 machines. The hybrid
``r2rps_ups_wrist`` (the seed module with an A/C wrist and the tool) is checked at its TCP, and once
more with a joint claim of Δλ and the tool axis's Δα (``--compensate-with module
--orientation-target 0.1mrad``).

Usage:
    python scripts/make_contract_doc.py [--machines 200] [--seed 0] [--out docs/contract.md]
        [--robots r2rps_ups tricept delta r2rps_ups_wrist] [--workers 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from pkmtol import DesignOptions, allocate, load_mechanism
from pkmtol.design.contract import ContractCheck, PoseCheck, check_contract
from pkmtol.exceptions import PkmtolError
from pkmtol.executor import Executor
from pkmtol.files import write_atomic
from pkmtol.statistics import wilson_interval

ROOT = Path(__file__).resolve().parents[1]
LIGHT = {"samples": 2000, "verification_poses": 200, "exact_samples": 0, "claim_poses": 20}
ROBOTS = ("r2rps_ups", "tricept", "delta", "r2rps_ups_wrist")
#: The hybrid whose joint claim (TCP position and tool axis) is checked, and its Δα* [rad].
HYBRID = "r2rps_ups_wrist"
JOINT_TARGET_RAD = 1e-4
MODES = ("ideal", "calibrated")
#: Machines of the Exechon row (none of them can be assembled; more would only take longer).
UNASSEMBLABLE_MACHINES = 20
#: Poses listed per design when the claim does not hold everywhere.
LISTED = 5


def _pct(x: float) -> str:
    return "–" if not np.isfinite(x) else f"{100 * max(x, 0.0):.2f}"


def _row(robot: str, mode: str, label: str, check: ContractCheck, alloc_s: float) -> str:
    measured = np.array([p.measured for p in check.poses])
    predicted = np.array([p.predicted for p in check.poses])
    w = check.worst
    f, lo, hi = check.aggregate
    v = check.verdicts()
    verdict = "holds" if check.holds else "**fails**" if v["fails"] else "**cannot hold**"
    counts = ", ".join(f"{n} {k}" for k, n in v.items() if n)
    unconv = f" ({len(check.unconverged)} unconverged)" if check.unconverged else ""
    spread = " / ".join(_pct(x) for x in (measured.min(), float(np.median(measured)), measured.max()))
    cells = [
        f"{robot} (TCP)" if check.hybrid else robot,
        mode,
        label,
        str(len(check.poses)),
        f"{check.machines}{unconv}",
        _pct(1 - check.claimed_reliability),
        f"{_pct(predicted.max())} (pose {int(predicted.argmax())})",
        spread,
        f"{w.index}: {_pct(w.measured)} [{_pct(w.low)}, {_pct(w.high)}] (linear {_pct(w.predicted)})",
        f"{_pct(f)} [{_pct(lo)}, {_pct(hi)}]",
        f"{verdict}: {counts}",
        f"{alloc_s:.1f} + {check.wall_time_s:.1f}",
    ]
    return "| " + " | ".join(cells) + " |"


def _pose_text(p: PoseCheck) -> str:
    return f"pose {p.index}: {_pct(p.measured)} % [{_pct(p.low)}, {_pct(p.high)}]"


def _details(robot: str, mode: str, label: str, check: ContractCheck) -> list[str]:
    out = []
    failing = [p for p in check.poses if p.verdict == "fails"]
    if failing:
        worst = sorted(failing, key=lambda p: -p.measured)[:LISTED]
        listed = "; ".join(_pose_text(p) for p in worst)
        out.append(
            f"- {robot}, {mode}, {label}: the claim fails at {len(failing)} of {len(check.poses)} poses; "
            f"worst {listed}"
        )
    reasons: dict[str, list[int]] = {}
    for p in check.poses:
        if p.verdict == "cannot hold here":
            reasons.setdefault(p.reason, []).append(p.index)
    for reason, idx in reasons.items():
        where = "every pose" if len(idx) == len(check.poses) else "poses " + ", ".join(map(str, idx))
        out.append(f"- {robot}, {mode}, {label}: cannot hold at {where}: {reason}")
    invalid = [p for p in check.poses if not p.linear_valid]
    if invalid:
        gap = max(p.linear_gap_m for p in invalid)
        out.append(
            f"- {robot}, {mode}, {label}: linear model not valid at {len(invalid)} poses (largest gap of "
            f"the mean/p95/p99 of Δλ: {gap * 1e6:.1f} µm, beyond 5 % of Δλ* = "
            f"{0.05 * check.target_m * 1e6:.1f} µm); use the exact figures"
        )
    if check.unconverged:
        out.append(f"- {robot}, {mode}, {label}: {_unconverged(check)}")
    if check.hybrid:
        tilt = check.dalpha_rad[check.converged]
        judged = (
            f"judged jointly with Δλ against Δα* = {check.orientation_target_rad * 1e6:.0f} µrad"
            if check.orientation_target_rad is not None
            else "not claimed, so not judged"
        )
        out.append(
            f"- {robot}, {mode}, {label}: the tool axis's tilt Δα of the machines ({judged}): mean "
            f"{np.nanmean(tilt) * 1e6:.1f} µrad, largest {np.nanmax(tilt) * 1e6:.1f} µrad"
        )
    return out


def _unconverged(check: ContractCheck) -> str:
    """What the unconverged machines are, and what the check would say with them kept."""
    bad = ~check.converged
    failed = np.where(np.isfinite(check.dlambda_m), check.dlambda_m > check.target_m, True)
    claimed = np.array([p.claimed for p in check.poses])
    counts = failed.sum(axis=0)
    lows = np.array([wilson_interval(int(c), check.machines)[0] for c in counts])
    broken = np.flatnonzero(np.isfinite(claimed) & (claimed < lows))
    k, why = check.unconverged[0]
    text = (
        f"the identification of {int(bad.sum())} of {check.machines} machines did not converge "
        f"(left out of the figures, as in the study; first: machine {k}, {why}). Measured as their "
        f"controller was left, {int(failed[bad].any(axis=1).sum())} of them are beyond Δλ* somewhere "
        f"(largest Δλ {np.nanmax(check.dlambda_m[bad]) * 1e6:.0f} µm); kept in the sample, "
    )
    if not broken.size:
        return text + "the claim would still hold at every pose"
    j = int(broken[np.argmax(counts[broken])])
    lo, hi = wilson_interval(int(counts[j]), check.machines)
    return text + (
        f"{broken.size} poses would fail (worst: pose {j}, {_pct(counts[j] / check.machines)} % "
        f"[{_pct(lo)}, {_pct(hi)}])"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--machines", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "contract.md")
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS))
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    executor = Executor(workers=args.workers) if args.workers > 1 else None
    rows, details, refused = [], [], []
    runs: list[tuple[str, str, str, dict, dict]] = []
    every = {"method": "exact", "criterion": "every"}
    for robot in args.robots:
        for mode in MODES:
            runs.append((robot, mode, "exact, every", every, {}))
            runs.append((robot, mode, "fosm (one pose)", {"method": "fosm"}, {}))
    if "r2rps_ups" in args.robots:
        urdf = {"method": "fosm", "parameter_set": "urdf"}
        runs.append(("r2rps_ups", "calibrated", "fosm, urdf set", urdf, {}))
    if HYBRID in args.robots:  # the joint claim: TCP position and tool axis, the module compensating
        joint = {**every, "orientation_target_rad": JOINT_TARGET_RAD}
        label = f"exact, every, Δα* = {JOINT_TARGET_RAD * 1e3:g} mrad, module compensates"
        runs.append((HYBRID, "ideal", label, joint, {"tool_scope": "module"}))
    # an over-constrained machine whose drawn samples cannot be assembled: the check says so per pose
    runs.append(("exechon", "ideal", "exact, every", every, {}))
    t_all = time.perf_counter()
    for robot, mode, label, kw, extra in runs:
        mech = load_mechanism(ROOT / "robots" / robot)
        if extra:
            mech = dataclasses.replace(mech, extra={**mech.extra, **extra})
        t0 = time.perf_counter()
        try:
            design = allocate(mech, DesignOptions(compensation=mode, **kw, **LIGHT))
        except PkmtolError as err:
            refused.append(f"- {robot}, {mode}, {label}: `pkmtol allocate` refuses: {err}")
            print(f"{robot} {mode} {label}: refused ({err})", file=sys.stderr)
            continue
        alloc_s = time.perf_counter() - t0
        count = min(args.machines, UNASSEMBLABLE_MACHINES) if robot == "exechon" else args.machines
        check = check_contract(design, machines=count, seed=args.seed, executor=executor)
        rows.append(_row(robot, mode, label, check, alloc_s))
        details += _details(robot, mode, label, check)
        print(rows[-1], file=sys.stderr)
    total = time.perf_counter() - t_all
    command = "python scripts/make_contract_doc.py" + (
        f" --machines {args.machines}" if args.machines != 200 else ""
    )
    text = PAGE.format(
        command=command,
        machines=args.machines,
        total_min=total / 60,
        header=HEADER,
        rows="\n".join(rows),
        details="\n".join(details) or "- none: every claim holds at every pose, with a valid linear model",
        refused="\n".join(refused) or "- none",
    )
    write_atomic(args.out, text.encode())
    print(f"wrote {args.out} ({total:.0f} s)", file=sys.stderr)
    return 0


COLUMNS = (
    "robot",
    "mode",
    "design",
    "poses",
    "machines",
    "claim [%]",
    "linear max [%]",
    "measured min / median / max [%]",
    "worst pose: measured [95 %]",
    "task space [95 %]",
    "verdict",
    "time [s]",
)
HEADER = "| " + " | ".join(COLUMNS) + " |\n|" + "---|" * len(COLUMNS)

PAGE = """# The contract, checked on exact kinematics

Every reliability pkmtol prints says where it holds (DESIGN.md, "Claims and their scope"). This page
checks the claim against machines built at the printed tolerances and measured by exact forward
kinematics at every grid pose the design used. Made by `{command}` ({machines} machines per
design, the Exechon's 20; {total_min:.1f} min wall time, serial); `tests/test_contract.py`
asserts the same at 100 machines. The designs are allocated with `samples=2000,
verification_poses=200, exact_samples=0`: that shortens only the in-command verification; the
tolerances are those of the default sample counts (compared for the seed robot's `exact` designs in
both modes: identical).

## How a design is checked

`pkmtol.design.contract.check_contract(design, machines)` draws each machine's errors Gaussian: every
toleranced error at its tolerance (σ, as printed), every other non-absorbed error at its manufacturing
σ (the `[calibration]` table: 100 µm and 0.5 mrad by default), absorbed errors at 0. Each machine then
goes through the calibration study's own simulation (`pkmtol.calibration.study.simulate_machine`):

- `ideal`: the actuators take the Eq. 25 correction of the machine's true errors (the in-command
  verification of `ideal` holds the compensatable errors at 0; here they are drawn, so that the
  correction itself is checked);
- `calibrated`: the tracker measures the allocation's own plan (its poses, its noise), the
  project's identification fits the controller model on exact kinematics, and the controller
  commands every grid target by the identified model's exact inverse kinematics.

The hybrid `r2rps_ups_wrist` (the seed module, an A/C wrist and the tool: [hybrid.md](hybrid.md)) is
checked at its TCP: its grid is 525 poses (75 TCP points × 7 tool axes), its machines perturb the
limbs, the wrist and the tool, the identification and the controller are the whole machine's (the
identified model's exact IK of the TCP and the tool axis, all five actuators), and each machine is
measured by the exact forward kinematics of the module and the tool chain. Every machine's tilt Δα
of the tool axis is measured too; with an orientation target the claim is the joint reliability of
Δλ ≤ Δλ* and Δα ≤ Δα*, and a machine fails at a pose when either is beyond its target.

At one grid pose every machine is one Bernoulli trial (a failure), so the 95 % Wilson interval across
machines is the interval clustered by machine. The claim **holds** at a pose when the claimed failure
lies inside or above it. A pose where the claim cannot be met says why (**cannot hold here**): the
tracker noise alone fails more than the claim there (the noise floor), or machines that cannot be
assembled or commanded there (counted as failed) are what breaks it. The task-space share pools the
poses with a bootstrap over whole machines.

A machine whose identification does not converge is left out of the figures and named, as in the
calibration study (`pkmtol calibrate --simulate`). When more than 10 % of the machines do not
converge, no pose can hold its claim (the figures would describe only the machines that happened to
converge); the details below say what the check would find with them kept.

The per-pose tests (147 per module design, 525 per hybrid design) are each at 95 %: at a pose
where a claim is met exactly, 2.5 % of such checks fail by chance. The `every` designs are met
exactly at one pose only (their minimum); every other pose has margin. The FOSM design prints
R = Φ(β) without a place; the check reads it over the task space, as a designer reads its headline
(issue 24). The `exact, every` design claims R ≥ Φ(β) at every grid pose.

## The table

Failures in %; claim = 1 − Φ(2) = 2.28 %. "Worst pose" is the grid pose with the largest measured
failure, with its Wilson interval and the design's own linear-model failure there; "linear max" is
that model's largest failure over the grid (exact Gaussian reliability of its L/N maps, J under
`ideal`). Times: allocation + machine simulation [s].

{header}
{rows}

## Where the claim does not hold, and flags

{details}

## Designs `pkmtol allocate` refuses

{refused}

## What changed for the Delta's calibrated row

Its `[calibration]` controller `full` identifies every error, so nothing is toleranced and the
claim rests on the calibration alone. Its 40-pose full plan (53 base parameters) is
ill-conditioned (smallest singular value 8.5e-5 of the largest): Gauss–Newton on the frozen
nominal Jacobian stalled several σ from the least-squares optimum, or crept to the iteration
limit, on 86 of 200 machines, and the row read "cannot hold". Every stop is now certified on the
analytic Jacobian at the estimate (docs/calibration.md, "Identification on exact kinematics"),
and the row above is what that identification gives. `tests/test_identification_convergence.py`
checks one of these machines against an independent finite-difference Jacobian at the estimate.
"""


if __name__ == "__main__":
    sys.exit(main())
