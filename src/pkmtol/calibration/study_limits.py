"""Up-front limits of ``pkmtol calibrate``: the counts of a plan and a study, checked before any work.

As ``allocate --samples`` is (:mod:`pkmtol.design.budget`): the memory that ``--machines``,
``--holdout`` and ``--candidates`` ask for is estimated from the arrays they fill, and a request
above :data:`MEMORY_FRACTION` of the available memory is refused, naming the option whose part is
largest. ``--random-sets`` costs time, not memory (one plan and one prediction each), and is capped
at :data:`MAX_RANDOM_SETS`.

>>> calibration_memory(n=40, values=3, machines=100, holdout=200, candidates=300).total_bytes < 1e8
True
"""

from __future__ import annotations

from dataclasses import dataclass

from pkmtol.exceptions import InvalidArgumentError, ResourceLimitError

#: Share of the available memory a run may plan to use.
MEMORY_FRACTION = 0.8
#: Random plans ``--random-sets`` may compare with (each is a plan and a prediction: ~0.1 s).
MAX_RANDOM_SETS = 1000
#: Study cases (controller models × selections) a study simulates.
CASES = 4
#: Float64 arrays per held-out pose and parameter: its maps (J, the rows of P and of the tilt, the
#: correction and the ideal residual, with the solver's copies).
HOLDOUT_ARRAYS = 24
#: ... per candidate pose, measured value and parameter (H rows, the maps, the scaled copies).
CANDIDATE_ARRAYS = 8
#: Floats kept per machine, held-out pose and case (P error, tilt, the linear prediction, flags).
STUDY_FLOATS = 8


@dataclass(frozen=True)
class CalibrationMemory:
    """The estimate of :func:`calibration_memory` [bytes], by the option that drives each part."""

    holdout_bytes: float
    candidates_bytes: float
    machines_bytes: float

    @property
    def total_bytes(self) -> float:
        """All parts [bytes]."""
        return self.holdout_bytes + self.candidates_bytes + self.machines_bytes


def calibration_memory(
    n: int, values: int, machines: int, holdout: int, candidates: int
) -> CalibrationMemory:
    """Memory of a plan report and a study [bytes], in Python ints (no overflow) made floats.

    Args:
        n: Parameters of the set.
        values: Measured values per pose (3 per tracker target).
        machines: ``--machines``.
        holdout: ``--holdout``.
        candidates: ``--candidates`` (random poses added to the grid pool).
    """
    return CalibrationMemory(
        holdout_bytes=float(8 * HOLDOUT_ARRAYS * int(holdout) * int(n) * 6),
        candidates_bytes=float(8 * CANDIDATE_ARRAYS * int(candidates) * int(values) * int(n)),
        machines_bytes=float(8 * STUDY_FLOATS * CASES * int(machines) * int(holdout)),
    )


def check_calibration_request(
    n: int,
    values: int,
    machines: int,
    holdout: int,
    candidates: int,
    random_sets: int,
    simulate: bool,
    available_bytes: float | None,
) -> CalibrationMemory:
    """Refuse counts that cannot run: negative, too many random sets, or more memory than there is.

    Raises:
        InvalidArgumentError: ``--random-sets`` below 0 or above :data:`MAX_RANDOM_SETS`.
        ResourceLimitError: the estimate exceeds :data:`MEMORY_FRACTION` of ``available_bytes``
            (names the largest part's option, and the most it could be).
    """
    if random_sets < 0 or random_sets > MAX_RANDOM_SETS:
        raise InvalidArgumentError(
            "--random-sets",
            random_sets,
            f"give 0 … {MAX_RANDOM_SETS:,} random plans to compare with (each one is a plan and a "
            "prediction; 10 show the spread)",
        )
    est = calibration_memory(n, values, machines if simulate else 0, holdout, candidates)
    if available_bytes is None or est.total_bytes <= MEMORY_FRACTION * available_bytes:
        return est
    room = MEMORY_FRACTION * available_bytes
    per_study = 8 * STUDY_FLOATS * CASES
    parts = {
        "--holdout": (est.holdout_bytes, holdout, 8 * HOLDOUT_ARRAYS * n * 6 + per_study * machines),
        "--candidates": (est.candidates_bytes, candidates, 8 * CANDIDATE_ARRAYS * values * n),
        "--machines": (est.machines_bytes, machines, per_study * holdout),
    }
    option = max(parts, key=lambda k: parts[k][0])
    part, value, per_unit = parts[option]
    fits = max(int((room - (est.total_bytes - part)) // max(per_unit, 1)), 0)
    raise ResourceLimitError(
        option, value, est.total_bytes, available_bytes, f"give at most about {fits:,} for {option}"
    )
