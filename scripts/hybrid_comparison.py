"""The tables of docs/hybrid.md from the allocation.json files of the runs the page lists.

Usage:
    python scripts/hybrid_comparison.py OUT   # OUT: module/, wmod/, wlock/, wmach/ (pkmtol allocate --out)

Prints, as Markdown: (1) the module's uncompensatable errors (the paper's Table IV set) with their
β = design tolerance in each run: the module alone at P, the whole machine at the TCP with the
module's compensation (the wrist's commands unchanged), with the wrist locked (3-axis work) and
with every actuator compensating; (2) the wrist's and the tool's errors of the module-compensation
run: sensitivity of the TCP at the design point, tolerance, share of σ²[Δλ] there.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

RUNS = {
    "module": "module alone, at P",
    "wmod": "whole machine, module compensates",
    "wmod_tilt": "the same, Δα* = 0.1 mrad",
    "wlock": "wrist locked (3-axis)",
    "wmach": "whole machine, all actuators",
}


def _load(out: Path, run: str) -> dict:
    return json.loads((out / run / "allocation.json").read_text(encoding="utf-8"))


def _tolerance(p: dict, col: int) -> float | None:
    """The design-β tolerance [SI] of a toleranced parameter, None if it is not toleranced."""
    if p["class_in_mode"] != "uncompensatable" or p["tolerance"] is None:
        return None
    t = p["tolerance"][col]
    return float("inf") if t is None else float(t)


def _cell(t: float | None, unit: str) -> str:
    if t is None:
        return "compensated"
    if t == float("inf"):
        return "+inf"
    return f"±{t * 1e3:.4f}"


def main(argv: list[str]) -> int:
    out = Path(argv[0])
    docs = {run: _load(out, run) for run in RUNS}
    col = docs["module"]["beta"].index(docs["module"]["design_beta"])
    by_name = {run: {p["name"]: p for p in d["parameters"]} for run, d in docs.items()}
    module_unc = [p for p in docs["module"]["parameters"] if p["class"] == "uncompensatable"]
    print("| parameter | unit | " + " | ".join(RUNS.values()) + " | locked / module compensates |")
    print("|---|---|" + "---|" * (len(RUNS) + 1))
    for p in module_unc:
        unit = "mm" if p["unit"] == "m" else "mrad"
        cells = [_cell(_tolerance(by_name[run][p["name"]], col), p["unit"]) for run in RUNS]
        lock, mod = (_tolerance(by_name[run][p["name"]], col) for run in ("wlock", "wmod"))
        finite = lock is not None and mod is not None and lock != float("inf") and mod != float("inf")
        ratio = f"{lock / mod:.1f}×" if finite else "-"  # type: ignore[operator]
        print(f"| {p['name']} | {unit} | " + " | ".join(cells) + f" | {ratio} |")
    counts = {
        run: sum(1 for p in d["parameters"] if p["class_in_mode"] == "uncompensatable")
        for run, d in docs.items()
    }
    print()
    print("toleranced errors per run: " + ", ".join(f"{RUNS[r]} {n}" for r, n in counts.items()))
    print()
    wmod = docs["wmod"]
    tool = [p for p in wmod["parameters"] if p.get("sub_assembly") in ("wrist", "tool")]
    rows = []
    total = 0.0
    for p in wmod["parameters"]:
        t = _tolerance(p, col)
        if t is not None and t != float("inf"):
            total += (p["sensitivity"] * t) ** 2
    for p in tool:
        t = _tolerance(p, col)
        share = 0.0 if t in (None, float("inf")) else 100 * (p["sensitivity"] * t) ** 2 / total
        unit = "µm/µm" if p["unit"] == "m" else "µm/µrad"
        rows.append((share, p, t, unit))
    print("| sub-assembly | parameter | TCP sensitivity at the design point | tolerance (design β) |")
    print("|---|---|---|---|")
    for _share, p, t, unit in sorted(rows, key=lambda r: (r[3], -r[1]["sensitivity"])):
        tol = (
            _cell(t, p["unit"]) + (" mm" if p["unit"] == "m" else " mrad")
            if t is not None
            else p["class_in_mode"]
        )
        print(f"| {p['sub_assembly']} | {p['name']} | {p['sensitivity']:.4f} {unit} | {tol} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
