"""The last lines of ``pkmtol allocate``: what the design claims and where, and whether its check agrees.

:func:`claim_line` states the claim with its scope ("R ≥ 97.72 % at every one of 147 grid poses
(exact reliability of the linear model)"; a one-pose design says "at the design point only" and
what holds over the task space); :func:`headline_lines` adds a line per verification row that falls
short of the claim beyond its 95 % interval, and a line per option the mode capped.
"""

from __future__ import annotations

from typing import Any

from pkmtol.design.claim import Claim


def _model(c: Claim, calibrated: bool) -> str:
    if c.joint:
        return "joint position and tilt reliability of the linear model, Monte Carlo over fixed draws"
    model = "the linear post-calibration model" if calibrated else "the linear model"
    return f"exact reliability of {model}, Gaussian errors at the σ_i"


def claim_line(c: Claim, calibrated: bool = False) -> str:
    """The claim of a design with its scope, in one line (reliabilities in %)."""
    m = c.reliability.size
    model = _model(c, calibrated)
    if c.toleranced == 0:
        model += "; nothing is left to tolerance: the mode removes every error"
    low = f"min R = {100 * c.min_reliability:.2f} % (grid pose {c.min_pose})"
    if c.scope == "every":
        return (
            f"claim ({c.method}): R ≥ {100 * c.claimed:.2f} % at every one of {m} grid poses ({model}; "
            f"lowest {100 * c.min_reliability:.2f} % at grid pose {c.min_pose})"
        )
    if c.scope == "average":
        return (
            f"claim ({c.method}): R = {100 * c.claimed:.2f} % on average over the {m} grid poses ({model}); "
            f"not at every pose: {low}"
        )
    who = "FOSM, Φ(β)" if c.scope == "fosm" else f"{c.method}, criterion 'worst'"
    return (
        f"claim ({who}): R = {100 * c.claimed:.2f} % at the design point only (grid pose {c.design_pose}); "
        f"over the task space: {low}, mean {100 * c.mean_reliability:.2f} % ({model})"
    )


def headline_lines(r: Any) -> list[str]:
    """The claim line, a line per verification miss and per capped option of a ``DesignResult``."""
    out = []
    for option, asked, used, why in r.option_caps:
        out.append(f"note: {option} {asked} capped at {used} {why}")
    if r.claim is None:
        return out
    out.append(claim_line(r.claim, r.compensation == "calibrated"))
    for miss in r.claim_misses:
        out.append(
            f"VERIFICATION MISSES THE CLAIM: {miss.distribution} errors, {miss.model} model, random "
            f"task-space poses: R = {100 * miss.reliability:.2f} % (95 % CI {100 * miss.interval[0]:.2f}–"
            f"{100 * miss.interval[1]:.2f} %, {miss.samples} samples) < claimed {100 * r.claim.claimed:.2f} %"
            + (
                "; the one-pose FOSM design does not hold over the task space: use --method exact"
                if r.claim.scope in ("fosm", "worst")
                else ""
            )
        )
    return out
