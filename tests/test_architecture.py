"""The package's layout (docs/architecture.md): no import circles, no private names across modules,
stages import only downward, modules small and each with a one-line docstring."""

from __future__ import annotations

import ast
import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "pkmtol"
#: The stages, bottom to top: a module may import its own stage and the ones below it.
STAGES = ("model", "kinematics", "error_model", "calibration", "design", "present")
#: Top-level modules every stage may use (they import nothing of the stages).
FOUNDATION = ("exceptions", "warning_types", "units", "files", "statistics", "values", "executor")
MAX_LINES = 600


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(path: Path, modules: dict[str, Path]) -> list[tuple[str, list[str], int]]:
    """``(module imported, names taken from it, line)`` for every pkmtol import, at any depth."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "pkmtol":
            names = [a.name for a in node.names]
            # `from pkmtol.x import y` where y is itself a module imports that module
            for n in names:
                if f"{node.module}.{n}" in modules:
                    out.append((f"{node.module}.{n}", [], node.lineno))
            out.append((node.module, [n for n in names if f"{node.module}.{n}" not in modules], node.lineno))
        elif isinstance(node, ast.Import):
            out.extend((a.name, [], node.lineno) for a in node.names if a.name.split(".")[0] == "pkmtol")
    return out


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for mod, path in modules.items():
        for target, _, _ in _imports(path, modules):
            if target in modules and target != mod:
                graph[mod].add(target)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (module → modules it imports), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_cycle_finder_finds_a_planted_circle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_circle_in_src():
    # the package's __init__ re-exports everything: it is a face, not a stage, and is left out
    graph = {m: {t for t in ts if t != "pkmtol"} for m, ts in _graph().items() if m != "pkmtol"}
    assert find_cycle(graph) is None


def _stage(module: str) -> int | None:
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in STAGES:
        return STAGES.index(parts[1])
    return None


def test_stages_import_only_their_own_stage_and_the_ones_below():
    bad = []
    for mod, targets in _graph().items():
        here = _stage(mod)
        if here is None:
            continue
        for t in targets:
            there = _stage(t)
            if t == "pkmtol" or (there is not None and there > here):
                bad.append(f"{mod} -> {t}")
            if there is None and t.split(".")[1] not in FOUNDATION:
                bad.append(f"{mod} -> {t} (not a foundation module)")
    assert not bad, "\n".join(bad)


def test_foundation_modules_import_no_stage():
    graph = _graph()
    for name in FOUNDATION:
        assert all(_stage(t) is None and t != "pkmtol" for t in graph[f"pkmtol.{name}"]), name


def test_no_module_imports_another_modules_private_names():
    modules = _modules()
    bad = []
    for path in modules.values():
        for target, names, line in _imports(path, modules):
            bad += [
                f"{path.relative_to(SRC)}:{line}: {target}.{n}"
                for n in names
                if n.startswith("_") and not n.endswith("__")
            ]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_module_is_small_and_says_what_it_holds(path):
    text = path.read_text(encoding="utf-8")
    assert text.count("\n") <= MAX_LINES, f"{path.name}: {text.count(chr(10))} lines > {MAX_LINES}"
    doc = ast.get_docstring(ast.parse(text))
    assert doc, f"{path.name} has no module docstring"
    assert len(doc.splitlines()[0]) > 20, f"{path.name}: the docstring's first line says too little"


def test_the_package_face_imports_lazily_and_exports_what_it_lists():
    import pkmtol

    assert list(pkmtol.__all__) == sorted(pkmtol.__all__)
    assert set(pkmtol.__all__) == set(pkmtol._EXPORTS)
    for name in pkmtol.__all__:
        value = getattr(pkmtol, name)
        assert getattr(importlib.import_module(pkmtol._EXPORTS[name]), name) is value
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        pkmtol.nothing_here  # noqa: B018


def test_import_pkmtol_loads_no_stage():
    heavy = "('pkmtol.', 'numpy', 'scipy', 'pinocchio')"
    code = f"import sys, pkmtol; print(sorted(m for m in sys.modules if m.startswith({heavy})))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_allocate_command_runs_without_scipy_optimize(tmp_path):
    # the sign-off's quantile column found its roots with scipy.optimize.brentq, whose import cost
    # a sixth of the command's CPU; its safeguarded Newton needs none of it
    code = (
        "import sys; from pkmtol.cli import main; "
        f"main(['allocate', {str(SRC.parent / 'robots' / 'r2rps_ups')!r}, '--no-figures', '--no-progress', "
        f"'--samples', '20000', '--exact-samples', '0', '--out', {str(tmp_path)!r}]); "
        "print(sorted(m for m in ('scipy.stats', 'scipy.optimize', 'scipy.integrate') if m in sys.modules))"
    )
    env = {**os.environ, "PKMTOL_JIT": "0"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.strip().splitlines()[-1] == "[]"
    assert (tmp_path / "allocation.json").is_file()


def test_the_allocate_command_starts_without_the_optional_scipy_packages():
    # scipy.stats, .optimize and .integrate cost most of a second of start-up on the CI VM; only the
    # exact and cost designs, the quantile column and some checks need them, and import them there
    code = (
        "import sys, pkmtol.cli.allocate, pkmtol.design.job, pkmtol.present.outputs; "
        "print(sorted(m for m in ('scipy.stats', 'scipy.optimize', 'scipy.integrate') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
