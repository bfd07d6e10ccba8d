"""``pkmtol sweep``: dimensional synthesis — the accuracy design over a grid of mechanism.toml numbers."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pkmtol.cli.common import add_executor_options, executor_from
from pkmtol.design.exact import CRITERIA
from pkmtol.design.options import DEFAULT_CRITERION, DEFAULT_METHOD, METHODS
from pkmtol.design.synthesis import check_keys, parse_vary, read_doc, synthesize
from pkmtol.exceptions import FiguresError, InvalidArgumentError
from pkmtol.executor import Executor
from pkmtol.model.loader import load_mechanism
from pkmtol.present.run_folder import RunFolder
from pkmtol.present.synthesis import summary_text, sweep_figure, to_csv, to_json


def add(subparsers: argparse._SubParsersAction) -> None:
    """Register ``pkmtol sweep`` and its options."""
    p = subparsers.add_parser(
        "sweep",
        help="dimensional synthesis: reachability, worst σ[Δλ], tolerances and cost per design variant",
        description="Vary numbers of mechanism.toml (dimensions, D–H entries, the reference point, the "
        "task space) over a grid and run the accuracy design of every variant: whether the task "
        "space is reachable, the worst σ[Δλ] (every uncompensatable error ~ N(0, 1)), the tolerances "
        "at the design β (the same allocation as allocate, --method below), σ[Δλ] when the "
        "tolerances of the robot as given are kept, and "
        "the cost of the tolerances. URDFs of limbs whose D–H table changes are regenerated in "
        "memory. Writes sweep.csv, sweep.json and sweep.png/.svg into --out.",
    )
    p.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    p.add_argument(
        "--vary",
        action="append",
        required=True,
        metavar="KEY=START:STOP:N",
        help="a number of mechanism.toml and N values from START to STOP (file units: m, degrees "
        "for D–H angles), e.g. reference_point.position_m[2]=0.1:0.5:5 or "
        "limbs[limb1].dh.links[0][2]=0.45:0.55:3; repeat for a grid of variants",
    )
    p.add_argument("--set", dest="pset", choices=["dh", "urdf"], default=None, help="parameter set")
    p.add_argument("--beta", type=float, default=None, help="β of the tolerances (default: the design β)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: out/<robot name>-sweep)")
    p.add_argument("--no-figures", action="store_true", help="do not write the figure")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--compensate-with",
        choices=["machine", "module"],
        default=None,
        help="a hybrid machine: which actuators compensate (default: [tool] compensation, else machine)",
    )
    p.add_argument(
        "--method",
        choices=list(METHODS),
        default=DEFAULT_METHOD,
        help=f"the design method of every variant, as allocate --method (default {DEFAULT_METHOD})",
    )
    p.add_argument(
        "--criterion",
        choices=list(CRITERIA),
        default=None,
        help="only with --method exact: where Φ(β) must hold, as allocate --criterion (default every)",
    )
    add_executor_options(p)
    p.set_defaults(run=_run)


def _run(args: argparse.Namespace) -> int:
    if args.criterion is not None and args.method != "exact":
        raise InvalidArgumentError(
            "--criterion",
            args.criterion,
            f"only --method exact reads it; --method {args.method} would ignore it",
        )
    varies = [parse_vary(spec) for spec in args.vary]
    load_mechanism(args.robot)  # a robot that cannot load fails before any output
    check_keys(read_doc(args.robot), varies)
    executor = executor_from(args)
    out = args.out if args.out is not None else Path("out") / f"{args.robot.name}-sweep"
    with RunFolder(out) as run:  # one run at a time, written all or nothing (issue 25)
        return _sweep(args, varies, executor, run)


def _sweep(args: argparse.Namespace, varies: list, executor: Executor, run: RunFolder) -> int:
    from tqdm import tqdm

    total = 1
    for v in varies:
        total *= len(v.values)
    bar = tqdm(
        total=total, desc="variants", unit="variant", disable=args.no_progress or not sys.stderr.isatty()
    )
    result = synthesize(
        args.robot,
        varies,
        args.pset,
        args.beta,
        executor,
        progress=lambda n: bar.update(1),
        tool_scope=args.compensate_with,
        method=args.method,
        criterion=args.criterion or DEFAULT_CRITERION,
    )
    bar.close()
    print(summary_text(result), end="")
    files = {"sweep.csv": to_csv(result).encode(), "sweep.json": to_json(result).encode()}
    if not args.no_figures:
        try:
            from pkmtol.present.plotting import render

            fig = sweep_figure(result)
            files.update({f"sweep.{fmt}": render(fig, fmt, 150) for fmt in ("png", "svg")})
        except (FiguresError, ImportError) as err:
            print(f"pkmtol: warning: no figure: {err}", file=sys.stderr)
    written = run.write(files)
    for path in written:
        print(f"wrote {path}")
    return 0
