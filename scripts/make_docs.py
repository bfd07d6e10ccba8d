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
import re
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import CodeType, FunctionType

sys.path.insert(0, str(Path(__file__).resolve().parent))  # its neighbours, also when loaded by a test

import docs_run  # noqa: E402
from docs_run import ROOT, SEED, SEED_FILES, module_files  # noqa: E402
from docs_scripts import (  # noqa: E402
    COMPENSATION_SHOWN,
    FIGAROH_SHOWN,
    HYBRID_SHOWN,
    ROBOT_FILES,
    SWEEP,
    _compensation,
    _figaroh,
    _hybrid,
    _robots,
    _scale,
)
from docs_seed import COST, FOSM, SIMULATE, _cost, _fosm, _simulate  # noqa: E402
from docs_tutorial import (  # noqa: E402
    ALLOCATE,
    CALIBRATED,
    MACHINES,
    OTHERS,
    STUDY,
    _allocate,
    _check,
    _errors,
    _machines,
    _mobility,
)

DOCS = ROOT / "docs"
SCRIPTS = ROOT / "scripts"
#: Per generator, the repository files (``src/pkmtol/...``, ``scripts/...``) its commands imported.
IMPORTS = DOCS / "data" / "generated_inputs.json"
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
        inputs: Files (globs relative to the repository) it reads besides the modules its
            commands import (measured).
        cheap: Fast enough (a few seconds) for the docs test to regenerate and compare.
    """

    name: str
    command: str
    make: Callable[[Path], dict[str, str]]
    inputs: tuple[str, ...]
    cheap: bool = False


GENERATORS = {
    g.name: g
    for g in (
        Generator("machines", "python " + MACHINES, _machines, ("scripts/compare_*", *OTHERS, *SEED_FILES)),
        Generator("tutorial-check", f"pkmtol check {SEED}", _check, SEED_FILES, cheap=True),
        Generator("tutorial-mobility", f"pkmtol check <{SEED}, limb 3 passive>", _mobility, SEED_FILES, True),
        Generator("tutorial-errors", f"pkmtol errors {SEED}", _errors, SEED_FILES, cheap=True),
        Generator("tutorial-allocate", f"{ALLOCATE}; {CALIBRATED}; {STUDY}", _allocate, SEED_FILES),
        Generator("seed-fosm", FOSM, _fosm, SEED_FILES),
        Generator("seed-cost", COST, _cost, SEED_FILES),
        Generator("seed-simulate", SIMULATE, _simulate, SEED_FILES),
        Generator("compensation", COMPENSATION_SHOWN, _compensation, SEED_FILES),
        Generator("figaroh", FIGAROH_SHOWN, _figaroh, SEED_FILES),
        Generator("scale", f"{SWEEP} [--workers 2]", _scale, SEED_FILES),
        Generator("hybrid", HYBRID_SHOWN, _hybrid, (*SEED_FILES, "robots/r2rps_ups_wrist/*")),
        Generator("robots", "pkmtol check|errors robots/<robot>", _robots, ROBOT_FILES),
    )
}  # fmt: skip


# --- pages ---------------------------------------------------------------------------------------


def script_parts(gen: Generator) -> tuple[list[str], set[str]]:
    """The parts of the scripts that make ``gen``'s output, and the pkmtol files they call directly.

    Starting from ``gen.make``: the source of every function of a ``scripts/`` module it names,
    recursively (names inside nested functions and comprehensions too, each looked up in its own
    module), and the ``repr`` of every constant (strings, tuples, numbers) it names. A ``pkmtol``
    function or class it names contributes the source file of its module.
    """
    parts: dict[str, str] = {}
    files: set[str] = set()

    def names(code: CodeType) -> set[str]:
        found = set(code.co_names)
        for const in code.co_consts:
            if isinstance(const, CodeType):
                found |= names(const)
        return found

    def ours(fn: FunctionType) -> bool:
        return Path(inspect.getfile(fn)).resolve().parent == SCRIPTS

    todo: list[FunctionType] = [gen.make]  # type: ignore[list-item]
    parts[f"{gen.make.__module__}.{gen.make.__name__}"] = inspect.getsource(gen.make)
    while todo:
        fn = todo.pop()
        here = fn.__globals__
        for name in sorted(names(fn.__code__)):
            if name not in here:
                continue
            value = here[name]
            key = f"{here['__name__']}.{name}"
            module = getattr(value, "__module__", None) or ""
            if isinstance(value, FunctionType) and ours(value):
                key = f"{value.__module__}.{value.__name__}"
                if key not in parts:
                    parts[key] = inspect.getsource(value)
                    todo.append(value)
            elif isinstance(value, str | tuple | int | float):
                parts[key] = f"{name} = {value!r}"
            elif module.split(".")[0] == "pkmtol":
                files |= module_files([module])
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
    docs_run.imported.clear()
    with tempfile.TemporaryDirectory() as tmp:
        made = gen.make(Path(tmp))
    return made, sorted(docs_run.imported)


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
