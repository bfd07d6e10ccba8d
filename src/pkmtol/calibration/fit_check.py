"""Whether an identification from real data may be used: converged, and its residuals near the noise.

A calibration that does not fit its data must not become a calibrated machine. :func:`fit_verdict`
looks at an identification's result and, when it is poor, says what is most likely wrong with the
data, in this order:

* every measured value is 0 (an empty export);
* a unit: the measured values are a power of ten (or 25.4) times the nominal ones;
* every pose measured the same value (the instrument lost the target and kept its last reading);
* a frame offset: a rigid motion of the tracker's frame, added to the machine's model, explains
  the residuals (``--tracker-frame identify`` identifies it);
* outliers by pose: the poses with the largest residuals are named.

Which of them apply depends on what the instrument measures (``values``): a registered tracker's
positions in K (``points``: all five), a tracker's positions in its own identified frame
(``frame points``: the unit is read from the spread of the points, which a rigid frame keeps; no
frame offset), a ballbar's lengths (``distances``: zeros, unit, the same length everywhere,
outliers), anything else (a probe's touches, a 6-D tracker: outliers).

A fit is poor when it did not converge, or when its residual RMS after the fit is more than
:data:`RMS_LIMIT` times the stated noise. The first three causes do not need the fit:
:func:`data_verdict` finds them from the measured and nominal values alone, so that
``pkmtol calibrate`` refuses such a file before it spends the fit on it.

>>> FitVerdict(False, "", "", 1e-5, 5e-5).poor
False
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pkmtol.exceptions import CalibrationError, InvalidRequestError

#: A fit whose residual RMS exceeds this many times the stated noise σ_m is poor.
RMS_LIMIT = 5.0
#: Factors between the measured and the nominal positions that point at a unit mistake.
UNIT_FACTORS = {
    1e3: "metres written under [mm] headers, or millimetres under [µm]",
    1e-3: "millimetres written under [m] headers, or micrometres under [mm]",
    1e6: "metres written under [µm] headers",
    1e-6: "micrometres written under [m] headers",
    25.4: "inches written under [mm] headers",
    1 / 25.4: "lengths converted from inches to millimetres twice",
    10.0: "centimetres written under [mm] headers",
    0.1: "a decimal point one place off (10× too large)",
}
#: Worst poses named when the residuals point at outliers.
WORST_POSES = 5
#: What an instrument's values are, for the causes that apply (see the module docstring).
VALUE_KINDS = ("points", "frame points", "distances", "")


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
    values: str = "points",
) -> FitVerdict:
    """Judge an identification from real data.

    Args:
        converged: Whether the Gauss–Newton iteration converged.
        iterations: Its iterations.
        rms_after_m: Residual RMS per coordinate at the estimate [m].
        noise_m: The stated measurement noise σ_m per coordinate [m].
        residuals_m: Shape (N, ...): residuals at the estimate, first axis the poses [m or rad].
        measured_m: Shape (N, ...): the measured values, first axis the poses: a tracker's target
            positions (N, t, 3) [m], a ballbar's lengths (N, 1) [m]; None: only the outliers are
            looked for.
        residuals_before_m: Shape of ``measured_m``: measured − nominal [m].
        H: Shape (3·N·t, p): the identification Jacobian of the controller model's columns (for
            the frame-offset check of ``points``; None: not checked).
        scale: Shape (p,): its column scales [m or rad].
        labels: The pose labels (for the outliers' names).
        lines: Shape (N,): the file line of each pose.
        values: What ``measured_m`` holds, one of :data:`VALUE_KINDS` (which causes apply).

    Returns:
        The verdict; ``poor`` is False for a converged fit within :data:`RMS_LIMIT` σ_m.
    """
    limit = RMS_LIMIT * float(noise_m)
    rms = float(rms_after_m)
    per, noise = ("coordinate", " tracker") if "points" in values else ("value", "n instrument")
    if converged and np.isfinite(rms) and rms <= limit:
        return FitVerdict(False, "", "", rms, limit)
    head = (
        f"the identification did not converge in {iterations} iterations"
        if not converged
        else "the identification converged"
    ) + f", leaving a residual RMS of {_um(rms)} per {per} against a{noise} noise of {_um(noise_m)}"
    if converged or rms > limit:
        head += f" (the limit is {RMS_LIMIT:g}× the noise, {_um(limit)})"
    cause, why = "", ""
    if measured_m is not None and residuals_before_m is not None:
        M = np.asarray(measured_m, dtype=float)
        P = M - np.asarray(residuals_before_m, dtype=float)  # the nominal values
        cause, why = _value_causes(M, P, limit, values)
        if not cause and values == "points" and H is not None and scale is not None:
            shift = _frame_offset(
                np.asarray(residuals_before_m, dtype=float).reshape(-1),
                P.reshape(-1, 3),
                H,
                scale,
                rms,
                limit,
            )
            if shift is not None:
                t, angle = shift
                cause, why = (
                    "frame offset",
                    (
                        f"a rigid offset of the tracker's frame (about {_mm3(t)} and {1e3 * angle:.3g} mrad) "
                        "explains the residuals: the tracker does not read in the base frame K. Give "
                        "--tracker-frame identify to identify its transform with the machine, or register "
                        "the tracker to the base"
                    ),
                )
    if not cause:
        cause, why = "outliers", _outliers(residuals_m, labels, lines)
    if not converged and rms <= limit and cause == "outliers":
        cause = "not converged"
    return FitVerdict(True, cause, f"{head}: {why}", rms, limit)


def data_verdict(
    measured: np.ndarray, nominal: np.ndarray, noise_m: float, values: str = "points"
) -> FitVerdict:
    """Judge measured values before any fit: all zero, in the wrong unit, or the same at every pose.

    These data cannot be right whatever the machine's errors are (they are millimetres at most),
    so no fit is needed to refuse them.

    Args:
        measured: Shape (N, ...): the measured values, first axis the poses [m].
        nominal: The same shape: the nominal machine's values at the same commands [m].
        noise_m: The stated noise σ_m per value [m].
        values: What they are, one of :data:`VALUE_KINDS`.

    Returns:
        A poor verdict (``zeros``, ``units`` or ``repeated point``), or a good one: the fit decides.

    >>> p = np.array([[0.1, 0.0, 1.0], [0.0, 0.2, 1.1], [-0.1, 0.0, 0.9]])
    >>> data_verdict(p / 1e3, p, 1e-5).cause
    'units'
    >>> data_verdict(p + 2e-5, p, 1e-5).poor
    False
    """
    limit = RMS_LIMIT * float(noise_m)
    M, P = np.asarray(measured, dtype=float), np.asarray(nominal, dtype=float)
    cause, why = _value_causes(M, P, limit, values)
    if not cause:
        return FitVerdict(False, "", "", float("nan"), limit)
    return FitVerdict(True, cause, f"the data cannot be right, before any fit: {why}", float("nan"), limit)


def _value_causes(M: np.ndarray, P: np.ndarray, limit: float, values: str) -> tuple[str, str]:
    """The cause the measured values ``M`` and the nominal ones ``P`` show by themselves, or ``("", "")``."""
    if values not in VALUE_KINDS:
        raise InvalidRequestError(
            f"values must be one of {', '.join(map(repr, VALUE_KINDS))}, got {values!r}"
        )
    if (
        not values
        or M.size == 0
        or M.shape != P.shape
        or not (np.all(np.isfinite(M)) and np.all(np.isfinite(P)))
    ):
        return "", ""
    what, device = ("length", "ballbar") if values == "distances" else ("coordinate", "tracker")
    if not np.any(M):
        return "zeros", (
            f"every measured {what} is 0 — the file holds no measurements; check the {device}'s export"
        )
    width = 1 if values == "distances" else 3
    Mv, Pv = M.reshape(-1, width), P.reshape(-1, width)
    spread_m = float(np.sqrt(np.mean(np.sum((Mv - Mv.mean(axis=0)) ** 2, axis=1))))
    spread_p = float(np.sqrt(np.mean(np.sum((Pv - Pv.mean(axis=0)) ** 2, axis=1))))
    unit = _frame_unit(Mv, Pv, spread_m, spread_p) if values == "frame points" else _unit_factor(Mv, Pv)
    if unit is not None:
        factor, meaning = unit
        of = {
            "points": "the measured positions are about {} the nominal ones",
            "frame points": "the measured positions spread over about {} what the nominal ones spread over "
            "(a tracker frame moves them, but keeps their distances)",
            "distances": "the measured lengths are about {} the nominal ones",
        }[values].format(_ratio(factor))
        return "units", f"{of}: {meaning}? Correct the unit in the column headers"
    if spread_m <= limit < spread_p:
        seen = _mm3(Mv.mean(axis=0)) if width == 3 else f"{1e3 * float(Mv.mean()):.4g} mm"
        noun = "point" if width == 3 else "length"
        return "repeated point", (
            f"every pose measured the same {noun} {seen}, while the nominal {noun}s spread over "
            f"{_um(spread_p)}: the instrument did not follow the target; re-measure"
        )
    return "", ""


def _frame_unit(M: np.ndarray, P: np.ndarray, spread_m: float, spread_p: float) -> tuple[float, str] | None:
    """The unit factor of points in another (rigid) frame: the ratio of their spreads, if scaling fits."""
    if spread_m <= 0 or spread_p <= 0 or len(M) < 3:
        return None
    k = spread_p / spread_m
    for factor, meaning in UNIT_FACTORS.items():
        if abs(k / factor - 1.0) < 0.1:
            scaled, plain = _rigid_misfit(k * M, P), _rigid_misfit(M, P)
            if scaled < 0.1 * plain:
                return factor, meaning
    return None


def _rigid_misfit(source: np.ndarray, target: np.ndarray) -> float:
    """RMS distance left after the best rigid motion of ``source`` onto ``target`` (Kabsch) [m]."""
    s, t = source - source.mean(axis=0), target - target.mean(axis=0)
    u, _, vt = np.linalg.svd(s.T @ t)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return float(np.sqrt(np.mean(np.sum((s @ R.T - t) ** 2, axis=1))))


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
