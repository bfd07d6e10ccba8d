"""Generate (or check) docs/api.md from the docstrings of pkmtol's public API.

The public API is ``pkmtol.__all__`` (the curated top-level names) plus the public names of the
modules in :data:`EXTRA_MODULES` (importable from their module). Each object gets its signature and
its docstring verbatim; classes also their public methods and properties. ``tests/test_docs.py``
runs the ``--check`` mode: change a docstring or the API, then rerun this script.

Usage:
    python scripts/make_api_doc.py          # write docs/api.md
    python scripts/make_api_doc.py --check  # exit 1 if docs/api.md differs from the docstrings
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
import re
import sys
from pathlib import Path
from typing import Any

import pkmtol

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"
#: Modules whose public names are documented besides ``pkmtol.__all__`` (imported from the module).
EXTRA_MODULES = (
    "pkmtol.values",
    "pkmtol.model.keys",
    "pkmtol.model.families",
    "pkmtol.model.robot_files",
    "pkmtol.kinematics.robot_folder",
    "pkmtol.design.budget",
    "pkmtol.present.run_folder",
    "pkmtol.present.outputs",
    "pkmtol.model.sidecar",
    "pkmtol.model.tree_cut",
    "pkmtol.model.tree_limbs",
    "pkmtol.model.closed_loop",
    "pkmtol.model.mjcf",
    "pkmtol.model.mjcf_checks",
    "pkmtol.model.constraints",
    "pkmtol.present.viewer.options",
    "pkmtol.present.viewer.colours",
    "pkmtol.present.viewer.geometry",
    "pkmtol.present.viewer.layers",
    "pkmtol.present.viewer.legend",
    "pkmtol.present.viewer.scene",
    "pkmtol.present.viewer.server",
    "pkmtol.present.viewer.browser",
    "pkmtol.present.viewer.export",
    "pkmtol.model.drawing",
    "pkmtol.design.contributions",
    "pkmtol.design.stackup",
    "pkmtol.design.capability",
    "pkmtol.design.iso286",
    "pkmtol.design.drawing",
    "pkmtol.design.signoff",
    "pkmtol.design.contract",
    "pkmtol.present.report_tables",
    "pkmtol.present.html_report",
    "pkmtol.present.provenance",
    "pkmtol.exceptions",
)
#: Section order: the pipeline (docs/architecture.md), then presentation, then errors.
MODULE_ORDER = (
    "pkmtol.values",
    "pkmtol.model.keys",
    "pkmtol.model.limb",
    "pkmtol.model.mechanism",
    "pkmtol.model.loader",
    "pkmtol.model.sidecar",
    "pkmtol.model.tree_cut",
    "pkmtol.model.tree_limbs",
    "pkmtol.model.closed_loop",
    "pkmtol.model.mjcf",
    "pkmtol.model.mjcf_checks",
    "pkmtol.model.constraints",
    "pkmtol.model.taskspace",
    "pkmtol.model.families",
    "pkmtol.model.robot_files",
    "pkmtol.model.drawing",
    "pkmtol.kinematics.closed_chain",
    "pkmtol.kinematics.perturbation",
    "pkmtol.kinematics.robot_folder",
    "pkmtol.error_model.parameters",
    "pkmtol.error_model.accuracy",
    "pkmtol.error_model.separation",
    "pkmtol.error_model.sweep",
    "pkmtol.error_model.table",
    "pkmtol.design.fosm",
    "pkmtol.design.pose_search",
    "pkmtol.design.verification",
    "pkmtol.design.reliability",
    "pkmtol.design.exact",
    "pkmtol.design.cost",
    "pkmtol.design.budget",
    "pkmtol.design.job",
    "pkmtol.design.contract",
    "pkmtol.design.contributions",
    "pkmtol.design.stackup",
    "pkmtol.design.capability",
    "pkmtol.design.iso286",
    "pkmtol.design.drawing",
    "pkmtol.design.signoff",
    "pkmtol.present.tables",
    "pkmtol.present.outputs",
    "pkmtol.present.run_folder",
    "pkmtol.present.report_tables",
    "pkmtol.present.html_report",
    "pkmtol.present.provenance",
    "pkmtol.present.viewer.options",
    "pkmtol.present.viewer.colours",
    "pkmtol.present.viewer.geometry",
    "pkmtol.present.viewer.layers",
    "pkmtol.present.viewer.legend",
    "pkmtol.present.viewer.scene",
    "pkmtol.present.viewer.server",
    "pkmtol.present.viewer.browser",
    "pkmtol.present.viewer.export",
    "pkmtol.exceptions",
)

INTRO = """\
# API reference

Generated from the docstrings by `scripts/make_api_doc.py` (a test keeps it in sync; do not edit by
hand). Everything is SI (m, rad) unless a name or docstring says otherwise; frames are named in the
docstrings (K: the base frame, K': origin at the platform point O' with K's axes — see the
[glossary](glossary.md)). Results are dataclasses holding numpy arrays.

Names marked `pkmtol.X` are importable from the top-level package (`from pkmtol import X`); the others
from their module. The [tutorial](tutorial.md) shows them at work.
"""


def _annotation(a: Any) -> str:
    if a is inspect.Parameter.empty:
        return ""
    return a if isinstance(a, str) else inspect.formatannotation(a)


def _default(v: Any) -> str:
    text = repr(v)
    if isinstance(v, dataclasses._HAS_DEFAULT_FACTORY_CLASS):  # type: ignore[attr-defined]
        return "<factory>"
    return re.sub(r" at 0x[0-9a-f]+", "", text)


def signature(obj: Any, name: str, is_class: bool = False) -> str:
    """``name(param: annotation = default, ...) -> return`` without the quotes of string annotations."""
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return f"{name}(*args)"
    parts = []
    seen_kw_only = False
    for p in sig.parameters.values():
        if p.kind is p.KEYWORD_ONLY and not seen_kw_only:
            parts.append("*")
            seen_kw_only = True
        prefix = "*" if p.kind is p.VAR_POSITIONAL else "**" if p.kind is p.VAR_KEYWORD else ""
        if p.kind is p.VAR_POSITIONAL:
            seen_kw_only = True
        text = prefix + p.name
        ann = _annotation(p.annotation)
        if ann:
            text += f": {ann}"
        if p.default is not inspect.Parameter.empty:
            text += f" = {_default(p.default)}" if ann else f"={_default(p.default)}"
        parts.append(text)
    ret = _annotation(sig.return_annotation)
    tail = f" -> {ret}" if ret and not is_class else ""
    return f"{name}({', '.join(parts)}){tail}"


def _doc(obj: Any) -> str:
    doc = inspect.getdoc(obj) or "(no docstring)"
    return doc.rstrip()


def _members(cls: type) -> list[tuple[str, Any]]:
    out = []
    for name, value in cls.__dict__.items():
        if name.startswith("_"):
            continue
        if isinstance(value, property | classmethod | staticmethod) or inspect.isfunction(value):
            out.append((name, value))
    return out


def document(obj: Any, qualname: str) -> str:
    """Markdown for one public object."""
    lines = [f"### `{qualname}`", ""]
    if inspect.isclass(obj):
        is_exc = issubclass(obj, BaseException)
        target = obj.__init__ if is_exc and "__init__" in obj.__dict__ else obj
        if is_exc and "__init__" not in obj.__dict__:
            head = f"class {obj.__name__}({obj.__mro__[1].__name__})"
        else:
            head = "class " + signature(target, obj.__name__, is_class=True)
            if is_exc:
                head = head.replace("(self, ", "(", 1)
        body = [head, "", _doc(obj)]
        for name, member in _members(obj):
            if isinstance(member, property):
                body += ["", f"{obj.__name__}.{name}  (property)", _indent(_doc(member.fget))]
            else:
                func = member.__func__ if isinstance(member, classmethod | staticmethod) else member
                sig = signature(func, f"{obj.__name__}.{name}")
                sig = sig.replace("(self, ", "(", 1).replace("(self)", "()", 1).replace("(cls, ", "(", 1)
                kind = "  (classmethod)" if isinstance(member, classmethod) else ""
                body += ["", sig + kind, _indent(_doc(func))]
    else:
        body = [signature(obj, obj.__name__), "", _doc(obj)]
    lines += ["```text", *body, "```", ""]
    return "\n".join(lines)


def _indent(text: str) -> str:
    return "\n".join(("    " + line) if line else "" for line in text.splitlines())


def public_objects() -> dict[str, list[tuple[str, Any]]]:
    """Module name → [(documented name, object)] in source order."""
    by_module: dict[str, list[tuple[str, Any]]] = {}
    for name in pkmtol.__all__:
        obj = getattr(pkmtol, name)
        by_module.setdefault(obj.__module__, []).append((f"pkmtol.{name}", obj))
    top = {id(getattr(pkmtol, n)) for n in pkmtol.__all__}
    for modname in EXTRA_MODULES:
        module = importlib.import_module(modname)
        public = getattr(module, "__all__", None)
        for name, obj in vars(module).items():
            if name.startswith("_") or id(obj) in top or (public is not None and name not in public):
                continue
            if (inspect.isclass(obj) or inspect.isfunction(obj)) and obj.__module__ == modname:
                by_module.setdefault(modname, []).append((f"{modname}.{name}", obj))
    for objs in by_module.values():
        objs.sort(key=lambda item: _source_line(item[1]))
    return by_module


def _source_line(obj: Any) -> int:
    try:
        return inspect.getsourcelines(obj)[1]
    except (OSError, TypeError):
        return 0


def generate() -> str:
    """The text of docs/api.md."""
    by_module = public_objects()
    order = [m for m in MODULE_ORDER if m in by_module] + sorted(set(by_module) - set(MODULE_ORDER))
    parts = [INTRO, "## Contents", ""]
    for modname in order:
        names = ", ".join(f"`{q.rsplit('.', 1)[1]}`" for q, _ in by_module[modname])
        parts.append(f"* [`{modname}`](#{modname.replace('.', '')}): {names}")
    parts.append("")
    for modname in order:
        module = importlib.import_module(modname)
        summary = (inspect.getdoc(module) or "").split("\n\n", 1)[0].replace("\n", " ")
        parts += [f"## {modname}", "", summary, ""]
        parts += [document(obj, qualname) for qualname, obj in by_module[modname]]
    return "\n".join(parts).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare with docs/api.md instead of writing it")
    args = ap.parse_args(argv)
    text = generate()
    if args.check:
        if not DOC.is_file() or DOC.read_text(encoding="utf-8") != text:
            print(
                f"{DOC} is out of date with the docstrings; rerun: python scripts/make_api_doc.py",
                file=sys.stderr,
            )
            return 1
        return 0
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
