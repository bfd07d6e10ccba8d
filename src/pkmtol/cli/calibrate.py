"""``pkmtol calibrate``: plan a calibration, simulate it on exact kinematics, or identify from data."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pkmtol.calibration.fit_check import FitVerdict, PoorFitError, data_verdict, fit_verdict
from pkmtol.calibration.hybrid_export import calibrated_files
from pkmtol.calibration.hybrid_poses import check_instrument, with_tracker_on
from pkmtol.calibration.instrument_data import calibrate_instrument_data
from pkmtol.calibration.instrument_files import instrument_plan_csv, read_instrument_measurements
from pkmtol.calibration.instruments import instrument_for
from pkmtol.calibration.maps import PoseMaps
from pkmtol.calibration.measurement_files import plan_csv, read_measurements
from pkmtol.calibration.real_data import calibrate_measurements
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.calibration.study_limits import check_calibration_request
from pkmtol.calibration.tolerance_file import read_tolerances
from pkmtol.calibration.urdf_export import write_calibrated_folder
from pkmtol.calibration.workflow import design_sigma, plan_report, simulate
from pkmtol.cli.calibration_options import add_plan_options, plan_settings
from pkmtol.cli.common import add_executor_options, add_tool_options, apply_tool_options, executor_from
from pkmtol.cli.robot_cache import RobotGrid, robot_grid
from pkmtol.cli.robot_cache import mechanism as cached_mechanism
from pkmtol.design.budget import available_memory
from pkmtol.design.job import DesignOptions, allocate
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.task import machine_parameter_set
from pkmtol.error_model.tool_sweep import TRACKER_POINTS
from pkmtol.exceptions import (
    FiguresError,
    InvalidArgumentError,
    InvalidRequestError,
    OutputError,
)
from pkmtol.executor import Executor
from pkmtol.model.mechanism import Mechanism
from pkmtol.present.calibration_tables import (
    dumps,
    identified_csv,
    identified_json,
    identified_text,
    plan_json,
    plan_text,
    residuals_csv,
    study_json,
    study_text,
)
from pkmtol.present.instrument_tables import (
    instrument_identified_csv,
    instrument_json,
    instrument_residuals_csv,
    instrument_text,
)
from pkmtol.present.run_folder import RunFolder, check_distinct
from pkmtol.present.tables import check_output_folder


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol calibrate`` and its options."""
    p = subparsers.add_parser(
        "calibrate",
        help="kinematic calibration: measurement plan, exact simulation study, identification from data",
        description="Without --simulate or --measurements: choose the calibration poses (D-optimal by "
        "default), print what they identify (rank, conditioning, base parameters, unidentifiable "
        "combinations, correlations) and how the plan compares with random plans of the same size, "
        "with the predicted accuracy after calibration; --plan writes the poses for the measurement "
        "session. --simulate: draw machines, measure them on exact kinematics with tracker noise, "
        "identify, compensate and measure held-out poses (docs/calibration.md). --measurements: "
        "identify the controller model from a tracker's measurements and write the identified "
        "parameters and calibrated limb URDFs. Settings come from the [calibration] table of "
        "mechanism.toml; the options override it.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    p.add_argument("--set", dest="pset", choices=["dh", "urdf"], default=None, help="parameter set")
    add_plan_options(p)
    p.add_argument("--plan", type=Path, default=None, help="write the chosen poses to this CSV file")
    p.add_argument("--simulate", action="store_true", help="run the exact-kinematics calibration study")
    p.add_argument("--machines", type=int, default=100, help="machines of the study (default 100)")
    p.add_argument("--holdout", type=int, default=200, help="held-out random poses (default 200)")
    p.add_argument(
        "--plan-per-machine",
        action="store_true",
        help="--simulate: calibrate every machine by its own plan (a new random plan, or the D-optimal "
        "plan of its own half of the candidate pool) and report the plan-to-plan spread",
    )
    p.add_argument("--measurements", type=Path, default=None, help="identify from this measurement CSV")
    p.add_argument(
        "--tracker-on",
        choices=TRACKER_POINTS,
        default=None,
        help="a hybrid machine: the tracker's targets on the TCP frame (default) or on the spindle nose "
        "(the tool's own errors do not move them); [calibration] tracker_on",
    )
    p.add_argument(
        "--tolerances",
        type=Path,
        default=None,
        help="allocation.json of a `pkmtol allocate` run: the σ of the uncompensatable errors "
        "(default: a quick FOSM allocation at the design β)",
    )
    p.add_argument(
        "--accept-poor-fit",
        action="store_true",
        help="--measurements: write the calibrated machine even when the fit did not converge or left "
        "residuals above 5× the noise (the report says it was overridden)",
    )
    p.add_argument("--random-sets", type=int, default=10, help="random plans to compare with (default 10)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default out/<robot>/calibration)")
    p.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    add_executor_options(p)
    add_tool_options(p)
    p.set_defaults(run=_run)


def _tolerances(
    mech: Mechanism, pset: ParameterSet, path: Path | None, seed: int, settings: CalibrationSettings
) -> tuple[np.ndarray, str]:
    """Design-β σ of every parameter (NaN where not allocated), and where they came from.

    A calibrated-mode design's identified parameters are drawn at the manufacturing σ of ``settings``.
    """
    if path is not None:
        return read_tolerances(path, mech.name, pset, settings)
    res = allocate(
        mech,
        DesignOptions(
            parameter_set=pset.kind,
            samples=2000,
            verification_poses=200,
            exact_samples=0,
            claim_poses=50,
            seed=seed,
        ),
    )
    return res.tolerances[
        :, res.design_column
    ], f"FOSM tolerances at β = {res.design_beta:g} (quick allocation)"


def _instrument_data(
    mech: Mechanism,
    pset: ParameterSet,
    grid: RobotGrid,
    settings: CalibrationSettings,
    args: argparse.Namespace,
    out: Path,
) -> list[tuple[Path, bytes]]:
    """Identify from the data of an instrument other than a registered tracker; the files to write."""
    classes = list(grid.classes)
    inst = instrument_for(settings, mech)
    stations = len(getattr(inst, "centres_m", [0]))
    meas = read_instrument_measurements(
        args.measurements, mech, inst, settings.targets(mech).shape[0], stations
    )
    sigma = None
    if settings.prior:
        tol, _ = _tolerances(mech, pset, args.tolerances, args.seed, settings)
        sigma = design_sigma(pset, classes, settings, tol)
    values = _VALUES.get(inst.name, "")
    if inst.name in ("tracker", "tracker-multi"):  # its own frame: identified with the machine
        values = "frame points"
    check = _data_check(
        args,
        meas.values,
        lambda m: inst.measure(m.origins_m, m.rotations, m.station_index, np.zeros(inst.nuisance_count)),
        values,
        settings.noise_m,
    )
    cal = calibrate_instrument_data(
        mech, pset, classes, settings, meas, args.measurements, sigma, grid.chain, grid.sweep, check
    )
    r = cal.result
    verdict = fit_verdict(
        r.converged,
        r.iterations,
        r.rms_after_m,
        settings.noise_m,
        r.residuals_m,
        meas.values if values else None,
        r.residuals_before_m if values else None,
        labels=meas.labels,
        lines=meas.lines,
        values=values,
    )
    note = _judged(verdict, args)
    files = [
        (out / "identified.json", _json_with(instrument_json(cal, pset.names), verdict)),
        (out / "identified.csv", instrument_identified_csv(cal).encode()),
        (
            out / "identified.md",
            ("# Identified parameters\n\n" + note + instrument_text(cal, True)).encode(),
        ),
        (out / "residuals.csv", instrument_residuals_csv(cal).encode()),
    ]
    try:
        urdfs, toml = calibrated_files(mech, pset, cal.result.estimate)  # a hybrid's tool chain too
        files += write_calibrated_folder(out / "calibrated", urdfs, toml)
    except Exception as err:  # noqa: BLE001 - reported, the identification stands
        print(f"pkmtol: warning: no calibrated URDFs: {err}", file=sys.stderr)
    print(note + instrument_text(cal), end="")
    return files


#: What an instrument's values are, for the fit check's causes (``fit_check.VALUE_KINDS``).
_VALUES = {"ballbar": "distances"}


def _target_points(maps: PoseMaps, targets_m: np.ndarray) -> np.ndarray:
    """The nominal positions (N, t, 3) in K of the platform's targets at the maps' poses [m]."""
    return maps.origins_m[:, None, :] + np.einsum("kab,tb->kta", maps.rotations, targets_m)


def _data_check(
    args: argparse.Namespace,
    measured: np.ndarray,
    nominal: Callable[[PoseMaps], np.ndarray],
    values: str,
    noise_m: float,
) -> Callable[[PoseMaps], None] | None:
    """Before the fit: refuse zeros, a wrong unit or a repeated value (not with ``--accept-poor-fit``)."""
    if args.accept_poor_fit or not values:
        return None

    def check(maps: PoseMaps) -> None:
        model = np.asarray(nominal(maps), dtype=float).reshape(np.shape(measured))
        verdict = data_verdict(measured, model, noise_m, values)
        if verdict.poor:
            raise PoorFitError(args.measurements, verdict.cause, verdict.problem)

    return check


def _judged(verdict: FitVerdict, args: argparse.Namespace) -> str:
    """Refuse a poor fit (:class:`PoorFitError`) unless ``--accept-poor-fit``; the report's note then."""
    if not verdict.poor:
        return ""
    if not args.accept_poor_fit:
        raise PoorFitError(args.measurements, verdict.cause, verdict.problem)
    print(f"pkmtol: warning: poor fit accepted by --accept-poor-fit: {verdict.problem}", file=sys.stderr)
    return f"POOR FIT, written because --accept-poor-fit overrode the check: {verdict.problem}\n\n"


def _json_with(doc: dict, verdict: FitVerdict) -> bytes:
    """identified.json: the identification with its fit check (and whether it was overridden)."""
    doc["fit_check"] = {
        "poor": verdict.poor,
        "overridden_by_accept_poor_fit": verdict.poor,
        "cause": verdict.cause,
        "problem": verdict.problem,
        "rms_after_m": verdict.rms_after_m,
        "limit_m": verdict.limit_m,
    }
    return dumps(doc).encode()


def _run(args: argparse.Namespace) -> int:
    mech = apply_tool_options(cached_mechanism(args.robot), args)  # loaded once while its files are unchanged
    if args.tracker_on is not None:  # a hybrid's tracker on the TCP or the spindle nose
        mech = with_tracker_on(mech, args.tracker_on)
    for name, value, low in (
        ("--machines", args.machines, 1),
        ("--holdout", args.holdout, 1),
        ("--seed", args.seed, 0),
    ):
        if value < low:
            raise InvalidRequestError(f"{name} must be ≥ {low}, got {value}")
    if args.simulate and args.measurements is not None:
        raise InvalidRequestError("give either --simulate or --measurements, not both")
    if args.plan_per_machine and not args.simulate:
        raise InvalidRequestError("--plan-per-machine is an option of the study: give --simulate too")
    settings = plan_settings(mech, args, args.seed)
    if args.tolerances is not None and args.measurements is not None and not settings.prior:
        raise InvalidArgumentError(
            "--tolerances",
            str(args.tolerances),
            "with --measurements only a --prior identification reads it (the σ of the prior); give "
            "--prior (or [calibration] prior = true), or leave --tolerances out",
        )
    if mech.tool is not None:  # a hybrid: a tracker on the TCP frame (calibration/hybrid_poses.py)
        check_instrument(mech, settings)
    executor = executor_from(args)  # a bad --workers or an unreachable --dask fails before any work
    pset = machine_parameter_set(mech, args.pset)  # a hybrid's: the module's, then the tool chain's
    check_calibration_request(
        len(pset),
        3 * settings.targets(mech).shape[0],
        args.machines,
        args.holdout,
        settings.candidates,
        args.random_sets,
        args.simulate,
        available_memory(),
    )
    out = args.out if args.out is not None else Path("out") / mech.name / "calibration"
    if args.plan is not None:
        check_output_folder(args.plan.parent if str(args.plan.parent) else Path("."))
        check_distinct([out / name for name in RUN_NAMES] + [args.plan])  # --plan at a run file
    with RunFolder(out) as run:  # one run at a time, written all or nothing (issue 25)
        files = _outputs(args, mech, settings, executor, pset, out)
        inside = {p.name: data for p, data in files if p.parent == out}
        outside = {p: data for p, data in files if p.parent != out}
        for path in outside:
            path.parent.mkdir(parents=True, exist_ok=True)
        written = run.write(inside, outside)
    for path in written:
        print(f"wrote {path}")
    return 0


#: The files a calibrate run may write into its folder (``--plan`` must not be one of them).
RUN_NAMES = (
    "identified.json",
    "identified.csv",
    "identified.md",
    "residuals.csv",
    "calibration_plan.json",
    "calibration_plan.md",
    "study.json",
    "study.md",
)


def _outputs(
    args: argparse.Namespace,
    mech: Mechanism,
    settings: CalibrationSettings,
    executor: Executor,
    pset: ParameterSet,
    out: Path,
) -> list[tuple[Path, bytes]]:
    """Compute what ``args`` asks for and print it; the files of the run, rendered in memory."""
    grid = robot_grid(mech, pset)  # one grid sweep for the classes and the nominal solutions
    classes = list(grid.classes)
    files: list[tuple[Path, bytes]] = []
    figures: dict[str, object] = {}
    registered = (
        settings.instrument in ("tracker", "tracker-multi") and settings.tracker_frame == "registered"
    )
    if args.measurements is not None and not registered:
        files += _instrument_data(mech, pset, grid, settings, args, out)
    elif args.measurements is not None:
        meas = read_measurements(args.measurements, mech, settings.targets(mech).shape[0])
        sigma = None
        if settings.prior:
            tol, _ = _tolerances(mech, pset, args.tolerances, args.seed, settings)
            sigma = design_sigma(pset, classes, settings, tol)
        targets = settings.targets(mech)
        check = _data_check(
            args, meas.measured_m, lambda m: _target_points(m, targets), "points", settings.noise_m
        )
        cal = calibrate_measurements(
            mech, pset, classes, settings, meas, args.measurements, sigma, grid.chain, grid.sweep, check
        )
        r = cal.result
        verdict = fit_verdict(
            r.converged,
            r.iterations,
            r.rms_after_m,
            cal.ident.noise_m,
            r.residuals_m,
            meas.measured_m,
            r.residuals_before_m,
            cal.H[:, cal.ident.columns],
            cal.ident.scale,
            meas.labels,
            meas.lines,
        )
        note = _judged(verdict, args)
        text = note + identified_text(cal)
        files += [
            (out / "identified.json", _json_with(identified_json(cal, pset.names), verdict)),
            (out / "identified.csv", identified_csv(cal).encode()),
            (
                out / "identified.md",
                ("# Identified parameters\n\n" + note + identified_text(cal, True)).encode(),
            ),
            (out / "residuals.csv", residuals_csv(cal).encode()),
        ]
        try:
            urdfs, toml = calibrated_files(mech, pset, cal.result.estimate)  # a hybrid's tool chain too
            files += write_calibrated_folder(out / "calibrated", urdfs, toml)
        except Exception as err:  # noqa: BLE001 - reported, the identification stands
            print(f"pkmtol: warning: no calibrated URDFs: {err}", file=sys.stderr)
        print(text, end="")
    else:
        tol, source = _tolerances(mech, pset, args.tolerances, args.seed, settings)
        sigma = design_sigma(pset, classes, settings, tol)
        print(
            f"machines drawn with: compensatable errors at the manufacturing σ "
            f"({1e3 * settings.manufacturing_length_m:g} mm, "
            f"{1e3 * settings.manufacturing_angle_rad:g} mrad); "
            f"uncompensatable errors at the {source}"
        )
        report = plan_report(
            mech,
            pset,
            classes,
            settings,
            sigma,
            mech.target_m,
            random_sets=args.random_sets,
            holdout=args.holdout,
        )
        text = plan_text(report)
        files += [
            (out / "calibration_plan.json", dumps(plan_json(report, pset.names)).encode()),
            (out / "calibration_plan.md", ("# Calibration plan\n\n" + plan_text(report, True)).encode()),
        ]
        if args.plan is not None:
            pm = report.plan.maps
            text_plan = (
                instrument_plan_csv(mech, pm.commands, pm.points_m, report.plan.stations)
                if settings.instrument in ("ballbar", "probe")
                else plan_csv(mech, pm.commands, pm.points_m)
            )
            files.append((args.plan, text_plan.encode()))
        study = None
        if args.simulate:
            rep = simulate(
                mech,
                pset,
                classes,
                settings,
                sigma,
                mech.target_m,
                args.machines,
                args.holdout,
                executor=executor,
                plans_per_machine=args.plan_per_machine,
            )
            study = rep.study
            text += "\n" + study_text(rep)
            files += [
                (out / "study.json", dumps(study_json(rep)).encode()),
                (out / "study.md", ("# Calibration study\n\n" + study_text(rep, True)).encode()),
            ]
        if not args.no_figures:
            try:
                from pkmtol.present.calibration_figures import (
                    histogram_figure,
                    pose_count_figure,
                    render_figures,
                )

                if report.curve:
                    figures["p99_against_poses"] = pose_count_figure(report, study)
                if study is not None:
                    figures["calibration_histogram"] = histogram_figure(study)
                files += render_figures(figures, out)
            except FiguresError as err:
                print(f"pkmtol: warning: no figures: {err}", file=sys.stderr)
        print(text, end="")
    if not files:  # pragma: no cover - every mode writes its tables
        raise OutputError(out, "nothing to write")
    return files
