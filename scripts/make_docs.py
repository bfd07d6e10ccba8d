"""Regenerate (or check) the generated blocks of the docs pages: every number comes from a command.

A page (``docs/*.md`` or ``README.md``) marks a block as

    <!-- generated: NAME inputs=HASH -->
    ...what the generator NAME printed...
    <!-- end -->

and :data:`GENERATORS` says how NAME is made: a command (``pkmtol ...`` or a script), run in a
fresh process at the repository root with this worktree's ``src`` first on the path and
``COLUMNS=100``. ``HASH`` is the SHA-256 (first 16 hex digits) of what determines the block's
output, and of nothing else, so that a refactor elsewhere leaves the block fresh:

* the generator's command text (as shown on the page);
* the files it reads (``Generator.inputs``: the robot folder, the scripts it runs);
* the source of the generator in this script: its ``make`` function and, recursively, every
  function and constant of this script that it names (:func:`script_parts`), plus the source file
  of any ``pkmtol`` function this script calls itself (``fit_text``);
* the source files of the modules its commands actually imported, measured when it was last
  generated: each command runs with ``python -X importtime``, and the ``pkmtol`` modules (and the
  ``scripts/`` modules) named in that log are recorded per generator in :data:`IMPORTS`
  (``docs/data/generated_inputs.json``).

The recorded module list is sound as long as the imports are static: a command can only import a
new module if one of the files it imported before changed (or its inputs did), and that already
changes the hash, so the block is regenerated and its list re-measured. So ``--check`` is cheap
(no command runs): a block is stale when its recorded hash differs from its inputs' hash today.
``tests/test_docs.py`` runs the check, and regenerates the cheap blocks (a few seconds each) and
compares them verbatim.

Usage:
    python scripts/make_docs.py                     # regenerate every block
    python scripts/make_docs.py --only machines     # one generator (its blocks, in every page)
    python scripts/make_docs.py --check             # exit 1 listing the stale or unknown blocks
    python scripts/make_docs.py --list              # the generators, their commands and pages
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import CodeType, FunctionType

from pkmtol.present.terminal import fit_text

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Per generator, the repository files (``src/pkmtol/...``, ``scripts/...``) its commands imported.
IMPORTS = DOCS / "data" / "generated_inputs.json"
SEED = "robots/r2rps_ups"
BLOCK = re.compile(
    r"<!-- generated: (?P<name>[\w-]+) inputs=(?P<hash>\w+) -->\n(?P<body>.*?)<!-- end -->", re.S
)


@dataclass(frozen=True)
class Generator:
    """How one or more blocks are made.

    Attributes:
        name: The generator's name (its blocks are ``name`` and ``name-<part>``).
        command: What it runs, as shown on the page (``pkmtol`` is ``python -m pkmtol.cli``).
        make: ``make(tmp) -> {block name: text}``; ``tmp`` is a fresh folder.
        inputs: Files (globs relative to the repository) it reads besides ``src/pkmtol``.
        cheap: Fast enough (a few seconds) for the docs test to regenerate and compare.
    """

    name: str
    command: str
    make: Callable[[Path], dict[str, str]]
    inputs: tuple[str, ...]
    cheap: bool = False


def run(command: str, cwd: Path = ROOT, columns: int = 100) -> tuple[str, float, float]:
    """Run ``command`` (``pkmtol`` → this Python's ``-m pkmtol.cli``): (stdout, wall [s], CPU [s]).

    The process runs with ``-X importtime``; the repository modules it imported are added to
    :data:`_imported` (see :func:`generate`).
    """
    words = command.split()
    tail = ["-m", "pkmtol.cli", *words[1:]] if words[0] == "pkmtol" else words
    argv = [sys.executable, "-X", "importtime", *tail]
    env = dict(
        os.environ,
        COLUMNS=str(columns),
        PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
    )
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    log = [line for line in done.stderr.splitlines() if line.startswith("import time:")]
    _imported.update(module_files(line.rpartition("|")[2].strip() for line in log))
    entry = ROOT / ("src/pkmtol/cli/__main__.py" if words[0] == "pkmtol" else words[0])
    if entry.is_file():  # run as __main__, so not in the log
        _imported.add(str(entry.relative_to(ROOT)))
    if done.returncode not in (0, 1):
        stderr = "\n".join(line for line in done.stderr.splitlines() if not line.startswith("import time:"))
        raise SystemExit(f"make_docs: `{command}` failed ({done.returncode}):\n{stderr}")
    return done.stdout, wall, cpu


#: The repository files imported by the commands run since :func:`generate` began.
_imported: set[str] = set()


def module_files(modules: object) -> set[str]:
    """The repository files (relative paths) of the module names ``modules`` that live here.

    ``pkmtol.a.b`` is ``src/pkmtol/a/b.py`` or ``src/pkmtol/a/b/__init__.py``; a top-level name
    that is a file of ``scripts/`` (a script importing its neighbour) is that file. Others (the
    standard library, numpy, Pinocchio) are not inputs of this repository.
    """
    found = set()
    for name in modules:  # type: ignore[attr-defined]
        parts = str(name).split(".")
        candidates = [ROOT / "scripts" / f"{name}.py"] if len(parts) == 1 else []
        if parts[0] == "pkmtol":
            base = ROOT / "src" / Path(*parts)
            candidates = [base.with_suffix(".py"), base / "__init__.py"]
        found |= {str(c.relative_to(ROOT)) for c in candidates if c.is_file()}
    return found


def fenced(text: str) -> str:
    return "```text\n" + text.rstrip("\n") + "\n```\n"


def between(lines: list[str], first: str, stop: str | None) -> list[str]:
    """The lines from the first that starts with ``first`` up to (not with) the next starting ``stop``."""
    start = next(k for k, line in enumerate(lines) if line.startswith(first))
    end = next((k for k in range(start + 1, len(lines)) if stop and lines[k].startswith(stop)), len(lines))
    return lines[start:end]


# --- the generators ------------------------------------------------------------------------------


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
    out, _, _ = run(f"pkmtol check {folder} --no-progress")
    return {"tutorial-mobility": fenced(out.rstrip("\n").splitlines()[-1])}


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
    out, _, _ = run(f"{ALLOCATE} --out {tmp}/out")
    lines = [line.replace(f"{tmp}/out", "out/r2rps_ups") for line in out.rstrip("\n").splitlines()]
    head = between(lines, "pkmtol allocation", "Contributions to")
    wrote = [line for line in lines if line.startswith("wrote ")]
    note = [
        "…  (contributions, stack-up, capability and drawing tolerances — docs/report.md —, claimed-vs-true",
        "   reliability, the 'exact' design's table, traditional method, stage times)",
        "",
    ]
    claim = next(line for line in lines if line.startswith("claim ("))
    made = {"tutorial-allocate": fenced("\n".join([*head[:-1], *note, *wrote, "", claim]))}
    fosm, _, _ = run(f"{ALLOCATE} --method fosm --no-figures --out {tmp}/fosm")
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
    out, wall, cpu = run(CALIBRATED + f" --out {tmp}/cal")
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
        "tutorial-allocate-calibrated": fenced("\n".join(shown)),
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
SEED_FILES = (f"{SEED}/*",)

GENERATORS = {
    g.name: g
    for g in (
        Generator("machines", "python " + MACHINES, _machines, ("scripts/compare_*", *OTHERS, *SEED_FILES)),
        Generator("tutorial-check", f"pkmtol check {SEED}", _check, SEED_FILES, cheap=True),
        Generator("tutorial-mobility", f"pkmtol check <{SEED}, limb 3 passive>", _mobility, SEED_FILES, True),
        Generator("tutorial-errors", f"pkmtol errors {SEED}", _errors, SEED_FILES, cheap=True),
        Generator("tutorial-allocate", f"{ALLOCATE}; {CALIBRATED}; {STUDY}", _allocate, SEED_FILES),
    )
}  # fmt: skip


# --- pages ---------------------------------------------------------------------------------------


def script_parts(gen: Generator) -> tuple[list[str], set[str]]:
    """The parts of this script that make ``gen``'s output, and the pkmtol files it calls directly.

    Starting from ``gen.make``: the source of every function of this script it names, recursively
    (names inside nested functions and comprehensions too), and the ``repr`` of every constant
    (strings, tuples, numbers) it names. A ``pkmtol`` function or class it names contributes the
    source file of its module.
    """
    here = globals()
    parts: dict[str, str] = {}
    files: set[str] = set()

    def names(code: CodeType) -> set[str]:
        found = set(code.co_names)
        for const in code.co_consts:
            if isinstance(const, CodeType):
                found |= names(const)
        return found

    todo = [gen.make]
    while todo:
        fn = todo.pop()
        for name in sorted(names(fn.__code__)):
            if name in parts or name not in here:
                continue
            value = here[name]
            module = getattr(value, "__module__", None) or ""
            if isinstance(value, FunctionType) and value.__module__ == __name__:
                parts[name] = inspect.getsource(value)
                todo.append(value)
            elif isinstance(value, str | tuple | int | float):
                parts[name] = f"{name} = {value!r}"
            elif module.split(".")[0] == "pkmtol":
                parts[name] = module
                files |= module_files([module])
    parts[gen.make.__name__] = inspect.getsource(gen.make)
    return [parts[k] for k in sorted(parts)], files


def recorded_imports() -> dict[str, list[str]]:
    """:data:`IMPORTS`: per generator, the repository files its commands imported (empty if none)."""
    if not IMPORTS.is_file():
        return {}
    return {k: list(v) for k, v in json.loads(IMPORTS.read_text(encoding="utf-8")).items()}


def input_files(gen: Generator, imported: list[str] | None = None) -> list[str]:
    """The files ``gen``'s hash covers: its inputs, its script's pkmtol calls, its commands' imports."""
    files = set(recorded_imports().get(gen.name, []) if imported is None else imported)
    files |= script_parts(gen)[1]
    for pattern in gen.inputs:
        files |= {str(p.relative_to(ROOT)) for p in ROOT.glob(pattern) if p.is_file()}
    return sorted(files)


def inputs_hash(gen: Generator, imported: list[str] | None = None) -> str:
    """SHA-256 (16 hex digits) of what determines ``gen``'s blocks (the module docstring lists it).

    Args:
        gen: The generator.
        imported: The files its commands imported (default: as recorded in :data:`IMPORTS`).
    """
    h = hashlib.sha256(gen.command.encode() + b"\0")
    for part in script_parts(gen)[0]:
        h.update(part.encode() + b"\0")
    for name in input_files(gen, imported):
        path = ROOT / name
        body = path.read_bytes() if path.is_file() else b"<missing>"
        h.update(name.encode() + b"\0" + body + b"\0")
    return h.hexdigest()[:16]


def generator_of(block: str) -> Generator | None:
    """The generator that makes ``block`` (``name`` or ``name-<part>``)."""
    name = block
    while name:
        if name in GENERATORS:
            return GENERATORS[name]
        name = name.rpartition("-")[0]
    return None


def pages() -> list[Path]:
    """The pages that may hold generated blocks: ``docs/*.md`` and ``README.md``."""
    return [*sorted(DOCS.glob("*.md")), ROOT / "README.md"]


def blocks(text: str) -> list[re.Match[str]]:
    return list(BLOCK.finditer(text))


def stale() -> list[str]:
    """``page: block (why)`` for every block that is unknown or whose inputs changed since."""
    out = []
    for page in pages():
        for m in blocks(page.read_text(encoding="utf-8")):
            gen = generator_of(m["name"])
            if gen is None:
                out.append(f"{page.name}: {m['name']} (no such generator)")
            elif m["hash"] != inputs_hash(gen):
                out.append(f"{page.name}: {m['name']} (stale: python scripts/make_docs.py --only {gen.name})")
    return out


def generate(gen: Generator) -> tuple[dict[str, str], list[str]]:
    """``gen``'s blocks, and the repository files its commands imported (measured)."""
    _imported.clear()
    with tempfile.TemporaryDirectory() as tmp:
        made = gen.make(Path(tmp))
    return made, sorted(_imported)


def write(gen: Generator) -> list[str]:
    """Regenerate ``gen``'s blocks in every page, record its imports; returns the ``page: block`` written."""
    made, imported = generate(gen)
    digest = inputs_hash(gen, imported)
    written = []
    for page in pages():
        text = page.read_text(encoding="utf-8")

        def fill(m: re.Match[str], page: Path = page) -> str:
            if m["name"] not in made:
                return m.group(0)
            written.append(f"{page.name}: {m['name']}")
            return f"<!-- generated: {m['name']} inputs={digest} -->\n{made[m['name']]}<!-- end -->"

        new = BLOCK.sub(fill, text)
        if new != text:
            _replace(page, new)
    record = recorded_imports()
    record[gen.name] = imported
    _replace(IMPORTS, json.dumps(dict(sorted(record.items())), indent=1, ensure_ascii=False) + "\n")
    return written


def _replace(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` whole (a temporary file renamed over it)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", action="append", choices=sorted(GENERATORS), help="regenerate only these")
    ap.add_argument("--check", action="store_true", help="list stale blocks (exit 1 if any); runs nothing")
    ap.add_argument("--list", action="store_true", help="list the generators")
    args = ap.parse_args(argv)
    if args.list:
        for gen in GENERATORS.values():
            where = sorted(
                {
                    f"{p.name}"
                    for p in pages()
                    for m in blocks(p.read_text(encoding="utf-8"))
                    if generator_of(m["name"]) is gen
                }
            )
            print(f"{gen.name}{' (cheap)' * gen.cheap}: {gen.command}  [{', '.join(where) or 'no page'}]")
        return 0
    if args.check:
        problems = stale()
        print("\n".join(problems) if problems else "every generated block is current")
        return 1 if problems else 0
    for name in args.only or list(GENERATORS):
        t0 = time.perf_counter()
        done = write(GENERATORS[name])
        print(f"{name}: {', '.join(done) or 'no block in any page'} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
