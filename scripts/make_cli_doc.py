"""Generate (or check) docs/cli.md from the ``pkmtol --help`` and ``pkmtol <command> --help`` output.

The help texts are produced by ``pkmtol.cli.main`` itself, at a fixed width of 100 columns, so the
page shows exactly what the command prints. ``tests/test_docs.py`` runs the ``--check`` mode: change
the command line, then rerun this script.

Usage:
    python scripts/make_cli_doc.py          # write docs/cli.md
    python scripts/make_cli_doc.py --check  # exit 1 if docs/cli.md differs from the help texts
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import sys
from pathlib import Path

from pkmtol.cli import main as pkmtol_main

DOC = Path(__file__).resolve().parents[1] / "docs" / "cli.md"
WIDTH = "100"

INTRO = """\
# Command-line reference

`pkmtol` has one subcommand per job; each is a thin layer over a library function of the same
name ([api.md](api.md)). Every subcommand takes a robot folder (`mechanism.toml` with its limb URDFs,
[mechanism-format.md](mechanism-format.md), or a closed-loop tree, [closed-loop.md](closed-loop.md)).

**Exit codes**: 0 success; 1 `check` ran and found a problem (an unreachable task-space point, a
mobility different from the number of actuators); 2 a pkmtol error — a bad description, an impossible
request, an unwritable output — printed on stderr as `pkmtol: error: <message>`, where the message
says what is wrong and what to do.

**Units**: lengths on the command line carry their unit (`--target 0.05mm`, `50um`, `5e-5m`); a number
without a unit is refused. Tables print lengths in mm and angles in mrad (`--units um`: µm and µrad);
JSON files are SI.

**Bad values** are refused before any work, naming the option (`--seed -1: must be ≥ 0`); a request
that would not fit in memory is refused up front with the estimate; progress bars show on stderr
when it is a terminal (`--no-progress` hides them). [errors.md](errors.md) lists the bad inputs and
their messages.

This page is generated from the commands' `--help` by `scripts/make_cli_doc.py` (a test keeps it in
sync). A walk-through with real output is in the [tutorial](tutorial.md).
"""

EXAMPLES = {
    "check": [
        "pkmtol check robots/r2rps_ups",
    ],
    "errors": [
        "pkmtol errors robots/r2rps_ups",
        "pkmtol errors robots/r2rps_ups --set urdf --json out/errors.json",
    ],
    "allocate": [
        "pkmtol allocate robots/r2rps_ups",
        "pkmtol allocate robots/r2rps_ups --target 20um --beta 2 --samples 2000 --out out/quick",
        "pkmtol allocate robots/r2rps_ups --method exact --criterion worst",
        "pkmtol allocate robots/r2rps_ups --method cost --html out/scene.html",
    ],
    "new": [
        "pkmtol new tricept --base-radius 550mm --out robots/my_tricept",
        "pkmtol new sprint_z3 --rod-length 450mm --slider-stroke 0mm 600mm --out robots/my_z3",
    ],
    "show": [
        "pkmtol show robots/r2rps_ups",
        "pkmtol show robots/r2rps_ups --html out/scene.html",
    ],
    "sweep": [
        "pkmtol sweep robots/r2rps_ups --vary 'reference_point.position_m[2]=0.1:0.5:5'",
        "pkmtol sweep robots/r2rps_ups --vary 'limbs[limb1].dh.links[0][2]=0.45:0.55:3' "
        "--vary 'task_space.radius_m=0.5:0.6:2' --workers 2",
        "pkmtol sweep robots/r2rps_ups --vary 'design.design_beta=1:3:5' --dask tcp://scheduler:8786",
    ],
}


def help_text(*args: str) -> str:
    """What ``pkmtol <args> --help`` prints, at WIDTH columns."""
    buf = io.StringIO()
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
            pkmtol_main([*args, "--help"])
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    return buf.getvalue().rstrip() + "\n"


def commands(top: str) -> list[str]:
    """Subcommand names listed in the top-level help."""
    section = top.split("positional arguments:", 1)[1].split("\noptions:", 1)[0]
    return re.findall(r"^ {4}(\w[\w-]*)", section, re.M)


def generate() -> str:
    """The text of docs/cli.md."""
    top = help_text()
    parts = [INTRO, "## pkmtol\n", "```text\n" + top + "```\n"]
    for cmd in commands(top):
        parts.append(f"## pkmtol {cmd}\n")
        text = help_text(cmd)
        parts.append("```text\n" + text + "```\n")
        for sub in commands(text) if "positional arguments:" in text else []:
            parts.append(f"### pkmtol {cmd} {sub}\n")
            parts.append("```text\n" + help_text(cmd, sub) + "```\n")
        if cmd in EXAMPLES:
            parts.append("Examples:\n")
            parts.append("```bash\n" + "\n".join(EXAMPLES[cmd]) + "\n```\n")
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare with docs/cli.md instead of writing it")
    args = ap.parse_args(argv)
    text = generate()
    if args.check:
        if not DOC.is_file() or DOC.read_text(encoding="utf-8") != text:
            print(
                f"{DOC} is out of date with the command line; rerun: python scripts/make_cli_doc.py",
                file=sys.stderr,
            )
            return 1
        return 0
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
