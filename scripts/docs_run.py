"""The runner of scripts/make_docs.py: a command in a fresh process, and what it imported.

:func:`run` runs a command (``pkmtol ...`` or a script) at the repository root with this
worktree's ``src`` first on the path, ``COLUMNS`` set, and ``python -X importtime``; the repository
modules named in that log are collected in :data:`imported` (make_docs hashes their files).
Helpers that cut the printed text are here too.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SEED = "robots/r2rps_ups"
SEED_FILES = (f"{SEED}/*",)


def run(command: str, cwd: Path = ROOT, columns: int = 100) -> tuple[str, float, float]:
    """Run ``command`` (``pkmtol`` → this Python's ``-m pkmtol.cli``): (stdout, wall [s], CPU [s]).

    The process runs with ``-X importtime``; the repository modules it imported are added to
    :data:`imported` (see :func:`generate`).
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
    imported.update(module_files(line.rpartition("|")[2].strip() for line in log))
    entry = ROOT / ("src/pkmtol/cli/__main__.py" if words[0] == "pkmtol" else words[0])
    if entry.is_file():  # run as __main__, so not in the log
        imported.add(str(entry.relative_to(ROOT)))
    if done.returncode not in (0, 1):
        stderr = "\n".join(line for line in done.stderr.splitlines() if not line.startswith("import time:"))
        raise SystemExit(f"make_docs: `{command}` failed ({done.returncode}):\n{stderr}")
    return done.stdout, wall, cpu


#: The repository files imported by the commands run since :func:`generate` began.
imported: set[str] = set()


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
