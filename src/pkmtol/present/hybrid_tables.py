"""A hybrid machine's report: its tolerances grouped by sub-assembly (module, wrist, tool).

For a mechanism with a tool chain (docs/hybrid.md), :func:`sub_assembly_lines` adds to the
allocation report one row per sub-assembly: how many of its errors are toleranced, the tightest
tolerance of each unit, and the sub-assembly's share of the variance of Δλ at the design point
for the design-β tolerances (the shares of the parameters, summed); then the toleranced errors
themselves, sub-assembly by sub-assembly.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from pkmtol.error_model.tool_chain import SUB_ASSEMBLIES, HybridParameterSet
from pkmtol.units import display, display_unit


def sub_assemblies(r: Any) -> list[str] | None:
    """The sub-assembly of every parameter of a hybrid's design (None for a parallel module)."""
    pset = r.pset
    if not isinstance(pset, HybridParameterSet):
        return None
    return [pset.sub_assembly(i) for i in range(len(pset))]


def hybrid_ideal_text(r: Any) -> str | None:
    """What the ``ideal`` mode means on a hybrid (its compensation scope), None for a parallel module."""
    sweep_ = r.grid
    scope = getattr(sweep_, "scope", None)
    if scope is None or r.mechanism.tool is None:
        return None
    if scope == "module":
        return "the module's Eq. 25 carried to the TCP, the wrist's commands held (--compensate-with module)"
    return (
        "every actuator, the module's and the wrist's, removes what it can of each error's task error at "
        "the TCP (the controller knows the compensatable errors exactly; docs/hybrid.md)"
    )


def sub_assembly_lines(
    r: Any, table: Callable[[list[list[str]]], str], h: Callable[[str], str], units: str = "mm"
) -> list[str]:
    """The report's section "Tolerances by sub-assembly" (empty for a parallel module).

    Args:
        r: The :class:`~pkmtol.design.job.DesignResult`.
        table: The table renderer (terminal text or Markdown).
        h: The section-heading renderer.
        units: ``mm`` or ``um`` for the tolerances.
    """
    groups = sub_assemblies(r)
    if groups is None:
        return []
    col = r.design_column
    unc = [int(i) for i in r.uncompensatable]
    sigma = r.tolerances[:, col]
    finite = [i for i in unc if np.isfinite(sigma[i])]
    w = r.worst_index
    variance = {i: float(np.sum((r.maps.position[w][:, i] * sigma[i]) ** 2)) for i in finite}
    total = sum(variance.values())
    rows = [
        ["sub-assembly", "errors", "toleranced", "tightest length", "tightest angle", "share of σ²[Δλ] [%]"]
    ]
    for g in SUB_ASSEMBLIES:
        members = [i for i, x in enumerate(groups) if x == g]
        tol = [i for i in finite if groups[i] == g]
        tight = {}
        for unit in ("m", "rad"):
            values = [sigma[i] for i in tol if r.pset.parameters[i].unit == unit]
            tight[unit] = (
                f"±{display(min(values), unit, units):.4f} {display_unit(unit, units)}" if values else "-"
            )
        share = f"{100.0 * sum(variance[i] for i in tol) / total:.1f}" if total > 0 else "-"
        rows.append([g, str(len(members)), str(len(tol)), tight["m"], tight["rad"], share])
    detail = [["sub-assembly", "parameter", "unit", f"β={r.design_beta:g}"]]
    for g in SUB_ASSEMBLIES:
        for i in (i for i in unc if groups[i] == g):
            p = r.pset.parameters[i]
            t = sigma[i]
            cell = f"±{display(t, p.unit, units):.4f}" if np.isfinite(t) else "+inf"
            detail.append([g, p.name, display_unit(p.unit, units), cell])
    return [
        h("Tolerances by sub-assembly (module, wrist, tool)"),
        f"design β = {r.design_beta:g}; shares of the variance of Δλ at the design point (TCP, pose {w})"
        + ("" if total > 0 else ": no toleranced parameter (the mode removes every error)"),
        "",
        table(rows),
        "",
        table(detail),
    ]
