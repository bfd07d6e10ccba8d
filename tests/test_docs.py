"""The documentation runs: every ```python block of docs/*.md and README.md is executed (the blocks
of one page in order, in one namespace, from the repository root), and a ```text block that follows
a python block directly (only blank lines between) must be exactly what that block prints. The
generated references (docs/cli.md, docs/api.md) are in sync with the code, the generated blocks of
the pages (scripts/make_docs.py) are current, and relative links between the pages point to files
that exist."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import re
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = sorted((REPO / "docs").glob("*.md")) + [REPO / "README.md"]
FENCE = re.compile(r"^```([\w+-]*)[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)


def fenced_blocks(text: str) -> list[tuple[str, str, int, int]]:
    """``(language, body, start, end)`` of every fenced block, in order."""
    return [(m.group(1), m.group(2), m.start(), m.end()) for m in FENCE.finditer(text)]


def python_examples(text: str) -> list[tuple[str, str | None, int]]:
    """Each python block with the text block right after it (its expected output) or None."""
    blocks = fenced_blocks(text)
    out = []
    for k, (lang, body, _start, end) in enumerate(blocks):
        if lang != "python":
            continue
        expected = None
        if k + 1 < len(blocks):
            nlang, nbody, nstart, _ = blocks[k + 1]
            if nlang == "text" and not text[end:nstart].strip():
                expected = nbody
        out.append((body, expected, text.count("\n", 0, end)))
    return out


def load_script(name: str):
    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_fence_parser():
    text = "a\n```python\nprint(1)\n```\n\n```text\n1\n```\n```python\nx = 2\n```\nprose\n```text\nno\n```\n"
    assert python_examples(text) == [("print(1)\n", "1\n", 3), ("x = 2\n", None, 10)]


PYTHON_PAGES = [p for p in PAGES if python_examples(p.read_text(encoding="utf-8"))]


def test_pages_with_python_blocks():
    names = {p.name for p in PYTHON_PAGES}
    assert {"tutorial.md", "closed-loop.md", "mechanism-format.md"} <= names


@pytest.mark.parametrize("page", PYTHON_PAGES, ids=lambda p: p.name)
def test_python_blocks_run_and_print_what_the_page_says(page, monkeypatch):
    monkeypatch.chdir(REPO)
    namespace: dict[str, object] = {"__name__": f"docs_{page.stem}"}
    for code, expected, line in python_examples(page.read_text(encoding="utf-8")):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            exec(compile(code, f"{page.name}:{line}", "exec"), namespace)  # noqa: S102
        if expected is not None:
            assert buf.getvalue() == expected, f"{page.name}, block ending at line {line}"


def test_cli_reference_is_in_sync():
    assert load_script("make_cli_doc").main(["--check"]) == 0


def test_api_reference_is_in_sync():
    assert load_script("make_api_doc").main(["--check"]) == 0


LINK = re.compile(r"\]\(([^)#\s]+)(#[^)]*)?\)")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_relative_links_exist(page):
    text = page.read_text(encoding="utf-8")
    for target, _anchor in LINK.findall(text):
        if "://" in target or target.startswith("mailto:"):
            continue
        assert (page.parent / target).exists(), f"{page.name}: broken link {target}"


def make_docs():
    import sys

    spec = importlib.util.spec_from_file_location("make_docs", REPO / "scripts" / "make_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_docs"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_generated_blocks_are_current():
    # every number in a generated block comes from its command; the block records the hash of
    # that command's inputs (src/pkmtol, the robots, the scripts): changed inputs make it stale
    assert make_docs().stale() == [], "rerun: python scripts/make_docs.py (the --only it names)"


def test_every_generator_has_a_block_and_every_block_a_generator():
    md = make_docs()
    seen = {
        md.generator_of(m["name"]).name
        for page in md.pages()
        for m in md.blocks(page.read_text(encoding="utf-8"))
        if md.generator_of(m["name"]) is not None
    }
    assert seen == set(md.GENERATORS)


def test_a_stale_block_is_detected(tmp_path, monkeypatch):
    md = make_docs()
    page = tmp_path / "page.md"
    page.write_text("x\n<!-- generated: tutorial-check inputs=0000000000000000 -->\nold\n<!-- end -->\n")
    monkeypatch.setattr(md, "pages", lambda: [page])
    want = "page.md: tutorial-check (stale: python scripts/make_docs.py --only tutorial-check)"
    assert md.stale() == [want]


@pytest.mark.parametrize("name", ["tutorial-check", "tutorial-mobility", "tutorial-errors"])
def test_cheap_blocks_regenerate_verbatim(name):
    md = make_docs()
    gen = md.GENERATORS[name]
    assert gen.cheap
    made, _imported = md.generate(gen)
    on_pages = {
        m["name"]: m["body"] for page in md.pages() for m in md.blocks(page.read_text(encoding="utf-8"))
    }
    for block, text in made.items():
        assert on_pages[block] == text, f"{block}: rerun python scripts/make_docs.py --only {name}"


def test_module_names_map_to_the_repository_files_they_load():
    md = make_docs()
    names = ["pkmtol", "pkmtol.units", "pkmtol.cli", "pkmtol.cli.check", "numpy", "compare_machines", "os"]
    assert md.module_files(names) == {
        "src/pkmtol/__init__.py",
        "src/pkmtol/units.py",
        "src/pkmtol/cli/__init__.py",
        "src/pkmtol/cli/check.py",
        "scripts/compare_machines.py",
    }


def test_a_block_hashes_only_the_files_its_command_imported():
    md = make_docs()
    gen = md.GENERATORS["tutorial-check"]
    files = md.input_files(gen)
    # `pkmtol check` loads the checker, not the 3D scene nor the HTML report
    assert {"src/pkmtol/kinematics/check.py", "src/pkmtol/cli/__main__.py"} <= set(files)
    assert "robots/r2rps_ups/mechanism.toml" in files
    assert "src/pkmtol/present/viewer/scene.py" not in files
    assert "src/pkmtol/present/html_report.py" not in files
    # the recorded imports are part of the hash: another list, another hash
    recorded = md.recorded_imports()["tutorial-check"]
    assert md.inputs_hash(gen) == md.inputs_hash(gen, recorded) != md.inputs_hash(gen, recorded[1:])


def test_a_generator_hashes_its_own_code_in_the_script_not_the_others():
    md = make_docs()
    parts, files = md.script_parts(md.GENERATORS["tutorial-check"])
    text = "\n".join(parts)
    assert "def _check(" in text and "def run(" in text and "def fenced(" in text
    assert "def _allocate(" not in text and "def _machines(" not in text
    parts, files = md.script_parts(md.GENERATORS["tutorial-allocate"])
    assert "src/pkmtol/present/terminal.py" in files  # fit_text, called by the script itself
