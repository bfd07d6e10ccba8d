"""The parameter table of ``pkmtol errors``: every error parameter, its class and sensitivity."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from pkmtol.error_model.accuracy import first_max, grid_norm_moments, sensitivities
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.task import grid_sweep, machine_parameter_set
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class ErrorTable:
    """Classes and sensitivities of every parameter of a set.

    Attributes:
        pset: The parameter set.
        classes: ``absorbed`` / ``compensatable`` / ``uncompensatable`` per parameter.
        grid: The task-space sweep.
        worst_index: Grid index with the largest analytic σ[Δλ] (η_c ~ N(0, 1), SI).
        sensitivity: Shape (n,): ``‖J[:, i]‖`` at the worst pose (after compensation) [m/unit].
        sensitivity_uncompensated: Shape (n,): ``‖J_total[:, i]‖`` there (no compensation) [m/unit].
    """

    pset: ParameterSet
    classes: list[str]
    grid: Sweep
    worst_index: int
    sensitivity: np.ndarray
    sensitivity_uncompensated: np.ndarray

    @property
    def worst_point_m(self) -> np.ndarray:
        """Position of P at the worst pose, in K [m]."""
        return self.grid.points_m[self.worst_index]

    def to_json(self) -> str:
        """JSON: one object per parameter (``name``, ``unit``, ``class``, ``sensitivity``)."""
        doc = {
            "parameter_set": self.pset.kind,
            "worst_point_m": self.worst_point_m.tolist(),
            "sensitivity_unit": "m per parameter unit (m or rad), at the worst point, after compensation",
            "parameters": [
                {
                    "name": p.name,
                    "unit": p.unit,
                    "class": c,
                    "sensitivity": float(s),
                    "sensitivity_uncompensated": float(su),
                }
                for p, c, s, su in zip(
                    self.pset.parameters,
                    self.classes,
                    self.sensitivity,
                    self.sensitivity_uncompensated,
                    strict=True,
                )
            ],
        }
        return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def error_table(
    mechanism: Mechanism, kind: str | None = None, chain: ClosedChain | None = None, progress: bool = False
) -> ErrorTable:
    """Classify every parameter over the task-space grid and take sensitivities at the worst pose.

    ``progress`` shows a progress bar over the grid (on stderr).
    """
    if not isinstance(mechanism, Mechanism):
        raise InvalidArgumentError("mechanism", mechanism, "expected a pkmtol.Mechanism (load_mechanism)")
    pset = machine_parameter_set(mechanism, kind)
    grid = grid_sweep(mechanism, pset, chain, progress=progress)
    classes = grid.classify()
    unc = [i for i, c in enumerate(classes) if c == "uncompensatable"]
    cols = unc if unc else list(range(len(pset)))
    maps = grid.J if unc else grid.J_total
    sigma = grid_norm_moments(maps[:, :, cols])[:, 1]
    worst = first_max(sigma)
    sens = np.zeros(len(pset))
    sens[unc] = sensitivities(grid.J[worst][:, unc])
    return ErrorTable(
        pset=pset,
        classes=classes,
        grid=grid,
        worst_index=worst,
        sensitivity=sens,
        sensitivity_uncompensated=sensitivities(grid.J_total[worst]),
    )
