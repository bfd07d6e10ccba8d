"""Benchmarks of pkmtol, printed as a table beside their targets and baselines (never run as timed tests).

Usage:
    python scripts/benchmark.py [robots/r2rps_ups] [--repeat-fast 15] [--repeat 3] [--skip-slow]

Each row gives the measured figure, its baseline measured in the same run and the target of
issue 15 (on the 2-core CI machine):

    inverse kinematics over the 147-point grid     ≥ 20,000 poses/s, ≥ 6× scipy least_squares
    IK + error model + separation + J             ≥ 10,000 poses/s
    the same on the Delta (loops inside limbs)    ≥ 50 % of the seed robot's rate per pose (issue 18)
    the same on the general path (one tree)       ≥ 70 % of the limb path's rate, ≥ 50 % on the Delta
    hybrid IK, r2rps_ups_wrist's TCP task grid     ≥ 50 % of the seed robot's IK rate per pose (issue 27)
    exact perturbed forward solves                 ≥ 15,000 /s
    import pkmtol (whole process)                  ≤ 0.3 s
    pkmtol allocate with figures (whole process)   ≤ 2.0 s CPU
    identification from 50 poses (issue 12)          ≤ 1 s
    calibration study 100 × 50 × 200 (issue 12)      ≤ 60 s on one core
    allocate --compensation calibrated (issue 13)    ≤ 2× the ideal mode (whole process CPU)
    10⁶ linear samples (allocate's sampling stages) ≤ 3 s and ≤ 350 MB peak RSS
    reading a measurement file of 10⁴/10⁵/10⁶ rows    10⁶ rows < 10 s, linear (issue 25)
    cost design on a 2,352-point grid              ≤ 3 s

With ``--baseline TREE`` (another version's source tree) the whole-process rows are measured for
that version too, run after run with this one. Baselines: the per-pose solver ``ClosedChain``
(what the hot loops used before) and scipy's
``least_squares`` (Levenberg–Marquardt, exact Jacobian, the same warm starts, tolerances tight
enough to reach the same solution to 1e-12) for the kinematics; a fresh perturbed ``ClosedChain``
per sample for the forward solves; ``python -c pass`` and the eager import of every stage for the
start-up; the per-pose ``gammainc`` quadrature for the reliabilities. The machine is a shared VM
whose speed drifts by tens of per cent: the in-process rows are interleaved run after run and the
best run is kept; whole-process rows are the best of ``--repeat`` runs. Ratios to the baseline are
the robust figures. The kinematics rows run on the compiled kernels when numba is installed (the
``fast`` extra; ``PKMTOL_JIT=0`` turns them off) and print the numpy path of the default install
beside them; the start-up rows (import, allocate, 10⁶ samples) run without them, as the README
installs pkmtol, and the allocate row also gives the figure with them. Under the table, a line
compares this run's scipy and per-pose baselines with issue 15's measurements of them
(:data:`ISSUE_RATES`) and prints the absolute targets scaled by the larger factor: what the
targets ask of a machine as fast as this one is today (docs/scale.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

# one BLAS thread in this process: the matrices are 6×6 to 21×21; threads only add synchronisation
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy import special  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from pkmtol.calibration.holdout import holdout_poses  # noqa: E402
from pkmtol.calibration.identification import identify, model_positions  # noqa: E402
from pkmtol.calibration.machine import Machine  # noqa: E402
from pkmtol.calibration.plan import candidate_pool, make_plan  # noqa: E402
from pkmtol.calibration.settings import CalibrationSettings  # noqa: E402
from pkmtol.calibration.study import StudyCase, run_study, study_context  # noqa: E402
from pkmtol.calibration.workflow import design_sigma  # noqa: E402
from pkmtol.design.job import DesignOptions, allocate  # noqa: E402
from pkmtol.design.methods import method_design_for  # noqa: E402
from pkmtol.design.reliability import _NODES, exact_reliability_many  # noqa: E402
from pkmtol.design.verification import sample_errors  # noqa: E402
from pkmtol.error_model.parameters import default_set, parameter_set  # noqa: E402
from pkmtol.error_model.sweep import sweep  # noqa: E402
from pkmtol.error_model.tool_chain import hybrid_parameter_set  # noqa: E402
from pkmtol.error_model.tool_sweep import hybrid_sweep  # noqa: E402
from pkmtol.error_model.tree_parameters import from_limb_set  # noqa: E402
from pkmtol.error_model.tree_separation import tree_sweep  # noqa: E402
from pkmtol.executor import Executor  # noqa: E402
from pkmtol.kinematics import acceleration  # noqa: E402
from pkmtol.kinematics.batch import BatchChain  # noqa: E402
from pkmtol.kinematics.closed_chain import ClosedChain  # noqa: E402
from pkmtol.kinematics.continuation import continuation  # noqa: E402
from pkmtol.kinematics.hybrid import HybridChain, HybridPose, task_grid  # noqa: E402
from pkmtol.kinematics.hybrid_continuation import hybrid_continuation  # noqa: E402
from pkmtol.kinematics.perturbation import perturbed_limb_models  # noqa: E402
from pkmtol.kinematics.tree_chain import TreeBatch  # noqa: E402
from pkmtol.model.loader import load_mechanism  # noqa: E402
from pkmtol.model.tree_from_limbs import tree_from_mechanism  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def sequential_ik(chain: ClosedChain, grid: np.ndarray) -> tuple[list, np.ndarray]:
    """The per-pose solver along the grid (tangent step from the previous point); poses and guesses."""
    guesses = [chain.home()]
    pose = chain.inverse(grid[0], guesses[0])
    poses = [pose]
    for p in grid[1:]:
        guesses.append(chain.predict(pose, p))
        pose = chain.inverse(p, guesses[-1])
        poses.append(pose)
    return poses, np.array(guesses)


def scipy_ik(chain: ClosedChain, grid: np.ndarray, guesses: np.ndarray) -> np.ndarray:
    """scipy least_squares (lm, exact Jacobian) on the same equations and warm starts."""
    out = []
    for p, g in zip(grid, guesses, strict=True):
        r = least_squares(
            lambda q, p=p: chain._evaluate(q, p)[0].copy(),
            g,
            jac=lambda q, p=p: chain._evaluate(q, p)[1].copy(),
            method="lm",
            xtol=1e-15,
            ftol=1e-15,
            gtol=1e-15,
        )
        out.append(r.x)
    return np.array(out)


def process(cmd: list[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[float, float, float, str]:
    """Run ``cmd``: (wall s, CPU s of the child, peak RSS MB of all children so far, stdout)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=True, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, after.ru_maxrss / 1024.0, proc.stdout


def numpy_path(fn: Callable[[], object]) -> Callable[[], object]:
    """``fn`` run without the compiled kernels: the batched solver's numpy path (the default install)."""

    def run() -> object:
        original = acceleration.kernels
        acceleration.kernels = lambda: None
        try:
            return fn()
        finally:
            acceleration.kernels = original

    return run


#: Issue 15's baselines as it measured them on main (2 cores, best of N): scipy least_squares and the
#: per-pose solver over the 147-point grid [poses/s]. The yardstick of the machine-speed line.
ISSUE_RATES = {"scipy": 3_000.0, "per_pose": 5_900.0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("robot", nargs="?", default="robots/r2rps_ups", type=Path)
    ap.add_argument("--repeat", type=int, default=3, help="runs of the whole-process and slow rows")
    ap.add_argument("--repeat-fast", type=int, default=15, help="interleaved runs of the in-process rows")
    ap.add_argument("--skip-slow", action="store_true", help="leave out the 10⁶-sample and cost rows")
    ap.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="TREE",
        help="a source tree of another pkmtol version (e.g. `git archive <commit> | tar -x -C TREE`): "
        "the whole-process rows run it too, interleaved, and print the ratio",
    )
    ap.add_argument(
        "--measurement-files-only", action="store_true", help="only the rows of reading measurement files"
    )
    args = ap.parse_args()
    mech = load_mechanism(args.robot)
    if args.measurement_files_only:
        for row in measurement_file_rows(mech):
            print("  ".join(row))
        return
    grid = mech.task_space.grid()
    chain = ClosedChain(mech)
    batch = BatchChain(mech, chain=chain)
    pset = parameter_set(mech, default_set(mech))
    home = chain.home()
    poses, guesses = sequential_ik(chain, grid)
    reference = np.array([p.q_all for p in poses])

    # the exact verification's samples: design tolerances, Gaussian errors, random poses
    res = allocate(mech, DesignOptions(samples=2000, exact_samples=0, verification_poses=200))
    unc = res.uncompensatable
    design = res.tolerances[unc, res.design_column]
    sig = np.where(np.isfinite(design), design, 0.0)
    rnd_points = mech.task_space.sample(np.random.default_rng(0), 200)
    rnd = sweep(mech, pset, rnd_points, chain, guesses=np.tile(poses[0].q_all, (200, 1)))
    n_fwd = 1000
    idx = np.arange(n_fwd) % len(rnd.poses)
    eta = np.zeros((n_fwd, len(pset)))
    eta[:, unc] = sample_errors("gaussian", sig, n_fwd, np.random.default_rng(1))
    q0 = np.array([rnd.poses[k].q_all for k in idx])
    correction = np.array([rnd.separations[k].correction for k in idx])
    u = q0[:, chain.actuated_idx] + np.einsum("sfn,sn->sf", correction, eta)
    eps, offsets = pset.perturbations(eta, mech)
    fwd_batch = BatchChain(mech, check_limits=False)

    def forward_per_pose(count: int) -> None:
        for s in range(count):
            e, o = pset.perturbation(eta[s], mech)
            ClosedChain(mech, perturbed_limb_models(mech, e), check_limits=False).forward(u[s], q0[s], o)

    # one reliability pass over a grid: the per-pose gammainc quadrature vs the stacked closed form
    J = res.grid.J[:, :, unc] * sig
    cov = J @ np.swapaxes(J, 1, 2)
    nodes_u, nodes_w = _NODES

    def gammainc_pass() -> None:
        for c in cov:
            lam = np.clip(np.linalg.eigh(c)[0], 0.0, None)
            y = res.target_m / np.sqrt(np.maximum((nodes_u**2) @ lam, lam.max() * 1e-300))
            float(nodes_w @ special.gammainc(1.5, 0.5 * y * y))

    # issue 18: the Delta (limbs with internal loops) against this robot, in the same interleaved runs
    delta = load_mechanism(ROOT / "robots" / "delta")
    delta_chain = ClosedChain(delta)
    delta_pset = parameter_set(delta, default_set(delta))
    delta_grid = delta.task_space.grid()

    # issue 26: the general formulation (one tree with loop constraints) against the limb path, on the
    # same mechanism and parameters (tree_from_mechanism: the same maps to 1e-10)
    tree, tree_raw = tree_from_mechanism(mech)
    tree_params = from_limb_set(tree_raw, pset)
    tree_batch = TreeBatch(tree)
    delta_tree, delta_raw = tree_from_mechanism(delta)
    delta_tree_params = from_limb_set(delta_raw, delta_pset)
    delta_tree_batch = TreeBatch(delta_tree)
    # issue 27: the whole machine (module + A/C wrist) on its TCP task grid, decoupled and general
    hybrid = load_mechanism(ROOT / "robots" / "r2rps_ups_wrist")
    hybrid_chain = HybridChain(hybrid)
    hybrid_general = HybridChain(hybrid)
    hybrid_general.wrist_offset_m = None  # the nested Newton every tool chain can take
    hybrid_tcp, hybrid_axes = task_grid(hybrid)
    hybrid_home = hybrid_chain.home()
    hybrid_pset = hybrid_parameter_set(hybrid, "urdf")

    n_per_pose = 40  # the per-pose baselines are slow: a subset, scaled
    fast = {
        "ik": lambda: continuation(batch, grid, home),
        "ik_numpy": numpy_path(lambda: continuation(batch, grid, home)),
        "ik_guesses": lambda: batch.inverse(grid, guesses),
        "ik_per_pose": lambda: sequential_ik(chain, grid),
        "ik_scipy": lambda: scipy_ik(chain, grid[:n_per_pose], guesses[:n_per_pose]),
        "sweep": lambda: sweep(mech, pset, grid, chain),
        "sweep_numpy": numpy_path(lambda: sweep(mech, pset, grid, chain)),
        "delta_sweep": lambda: sweep(delta, delta_pset, delta_grid, delta_chain),
        "tree_sweep": lambda: tree_sweep(tree, tree_params, grid, tree_batch),
        "delta_tree_sweep": lambda: tree_sweep(delta_tree, delta_tree_params, delta_grid, delta_tree_batch),
        "forward": lambda: fwd_batch.forward(u, q0, offsets, eps),
        "forward_numpy": numpy_path(lambda: fwd_batch.forward(u, q0, offsets, eps)),
        "forward_per_pose": lambda: forward_per_pose(n_per_pose),
        "hybrid_ik": lambda: hybrid_continuation(hybrid_chain, hybrid_tcp, hybrid_axes, hybrid_home),
        "hybrid_ik_general": lambda: hybrid_continuation(
            hybrid_general, hybrid_tcp, hybrid_axes, hybrid_home
        ),
        "hybrid_sweep": lambda: hybrid_sweep(hybrid, hybrid_pset, hybrid_tcp, hybrid_axes, hybrid_chain),
        "reliability": lambda: exact_reliability_many(cov, res.target_m),
        "reliability_gammainc": gammainc_pass,
    }
    best = dict.fromkeys(fast, float("inf"))
    for _ in range(args.repeat_fast):
        for key, fn in fast.items():
            t0 = time.perf_counter()
            fn()
            best[key] = min(best[key], time.perf_counter() - t0)
    # the fast paths solve the same problems to 1e-12
    assert np.abs(continuation(batch, grid, home).q - reference).max() < 1e-12
    # the general path solves the same problems: the same maps to 1e-10
    assert np.abs(fast["tree_sweep"]().J - fast["sweep"]().J).max() < 1e-10
    assert np.abs(fast["delta_tree_sweep"]().J - fast["delta_sweep"]().J).max() < 1e-10
    assert np.abs(numpy_path(lambda: continuation(batch, grid, home))().q - reference).max() < 1e-12
    assert np.abs(scipy_ik(chain, grid[:5], guesses[:5]) - reference[:5]).max() < 1e-12
    hybrid_check = hybrid_continuation(hybrid_chain, hybrid_tcp, hybrid_axes)
    for sol, t, a in zip(hybrid_check, hybrid_tcp, hybrid_axes, strict=True):
        assert (
            isinstance(sol, HybridPose)
            and max(np.abs(sol.tcp_m - t).max(), np.abs(sol.axis - a).max()) < 1e-11
        )
    m = len(grid)
    path = " — compiled kernels" if acceleration.kernels() is not None else " — numpy (no numba)"
    rate = {
        "ik": m / best["ik"],
        "ik_numpy": m / best["ik_numpy"],
        "sweep_numpy": m / best["sweep_numpy"],
        "forward_numpy": n_fwd / best["forward_numpy"],
        "ik_guesses": m / best["ik_guesses"],
        "ik_per_pose": m / best["ik_per_pose"],
        "ik_scipy": n_per_pose / best["ik_scipy"],
        "sweep": m / best["sweep"],
        "delta_sweep": len(delta_grid) / best["delta_sweep"],
        "tree_sweep": m / best["tree_sweep"],
        "delta_tree_sweep": len(delta_grid) / best["delta_tree_sweep"],
        "forward": n_fwd / best["forward"],
        "forward_per_pose": n_per_pose / best["forward_per_pose"],
        "hybrid_ik": len(hybrid_tcp) / best["hybrid_ik"],
        "hybrid_ik_general": len(hybrid_tcp) / best["hybrid_ik_general"],
        "hybrid_sweep": len(hybrid_tcp) / best["hybrid_sweep"],
    }
    rows = [
        (
            f"inverse kinematics, grid (continuation){path}",
            f"{m} poses",
            f"{rate['ik']:,.0f} poses/s",
            f"per-pose {rate['ik_per_pose']:,.0f}/s; scipy {rate['ik_scipy']:,.0f}/s"
            f" = {rate['ik'] / rate['ik_scipy']:.1f}×",
            "≥ 20,000/s, ≥ 6× scipy",
        ),
        (
            "  the same, numpy path (default install)",
            f"{m} poses",
            f"{rate['ik_numpy']:,.0f} poses/s",
            f"{rate['ik_numpy'] / rate['ik_scipy']:.1f}× scipy",
            "",
        ),
        (
            "  the same with the per-pose solver's guesses",
            f"{m} poses",
            f"{rate['ik_guesses']:,.0f} poses/s",
            f"{rate['ik_guesses'] / rate['ik_scipy']:.1f}× scipy",
            "",
        ),
        (
            "IK + error model + separation + J",
            f"{m} poses",
            f"{rate['sweep']:,.0f} poses/s",
            f"{rate['sweep'] / rate['ik_per_pose']:.1f}× per-pose IK alone; numpy path"
            f" {rate['sweep_numpy']:,.0f}/s",
            "≥ 10,000/s",
        ),
        (
            "Delta: IK + error model + separation + J",
            f"{len(delta_grid)} poses",
            f"{rate['delta_sweep']:,.0f} poses/s",
            f"{mech.name} above {rate['sweep']:,.0f}/s: {rate['delta_sweep'] / rate['sweep']:.0%} of it",
            "≥ 50 % of the seed's",
        ),
        (
            "general path (one tree + loops): IK + error model + separation + J",
            f"{m} poses",
            f"{rate['tree_sweep']:,.0f} poses/s",
            f"limb path {rate['sweep']:,.0f}/s: {rate['tree_sweep'] / rate['sweep']:.0%} of it",
            "≥ 70 % of the limb path's",
        ),
        (
            "Delta, general path: IK + error model + separation + J",
            f"{len(delta_grid)} poses",
            f"{rate['delta_tree_sweep']:,.0f} poses/s",
            f"limb path {rate['delta_sweep']:,.0f}/s: "
            f"{rate['delta_tree_sweep'] / rate['delta_sweep']:.0%} of it",
            "≥ 50 % of the limb path's",
        ),
        (
            "hybrid IK: r2rps_ups_wrist, TCP points × tool axes (decoupled)",
            f"{len(hybrid_tcp)} poses",
            f"{rate['hybrid_ik']:,.0f} poses/s",
            f"{mech.name} IK above {rate['ik']:,.0f}/s: {rate['hybrid_ik'] / rate['ik']:.0%} of it",
            "≥ 50 % of the seed's",
        ),
        (
            "  the same, general nested Newton (any tool chain)",
            f"{len(hybrid_tcp)} poses",
            f"{rate['hybrid_ik_general']:,.0f} poses/s",
            f"{rate['hybrid_ik_general'] / rate['ik']:.0%} of the seed's IK",
            "",
        ),
        (
            "hybrid IK + whole-machine error model at the TCP",
            f"{len(hybrid_tcp)} poses",
            f"{rate['hybrid_sweep']:,.0f} poses/s",
            f"{rate['hybrid_sweep'] / rate['sweep']:.0%} of the seed's IK + error model",
            "",
        ),
        (
            "exact perturbed forward solves",
            f"{n_fwd} samples",
            f"{rate['forward']:,.0f} /s",
            f"fresh chain per sample {rate['forward_per_pose']:,.0f}/s"
            f" = {rate['forward'] / rate['forward_per_pose']:.1f}×;"
            f" numpy path {rate['forward_numpy']:,.0f}/s",
            "≥ 15,000/s",
        ),
        (
            "exact reliability, one pass over the grid",
            f"{m} poses",
            f"{1e6 * best['reliability'] / m:.1f} µs/pose",
            f"gammainc per pose {1e6 * best['reliability_gammainc'] / m:.1f} µs = "
            f"{best['reliability_gammainc'] / best['reliability']:.1f}×",
            "",
        ),
    ]

    py = sys.executable
    code_10e6 = (
        "import resource, sys; from pkmtol.cli import main; main(sys.argv[1:]); "
        "print('maxrss', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    stages = ("sensitive-pose search", "claimed vs true reliability", "verification")

    def whole(src: Path | None, tmp: str) -> dict[str, float]:
        """One run of every whole-process row with the pkmtol at ``src`` (None: this one)."""
        env = dict(os.environ)
        if src is not None:
            env["PYTHONPATH"] = str(src / "src")
        cli = [py, "-m", "pkmtol.cli"]
        # the README's install has no numba: the start-up rows run without the kernels, and
        # allocate runs once more with them (the fast extra: numba's import and the kernels' load)
        lean = {**env, acceleration.ENVIRONMENT: "0"}
        allocate_cmd = [*cli, "allocate", str(args.robot), "--out", tmp, "--no-progress"]
        out = {
            "import": process([py, "-c", "import pkmtol"], ROOT, lean)[0],
            "allocate_cpu": process(allocate_cmd, ROOT, lean)[1],
            "allocate_cpu_fast": process(allocate_cmd, ROOT, env)[1],
        }
        if not args.skip_slow:
            cmd = [
                "allocate",
                str(args.robot),
                "--samples",
                "1000000",
                "--exact-samples",
                "0",
                "--no-figures",
            ]
            wall, _, _, text = process([py, "-c", code_10e6, *cmd, "--out", tmp, "--no-progress"], ROOT, lean)
            line = next(ln for ln in text.splitlines() if ln.startswith("stage times: "))
            times = {
                part.rsplit(" ", 2)[0]: float(part.rsplit(" ", 2)[1])
                for part in line.removeprefix("stage times: ").split(", ")
            }
            out["samples_s"] = sum(times[s] for s in stages)
            out["samples_rss"] = float(text.split("maxrss")[-1]) / 1024.0
            out["samples_wall"] = wall
        return out

    runs: dict[str, list[dict[str, float]]] = {"new": [], "base": []}
    floor = {"bare": float("inf"), "imports": float("inf")}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):  # interleaved: this version, then the baseline version
            runs["new"].append(whole(None, tmp))
            if args.baseline is not None:
                runs["base"].append(whole(args.baseline, tmp))
            floor["bare"] = min(floor["bare"], process([py, "-c", "pass"], ROOT)[0])
            imports = "import numpy, pinocchio, scipy.special, matplotlib.figure"
            floor["imports"] = min(floor["imports"], process([py, "-c", imports], ROOT)[1])

    def best_of(version: str, key: str) -> float:
        return min(r[key] for r in runs[version]) if runs[version] else float("nan")

    def vs(key: str, fmt: str) -> str:
        if not runs["base"]:
            return ""
        b, n = best_of("base", key), best_of("new", key)
        return f"baseline {fmt.format(b)} = {b / n:.1f}×"

    rows.append(
        (
            "import pkmtol (whole process)",
            "",
            f"{best_of('new', 'import'):.3f} s",
            f"python -c pass {floor['bare']:.3f} s; " + vs("import", "{:.3f} s"),
            "≤ 0.3 s",
        )
    )
    rows.append(
        (
            "pkmtol allocate with figures (CPU)",
            "",
            f"{best_of('new', 'allocate_cpu'):.2f} s CPU",
            f"imports alone {floor['imports']:.2f} s;"
            f" fast extra {best_of('new', 'allocate_cpu_fast'):.2f} s; " + vs("allocate_cpu", "{:.2f} s"),
            "≤ 2.0 s CPU",
        )
    )
    if not args.skip_slow:
        rows.append(
            (
                "10⁶ linear samples: search + claims + verification",
                "10⁶ samples",
                f"{best_of('new', 'samples_s'):.2f} s, {best_of('new', 'samples_rss'):.0f} MB",
                vs("samples_s", "{:.1f} s")
                + (f", {best_of('base', 'samples_rss'):.0f} MB" if runs["base"] else ""),
                "≤ 3 s, ≤ 350 MB",
            )
        )
    if not args.skip_slow:
        ts = dataclasses.replace(mech.task_space, layers=48)
        big = dataclasses.replace(mech, task_space=ts)
        bres = allocate(big, DesignOptions(samples=1000, exact_samples=0, verification_poses=100))
        t_cost = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            method_design_for(
                big,
                bres.pset,
                bres.grid,
                bres.uncompensatable,
                bres.tolerances[bres.uncompensatable, bres.design_column],
                bres.target_m,
                bres.design_beta,
                bres.worst_index,
                DesignOptions(method="cost"),
            )
            t_cost.append(time.perf_counter() - t0)
        rows.append(
            (
                "cost design (incl. reference)",
                f"{len(bres.grid.points_m)} poses",
                f"{min(t_cost):.2f} s",
                f"one gammainc pass {best['reliability_gammainc'] / m * len(bres.grid.points_m):.2f} s",
                "≤ 3 s",
            )
        )

    rows += calibration_rows(mech, pset, chain, args, py)
    rows += instrument_rows(mech, pset, chain, args)
    rows += measurement_file_rows(mech)

    w = max(len(r[0]) for r in rows)
    print(
        f"pkmtol benchmark — {mech.name}, best of {args.repeat_fast} interleaved (in-process) / "
        f"{args.repeat} (whole process) runs, numpy {np.__version__}, {os.cpu_count()} cores"
    )
    print(f"{'row'.ljust(w)}  {'size':>11}  {'measured':>18}  {'baseline (same run)':<55}  target")
    print("-" * (w + 110))
    for name, size, value, base, target in rows:
        print(f"{name.ljust(w)}  {size:>11}  {value:>18}  {base:<55}  {target}")
    # issue 15 set its absolute targets on a 2-core VM on another day; its two baselines do the same
    # work here (scipy's solver unchanged, the per-pose solver the same Newton loop), so their rates
    # tell how fast this machine is against that one. The larger factor is the stricter reading.
    factors = {key: rate[f"ik_{key}"] / ISSUE_RATES[key] for key in ISSUE_RATES}
    speed = max(factors.values())
    print(
        f"\nMachine speed against issue 15's: scipy {rate['ik_scipy']:,.0f}/s here against "
        f"{ISSUE_RATES['scipy']:,.0f}/s there = {factors['scipy']:.2f}×, the per-pose solver "
        f"{rate['ik_per_pose']:,.0f}/s against {ISSUE_RATES['per_pose']:,.0f}/s = "
        f"{factors['per_pose']:.2f}×. The targets at the larger factor, {speed:.2f}×: "
        f"IK ≥ {20_000 * speed:,.0f}/s, IK + error model ≥ {10_000 * speed:,.0f}/s, "
        f"forward solves ≥ {15_000 * speed:,.0f}/s, allocate ≤ {2.0 / speed:.1f} s CPU, "
        f"10⁶ samples ≤ {3.0 / speed:.1f} s, cost design ≤ {3.0 / speed:.1f} s."
    )


def calibration_rows(mech, pset, chain, args, py):  # noqa: ANN001, ANN201 - script helper
    """Issues 12 and 13: identification, the exact study, and allocate --compensation calibrated."""
    grid = sweep(mech, pset, mech.task_space.grid(), chain)
    classes = grid.classify()
    settings = CalibrationSettings(poses=50)
    plan = make_plan(mech, pset, classes, settings, candidate_pool(mech, pset, settings, chain, grid=grid))
    rng = np.random.default_rng(0)
    comp = [i for i, c in enumerate(classes) if c == "compensatable"]
    delta = np.zeros(len(pset))
    delta[comp] = rng.standard_normal(len(comp)) * settings.manufacturing_sigma(pset)[comp]
    true = Machine(mech, pset, delta)
    measured, _ = model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
    measured = measured + rng.standard_normal(measured.shape) * settings.noise_m

    def per_pose_pass() -> None:  # what one Gauss–Newton pass cost before the batched solver
        for u, q in zip(plan.maps.commands, plan.maps.q, strict=True):
            true.forward(u, q)

    t_id, t_pass, t_batch, iters = [], [], [], 0
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        ident = identify(
            mech, pset, plan.ident, plan.H, plan.maps.commands, plan.maps.q, measured, plan.targets_m
        )
        t_id.append(time.perf_counter() - t0)
        iters = ident.iterations
        t0 = time.perf_counter()
        per_pose_pass()
        t_pass.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        model_positions(true, plan.maps.commands, plan.maps.q, plan.targets_m)
        t_batch.append(time.perf_counter() - t0)
    rows = [
        (
            "identification on exact kinematics",
            "50 poses",
            f"{min(t_id):.3f} s ({iters} GN iter.)",
            f"one forward pass per pose {min(t_pass) * 1e3:.1f} ms, batched {min(t_batch) * 1e3:.1f} ms"
            f" = {min(t_pass) / min(t_batch):.1f}×",
            "≤ 1 s",
        )
    ]
    if not args.skip_slow:
        sigma = design_sigma(pset, classes, settings, None)
        unc = [i for i, c in enumerate(classes) if c == "uncompensatable"]
        sigma[unc] = 2e-5
        ho = holdout_poses(mech, pset, 200, np.random.default_rng(1), chain)
        case = [(StudyCase("compensatable", "d-optimal", 50), plan)]
        ctx = study_context(mech, pset, sigma, ho.maps, ho.correction, ho.ideal, case, mech.target_m)
        t0 = time.perf_counter()
        run_study(ctx, 100, seed=0)
        serial = time.perf_counter() - t0
        t0 = time.perf_counter()
        run_study(ctx, 100, seed=0, chunk=10, executor=Executor(workers=2))
        two = time.perf_counter() - t0
        rows.append(
            (
                "calibration study, exact (one case)",
                "100×50×200",
                f"{serial:.1f} s serial",
                f"2 local workers {two:.1f} s = {serial / two:.2f}× (same numbers)",
                "≤ 60 s on one core",
            )
        )
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [py, "-m", "pkmtol.cli", "allocate", str(args.robot), "--no-figures", "--no-progress"]
        ideal, cal = [], []
        for k in range(args.repeat):  # interleaved
            ideal.append(process([*cmd, "--out", f"{tmp}/i{k}"], ROOT)[1])
            cal.append(process([*cmd, "--compensation", "calibrated", "--out", f"{tmp}/c{k}"], ROOT)[1])
    rows.append(
        (
            "allocate --compensation calibrated (CPU)",
            "",
            f"{min(cal):.2f} s CPU",
            f"ideal {min(ideal):.2f} s CPU = {min(cal) / min(ideal):.2f}× ideal",
            "≤ 2× ideal",
        )
    )
    return rows


def instrument_rows(mech, pset, chain, args):  # noqa: ANN001, ANN201 - script helper
    """Issue 28: a 50-pose identification of every instrument, and each one's default study (CPU)."""
    from pkmtol.calibration.identification import identify_with, machine_poses
    from pkmtol.calibration.workflow import simulate

    grid = sweep(mech, pset, mech.task_space.grid(), chain)
    classes = grid.classify()
    cases = {
        "tracker": {},
        "tracker, frame identified": {"tracker_frame": "identify"},
        "tracker-multi": {"instrument": "tracker-multi"},
        "tracker-6d": {"instrument": "tracker-6d"},
        "ballbar (5 circles × 10)": {"instrument": "ballbar", "poses": 5, "circle_points": 10},
        "probe": {"instrument": "probe"},
        "probe, plane artifact": {"instrument": "probe", "artifact": "plane"},
    }
    rows = []
    for label, kw in cases.items():
        settings = CalibrationSettings(**{"poses": 50, **kw})
        plan = make_plan(
            mech, pset, classes, settings, candidate_pool(mech, pset, settings, chain, grid=grid)
        )
        inst = plan.instrument
        rng = np.random.default_rng(0)
        comp = [i for i, c in enumerate(classes) if c == "compensatable"]
        delta = np.zeros(len(pset))
        delta[comp] = rng.standard_normal(len(comp)) * settings.manufacturing_sigma(pset)[comp]
        o, R, _ = machine_poses(Machine(mech, pset, delta), plan.maps.commands, plan.maps.q)
        pi = inst.draw_nuisance(rng)
        y = inst.perturb(
            inst.measure(o, R, plan.stations, pi),
            rng.standard_normal((len(o), inst.values_per_pose)) * inst.noise,
        )
        times, iters = [], 0
        for _ in range(args.repeat):
            t0 = time.process_time()
            ident = identify_with(mech, pset, plan.ident, plan.maps, inst, y)
            times.append(time.process_time() - t0)
            iters = ident.iterations
        rows.append(
            (
                f"identification, {label}",
                f"{plan.poses} poses",
                f"{min(times):.3f} s CPU ({iters} GN iter.)",
                f"{plan.H.shape[0]} values, {inst.nuisance_count} nuisance",
                "≤ 1 s",
            )
        )
    if not args.skip_slow:
        for label, kw in cases.items():
            if "circles" in label:
                kw, label = {"instrument": "ballbar"}, "ballbar"
            settings = CalibrationSettings(**kw)
            sigma = design_sigma(pset, classes, settings, None)
            unc = [i for i, c in enumerate(classes) if c == "uncompensatable"]
            sigma[unc] = 2e-5
            t0 = time.process_time()
            rep = simulate(mech, pset, classes, settings, sigma, mech.target_m)
            cpu = time.process_time() - t0
            left = sum(len(c.unconverged) for c in rep.study.cases)
            rows.append(
                (
                    f"default study, {label}",
                    "100×4 cases×200",
                    f"{cpu:.1f} s CPU",
                    f"exact simulation {rep.timings_s['exact simulation']:.1f} s wall; "
                    f"{left} machine-cases left out",
                    "≤ 60 s on one core",
                )
            )
    return rows


def measurement_file_rows(mech):  # noqa: ANN001, ANN201 - script helper
    """Issue 25: reading (and grouping into poses) a tracker file of 10⁴, 10⁵ and 10⁶ rows (wall and CPU).

    Every pose has one target, so every row is a new pose: the worst case of the grouping. The
    commands are random values inside a 1 m span, written as the tracker's CSV.
    """
    from pkmtol.calibration.measurement_files import measurements_csv, read_measurements

    f = sum(len(limb.actuated) for limb in mech.limbs)
    rows, times = [], {}
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        for n in (10_000, 100_000, 1_000_000):
            commands = rng.uniform(0.5, 1.5, size=(n, f))
            points = rng.uniform(-0.5, 0.5, size=(n, 1, 3))
            path = Path(tmp) / f"m{n}.csv"
            path.write_text(measurements_csv(mech, commands, points))
            t0, c0 = time.perf_counter(), time.process_time()
            m = read_measurements(path, mech, 1)
            times[n] = time.perf_counter() - t0
            cpu = time.process_time() - c0
            assert m.commands.shape == (n, f)
            per_row = 1e6 * times[n] / n
            rows.append(
                (
                    "reading a measurement file",
                    f"{n:,} rows",
                    f"{times[n]:.2f} s",
                    f"{cpu:.2f} s CPU; {per_row:.2f} µs/row; ×{times[n] / times[10_000]:.0f} of 10⁴ rows",
                    "10⁶ rows < 10 s, linear",
                )
            )
    return rows


if __name__ == "__main__":
    main()
