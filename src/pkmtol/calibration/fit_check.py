"""Whether an identification from real data may be used: converged, and its residuals near the noise.

A calibration that does not fit its data must not become a calibrated machine. :func:`fit_verdict`
looks at an identification's result and, when it is poor, says what is most likely wrong with the
data, in this order:

* every measured coordinate is 0 (an empty export);
* a unit: the measured positions are a power of ten (or 25.4) times the nominal ones;
* every pose measured the same point (the tracker lost the target and kept its last reading);
* a frame offset: a rigid motion of the tracker's frame, added to the machine's model, explains
  the residuals (``--tracker-frame identify`` identifies it);
* outliers by pose: the poses with the largest residuals are named.

A fit is poor when it did not converge, or when its residual RMS after the fit is more than
:data:`RMS_LIMIT` times the stated noise.

>>> FitVerdict(False, "", "", 1e-5, 5e-5).poor
False
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pkmtol.exceptions import CalibrationError

#: A fit whose residual RMS exceeds this many times the stated noise σ_m is poor.
RMS_LIMIT = 5.0
#: Factors between the measured and the nominal positions that point at a unit mistake.
UNIT_FACTORS = {
    1e3: "metres written under [mm] headers",
    1e-3: "millimetres written under [m] headers",
    1e6: "metres written under [µm] headers",
    1e-6: "micrometres written under [m] headers",
    25.4: "inches written under [mm] headers",
    1 / 25.4: "millimetres written under [in] headers",
    10.0: "centimetres written under [mm] headers",
    0.1: "millimetres written under [cm] headers",
}
#: Worst poses named when the residuals point at outliers.
WORST_POSES = 5


class PoorFitError(CalibrationError):
    """A fit of real data did not converge or left residuals above :data:`RMS_LIMIT` × the noise.

    No calibrated machine is written; ``--accept-poor-fit`` writes it anyway (and says so). Kept
    beside its check, not in :mod:`pkmtol.exceptions` (a foundation module at its size limit).

    Attributes:
        path: The measurement file.
        cause: ``not converged``, ``zeros``, ``repeated point``, ``units``, ``frame offset`` or
            ``outliers``.
    """

    def __init__(self, path: Path | str, cause: str, problem: str) -> None:
        self.path = Path(path)
        self.cause = cause
        super().__init__(
            f"{self.path}: {problem}. Nothing was written; give --accept-poor-fit to write the "
            "calibrated machine anyway"
        )


@dataclass(frozen=True)
class FitVerdict:
    """The outcome of :func:`fit_verdict`.

    Attributes:
        poor: True when the fit must not be used (without ``--accept-poor-fit``).
        cause: ``""``, ``not converged``, ``zeros``, ``repeated point``, ``units``, ``frame offset``
            or ``outliers``.
        problem: What is wrong and what to do (one sentence or two; ``""`` when the fit is good).
        rms_after_m: Residual RMS per coordinate after the fit [m].
        limit_m: The largest acceptable RMS (:data:`RMS_LIMIT` × σ_m) [m].
    """

    poor: bool
    cause: str
    problem: str
    rms_after_m: float
    limit_m: float


def fit_verdict(
    converged: bool,
    iterations: int,
    rms_after_m: float,
    noise_m: float,
    residuals_m: np.ndarray,
    measured_m: np.ndarray | None = None,
    residuals_before_m: np.ndarray | None = None,
    H: np.ndarray | None = None,
    scale: np.ndarray | None = None,
    labels: tuple[str, ...] = (),
    lines: np.ndarray | None = None,
) -> FitVerdict:
    """Judge an identification from real data.

    Args:
        converged: Whether the Gauss–Newton iteration converged.
        iterations: Its iterations.
        rms_after_m: Residual RMS per coordinate at the estimate [m].
        noise_m: The stated measurement noise σ_m per coordinate [m].
        residuals_m: Shape (N, ...): residuals at the estimate, first axis the poses [m or rad].
        measured_m: Shape (N, t, 3): measured target positions in K [m] (a tracker; None for
            other instruments: only the outliers are then looked for).
        residuals_before_m: Shape (N, t, 3): measured − nominal [m] (with ``measured_m``).
        H: Shape (3·N·t, p): the identification Jacobian of the controller model's columns (for
            the frame-offset check; None: not checked).
        scale: Shape (p,): its column scales [m or rad].
        labels: The pose labels (for the outliers' names).
        lines: Shape (N,): the file line of each pose.

    Returns:
        The verdict; ``poor`` is False for a converged fit within :data:`RMS_LIMIT` σ_m.
    """
    limit = RMS_LIMIT * float(noise_m)
    rms = float(rms_after_m)
    if converged and np.isfinite(rms) and rms <= limit:
        return FitVerdict(False, "", "", rms, limit)
    head = (
        f"the identification did not converge in {iterations} iterations"
        if not converged
        else "the identification converged"
    ) + f", leaving a residual RMS of {_um(rms)} per coordinate against a tracker noise of {_um(noise_m)}"
    if converged or rms > limit:
        head += f" (the limit is {RMS_LIMIT:g}× the noise, {_um(limit)})"
    cause, why = _diagnosis(rms, limit, residuals_m, measured_m, residuals_before_m, H, scale, labels, lines)
    if not converged and rms <= limit and cause == "outliers":
        cause = "not converged"
    return FitVerdict(True, cause, f"{head}: {why}", rms, limit)


def _diagnosis(
    rms: float,
    limit: float,
    residuals: np.ndarray,
    measured: np.ndarray | None,
    before: np.ndarray | None,
    H: np.ndarray | None,
    scale: np.ndarray | None,
    labels: tuple[str, ...],
    lines: np.ndarray | None,
) -> tuple[str, str]:
    if measured is not None and before is not None:
        M = np.asarray(measured, dtype=float).reshape(-1, 3)
        P = M - np.asarray(before, dtype=float).reshape(-1, 3)  # the nominal positions
        if not np.any(M):
            return "zeros", (
                "every measured coordinate is 0 — the file holds no measurements; check the tracker's export"
            )
        spread_m = float(np.sqrt(np.mean(np.sum((M - M.mean(axis=0)) ** 2, axis=1))))
        spread_p = float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))))
        unit = _unit_factor(M, P)
        if unit is not None:
            factor, what = unit
            return "units", (
                f"the measured positions are about {_ratio(factor)} the nominal ones: {what}? "
                "Correct the unit in the column headers"
            )
        if spread_m <= limit < spread_p:
            return "repeated point", (
                f"every pose measured the same point {_mm3(M.mean(axis=0))}, while the nominal positions "
                f"spread over {_um(spread_p)}: the tracker did not follow the target; re-measure"
            )
        if H is not None and scale is not None:
            shift = _frame_offset(np.asarray(before, dtype=float).reshape(-1), P, H, scale, rms, limit)
            if shift is not None:
                t, angle = shift
                return "frame offset", (
                    f"a rigid offset of the tracker's frame (about {_mm3(t)} and {1e3 * angle:.3g} mrad) "
                    "explains the residuals: the tracker does not read in the base frame K. Give "
                    "--tracker-frame identify to identify its transform with the machine, or register "
                    "the tracker to the base"
                )
    return "outliers", _outliers(residuals, labels, lines)


def _unit_factor(M: np.ndarray, P: np.ndarray) -> tuple[float, str] | None:
    """The unit factor ``f`` with ``M·f ≈ P`` (within 10 %), if the measured ones look scaled."""
    mm_ = float(np.sum(M * M))
    if mm_ <= 0:
        return None
    k = float(np.sum(M * P)) / mm_
    if not np.isfinite(k) or k <= 0:
        return None
    for factor, what in UNIT_FACTORS.items():
        if abs(k / factor - 1.0) < 0.1:
            scaled = float(np.sqrt(np.mean((k * M - P) ** 2)))
            plain = float(np.sqrt(np.mean((M - P) ** 2)))
            if scaled < 0.1 * plain:
                return factor, what
    return None


def _frame_offset(
    before: np.ndarray, P: np.ndarray, H: np.ndarray, scale: np.ndarray, rms: float, limit: float
) -> tuple[np.ndarray, float] | None:
    """``(translation [m], rotation angle [rad])`` of the tracker frame if it explains the residuals.

    Linear least squares of the residuals before the fit on the machine's columns with, and
    without, the six columns of a rigid motion of the measured points (``δp = t + ω × p``).
    """
    n = P.shape[0]
    F = np.zeros((3 * n, 6))
    for k, p in enumerate(P):
        F[3 * k : 3 * k + 3, :3] = np.eye(3)
        F[3 * k : 3 * k + 3, 3:] = -np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    if H.shape[0] != before.size:
        return None
    A = np.hstack([H * scale, F * 1e-3])
    try:
        x, *_ = np.linalg.lstsq(A, before, rcond=1e-10)
        x0, *_ = np.linalg.lstsq(H * scale, before, rcond=1e-10)
    except np.linalg.LinAlgError:
        return None
    with_frame = float(np.sqrt(np.mean((before - A @ x) ** 2)))
    without = float(np.sqrt(np.mean((before - (H * scale) @ x0) ** 2)))
    if with_frame <= max(limit, 0.2 * min(rms, without)):
        xi = 1e-3 * x[-6:]
        return xi[:3], float(np.linalg.norm(xi[3:]))
    return None


def _outliers(residuals: np.ndarray, labels: tuple[str, ...], lines: np.ndarray | None) -> str:
    r = np.asarray(residuals, dtype=float)
    per_pose = np.sqrt(np.sum(r.reshape(r.shape[0], -1) ** 2, axis=1)) if r.size else np.zeros(0)
    worst = np.argsort(-per_pose)[:WORST_POSES]
    names = []
    for k in worst:
        label = labels[k] if k < len(labels) else str(k)
        line = f", line {int(lines[k])}" if lines is not None and k < len(lines) else ""
        names.append(f"'{label}'{line}: {_um(float(per_pose[k]))}")
    return (
        "the model does not fit these poses; the worst (pose: |residual|) are "
        + "; ".join(names)
        + " — re-measure or remove them, or check the commands and the targets of those rows"
    )


def _um(x: float) -> str:
    x = float(x)
    if not np.isfinite(x):
        return f"{x} m"
    return f"{1e6 * x:.4g} µm" if abs(x) < 1e-3 else f"{1e3 * x:.4g} mm"


def _mm3(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{1e3 * v + 0.0:.1f}" for v in p) + ") mm"


def _ratio(factor: float) -> str:
    """``1/1000 of`` for measured values 1000× too small, ``1000×`` for values too large."""
    return f"1/{factor:.4g} of" if factor >= 1 else f"{1 / factor:.4g}×"
