"""``pkmtol allocate``: the main job — tolerance table, verification, files, figures, 3D page."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pkmtol.cli.calibration_options import add_plan_options, calibrated_settings
from pkmtol.cli.common import (
    OPTION_OF_FIELD,
    add_executor_options,
    add_tool_options,
    apply_tool_options,
    executor_from,
    named_as_options,
    show_progress,
    target_option,
)
from pkmtol.design.budget import check_memory
from pkmtol.design.job import DesignOptions, DesignResult, allocate
from pkmtol.design.mode_verification import CALIBRATED_EXACT_SAMPLES
from pkmtol.design.options import DEFAULT_CRITERION, DEFAULT_METHOD
from pkmtol.exceptions import FiguresError, InvalidArgumentError, InvalidRequestError, OutputError
from pkmtol.model.drawing import CONVENTIONS, DrawingSettings
from pkmtol.model.loader import load_mechanism
from pkmtol.present.headline import headline_lines
from pkmtol.present.outputs import render_tables
from pkmtol.present.run_folder import MANIFEST, RUN_FILES, RunFolder, check_distinct
from pkmtol.present.tables import summary_text
from pkmtol.present.viewer.options import SceneOptions
from pkmtol.units import parse_angle


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol allocate`` and its options."""
    p = subparsers.add_parser(
        "allocate",
        help="the main job: tolerance table for a required accuracy and reliability",
        description="Error model, sensitive-pose search, FOSM tolerance allocation over the β "
        "series (the paper's Table III), verification by Monte Carlo (linear model and exact "
        "kinematics) and the traditional method for comparison. Prints the tables and writes "
        "allocation.json, allocation.csv and allocation.md (and figures) into --out, all or "
        "nothing: the previous run's files are replaced, pkmtol-run.json lists the run's files, "
        "and a second run into the same --out at the same time is refused.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    p.add_argument(
        "--target",
        default=None,
        help="required accuracy Δλ* at P with its unit, e.g. 0.05mm or 50um (default: mechanism.toml)",
    )
    p.add_argument(
        "--beta",
        type=float,
        nargs="+",
        default=None,
        help="reliability index of the design (one value) or the whole β series "
        "(several; the design β is then --design-beta or the mechanism's)",
    )
    p.add_argument("--design-beta", type=float, default=None, help="β of the verified design")
    p.add_argument("--set", dest="pset", choices=["dh", "urdf"], default=None, help="parameter set")
    p.add_argument(
        "--samples",
        type=int,
        default=10_000,
        help="Monte Carlo samples (default 10000); a count that would not fit in memory is refused "
        "up front with the estimate",
    )
    p.add_argument(
        "--exact-samples",
        type=int,
        default=1_000,
        help="exact-kinematics verification samples per distribution (default 1000; under "
        f"--compensation calibrated at most {CALIBRATED_EXACT_SAMPLES}, Gaussian only, each a simulated "
        "calibration of its own machine; a cap prints a note)",
    )
    p.add_argument(
        "--verification-poses",
        type=int,
        default=2_000,
        help="distinct random task-space poses of the verification (default 2000)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed, ≥ 0 (default 0)")
    p.add_argument(
        "--method",
        choices=["fosm", "exact", "cost"],
        default=DEFAULT_METHOD,
        help="fosm: the paper's Eq. 20 (one-pose FOSM at the design point); exact: equal-effect "
        "shape scaled so that the exact reliability of the linear model equals Φ(β) where "
        "--criterion says; cost: cheapest tolerances with exact reliability ≥ Φ(β) at every grid "
        f"pose (default {DEFAULT_METHOD})",
    )
    p.add_argument(
        "--criterion",
        choices=["worst", "every", "average"],
        default=None,
        help="only with --method exact: reach Φ(β) at the worst pose, at every grid pose (default) "
        "or on average",
    )
    p.add_argument(
        "--units",
        choices=["mm", "um"],
        default="mm",
        help="units of the tolerance tables: mm and mrad (default) or um (µm and µrad)",
    )
    p.add_argument(
        "--compensation",
        choices=["ideal", "calibrated", "none"],
        default="ideal",
        help="ideal: the paper's Eq. 25 (default); calibrated: the machine after a least-squares "
        "calibration (plan from [calibration] or the options below); none: the traditional method",
    )
    p.add_argument(
        "--orientation-target",
        default=None,
        help="largest tilt Δα* of the tool axis, e.g. 0.1mrad (default: [design] orientation_target; none)",
    )
    p.add_argument(
        "--tool-axis",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="tool axis in the platform frame (default: [design] tool_axis, else 0 0 1)",
    )
    add_plan_options(p)
    p.add_argument("--out", type=Path, default=None, help="output folder (default: out/<robot name>)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--view",
        action="store_true",
        help="afterwards, serve the 3D scene in meshcat on 127.0.0.1 until Ctrl-C",
    )
    p.add_argument(
        "--html",
        type=Path,
        default=None,
        help="also write the 3D scene as a self-contained HTML page to FILE",
    )
    p.add_argument(
        "--no-figures",
        action="store_true",
        help="do not write the PNG/SVG figures (without matplotlib they are left out with a warning)",
    )
    p.add_argument(
        "--report",
        type=Path,
        default=None,
        metavar="FILE",
        help="also write the sign-off report to FILE (.html): every table, the figures as inline SVG, "
        "the 3D scene and the provenance in one self-contained page that loads nothing from the network",
    )
    p.add_argument(
        "--drawing",
        choices=CONVENTIONS,
        default=None,
        help="drawing tolerances: normal, ±t = k·σ (default, k = 3), or uniform, ±t = √3·σ "
        "(default: [drawing] convention)",
    )
    p.add_argument(
        "--drawing-k",
        type=float,
        default=None,
        metavar="K",
        help="the k of ±t = k·σ (default: [drawing] k, else 3)",
    )
    p.add_argument(
        "--ellipsoids",
        action="store_true",
        help="in the 3D scene (--html, --view, --report), the 1σ ellipsoid of P's error at every grid "
        "point instead of a sphere",
    )
    add_executor_options(p)
    add_tool_options(p)
    p.set_defaults(run=_run)


def _run(args: argparse.Namespace) -> int:
    mech = apply_tool_options(load_mechanism(args.robot), args)
    target = target_option(args.target)
    betas = design_beta = None
    if args.beta is not None and len(args.beta) == 1:
        design_beta = args.beta[0]
    elif args.beta is not None:
        betas = tuple(args.beta)
    if args.design_beta is not None:
        design_beta = args.design_beta
    if args.criterion is not None and args.method != "exact":
        raise InvalidArgumentError(
            "--criterion",
            args.criterion,
            f"only --method exact reads it; --method {args.method} would ignore it",
        )
    orientation = None
    if args.orientation_target is not None:
        try:
            orientation = parse_angle(args.orientation_target, "--orientation-target")
        except InvalidRequestError as err:
            raise InvalidArgumentError(
                "--orientation-target",
                args.orientation_target,
                str(err).removeprefix("--orientation-target: "),
            ) from err
    # one --beta value is the design β: name it as typed
    names = {
        **OPTION_OF_FIELD,
        "design_beta": "--design-beta" if args.design_beta is not None else "--beta",
        "orientation_target_rad": "--orientation-target",
        "tool_axis": "--tool-axis",
    }
    with named_as_options(names):
        opts = DesignOptions(
            target_m=target,
            betas=betas,
            design_beta=design_beta,
            parameter_set=args.pset,
            samples=args.samples,
            verification_poses=args.verification_poses,
            exact_samples=args.exact_samples,
            seed=args.seed,
            method=args.method,
            criterion=args.criterion or DEFAULT_CRITERION,
            progress=show_progress(args.no_progress),
            executor=executor_from(args),
            compensation=args.compensation,
            calibration=calibrated_settings(mech, args, args.seed),
            orientation_target_rad=orientation,
            tool_axis=None if args.tool_axis is None else tuple(args.tool_axis),
            drawing=drawing_option(mech.extra.get("drawing"), args.drawing, args.drawing_k),
        )
        check_memory(mech, opts)
    out = args.out if args.out is not None else Path("out") / mech.name
    for name, path in (("--html", args.html), ("--report", args.report)):
        if path is not None and not (path.parent if str(path.parent) else Path(".")).is_dir():
            raise OutputError(path, f"folder {path.parent} does not exist; create it first ({name})")
    given = [p for p in (args.html, args.report) if p is not None]
    check_distinct([out / name for name in (*RUN_FILES, MANIFEST)] + given)  # before any work
    options = scene_options(args.ellipsoids)
    with RunFolder(out) as run:
        result = allocate(mech, opts)
        # everything is rendered before anything is written: a failure leaves the folder as it was
        files = render_tables(result, args.units)
        if not args.no_figures:
            files.update(_figures(result))
        page = None
        if args.html is not None:
            from pkmtol.present.viewer.export import render_html

            page = render_html(result, args.html, options)
        outside = {} if page is None else {args.html: page.data}
        report = None
        if args.report is not None:
            report = _render_report(result, options, args.seed, getattr(args, "argv", sys.argv))
            outside[args.report] = report.data
        written = run.write(files, outside)
    print(summary_text(result, units=args.units), end="")
    print("\nstage times: " + ", ".join(f"{k} {v:.2f} s" for k, v in result.timings_s.items()))
    for path in written[: len(files)]:
        print(f"wrote {path}")
    if page is not None:
        spheres = page.export.scene.spheres
        print(
            f"wrote {args.html} ({page.export.bytes} bytes, {spheres.count if spheres else 0} error spheres)"
        )
    if report is not None:
        if report.figures_missing:
            print(f"pkmtol: warning: report without figures: {report.figures_missing}", file=sys.stderr)
        print(
            f"wrote {args.report} ({len(report.data)} bytes: {len(report.sections)} sections, "
            f"{len(report.figures)} figures)"
        )
    print("\n".join(["", *headline_lines(result)]))  # the last lines: the claim, a failed check
    if args.view:
        view(result, None, True, options)
    return 0


def drawing_option(
    table: DrawingSettings | None, convention: str | None, k: float | None
) -> DrawingSettings | None:
    """The mechanism's ``[drawing]`` settings with ``--drawing`` / ``--drawing-k`` applied (None: as is).

    Raises:
        InvalidArgumentError: ``--drawing-k`` with the uniform convention, or a k that is not positive.
    """
    if convention is None and k is None:
        return None
    if k is not None and not 0 < k <= 10:  # issue 25: 1e308 overflowed the drawing's ±t
        raise InvalidArgumentError("--drawing-k", k, "the k of ±t = k·σ must be in (0, 10], e.g. 3")
    base = table if table is not None else DrawingSettings()
    if k is not None and (convention or base.convention) == "uniform":
        raise InvalidArgumentError(
            "--drawing-k", k, "it sets the k of ±t = k·σ; the uniform convention has none (√3)"
        )
    try:
        return base.with_convention(convention, k)
    except InvalidRequestError as err:
        raise InvalidArgumentError("--drawing-k", k, str(err)) from err


def scene_options(ellipsoids: bool) -> SceneOptions | None:
    """The 3D scene's options for ``--ellipsoids`` (None: the defaults)."""
    return SceneOptions(glyph="ellipsoid") if ellipsoids else None


def _render_report(result: DesignResult, options: SceneOptions | None, seed: int, argv: list[str]):  # noqa: ANN202
    """The sign-off report rendered in memory (``argv``: the command's words, for its provenance)."""
    from pkmtol.present.html_report import render_report
    from pkmtol.present.provenance import provenance

    return render_report(result, provenance(result.mechanism, seed, argv), options)


def _figures(result: DesignResult) -> dict[str, bytes]:
    """The figures in memory; without matplotlib, one warning line and none."""
    from pkmtol.present.figures import render_figures

    try:
        return render_figures(result)
    except FiguresError as err:
        print(f"pkmtol: warning: no figures: {err}", file=sys.stderr)
        return {}


def view(result: DesignResult, html: Path | None, live: bool, options: SceneOptions | None = None) -> None:
    """Write the 3D page to ``html`` (if given), then serve the scene live (if ``live``)."""
    from pkmtol.present.viewer.export import export_html, show

    if html is not None:
        info = export_html(result, html, options)
        spheres = info.scene.spheres
        print(f"wrote {info.path} ({info.bytes} bytes, {spheres.count if spheres else 0} error spheres)")
    if live:
        show(result, options)
