"""Percent contribution of each toleranced error to E[Δλ²] (the HLM / Pareto view of tolerance tools).

With independent zero-mean errors of standard deviation σ_i, P's error at pose k is
``e_k = L_k δ + N_k ν`` and its mean square is exactly

    E[Δλ_k²] = Σ_i ω_{k,i}² σ_i² + σ_m² ‖N_k‖²_F,    ω_{k,i} = ‖L_k[:, i]‖,

so error i's share is ``ω_{k,i}² σ_i² / E[Δλ_k²]`` and, after a calibration, the tracker noise has
its own share. ``L`` is the compensation mode's map (``J`` under ``ideal``, the post-calibration
``L`` under ``calibrated``, ``J_total`` under ``none``). The shares at the design point sum to 100 %;
the worst share of an error is its largest share over the task-space grid (at different poses for
different errors, so those do not sum to 100 %). The same split holds for the tilt Δα of the tool
axis with the tilt maps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.error_model.accuracy import first_max
from pkmtol.exceptions import InvalidRequestError

#: Name of the tracker-noise line.
NOISE = "tracker noise"


@dataclass(frozen=True, eq=False)
class Contributions:
    """Shares of E[Δλ²] (or E[Δα²]) at every grid pose.

    Attributes:
        columns: Shape (n,): parameter indices of the toleranced errors (in the parameter set).
        shares: Shape (m, n): error i's share at pose k (fraction, 0–1).
        noise_share: Shape (m,): the tracker noise's share (0 without a calibration).
        mean_square: Shape (m,): ``E[Δλ²]`` at each pose [m² or rad²].
        design_index: The pose the design-point shares belong to.
    """

    columns: np.ndarray
    shares: np.ndarray
    noise_share: np.ndarray
    mean_square: np.ndarray
    design_index: int

    @property
    def at_design(self) -> np.ndarray:
        """Shape (n,): each error's share at the design point."""
        return self.shares[self.design_index]

    @property
    def noise_at_design(self) -> float:
        """The noise's share at the design point."""
        return float(self.noise_share[self.design_index])

    @property
    def worst(self) -> np.ndarray:
        """Shape (n,): each error's largest share over the grid."""
        return self.shares.max(axis=0) if len(self.shares) else np.zeros(self.columns.size)

    @property
    def worst_pose(self) -> np.ndarray:
        """Shape (n,): the grid pose of each error's largest share."""
        if not len(self.shares):
            return np.zeros(self.columns.size, dtype=int)
        # the first of poses tied to round-off (symmetric mechanisms), not the last bit's pick
        return np.array([first_max(self.shares[:, j]) for j in range(self.shares.shape[1])], dtype=int)

    def order(self) -> np.ndarray:
        """Positions into ``columns``, largest share at the design point first (Pareto order).

        Shares equal to 1e-9 (FOSM's equal effect makes them equal) are ordered by worst share.
        """
        return np.lexsort((-self.worst, -np.round(self.at_design, 9)))


def contributions(
    L: np.ndarray,
    sigma: np.ndarray,
    columns: np.ndarray,
    design_index: int,
    noise: np.ndarray | None = None,
    noise_sigma: float = 0.0,
) -> Contributions:
    """Shares of E[‖L_k δ + N_k ν‖²] of each toleranced error and of the noise at every pose.

    Args:
        L: Shape (m, 3, n_params): the mode's map per pose (all parameters).
        sigma: Shape (n_params,): the errors' standard deviations (SI; a non-finite σ counts as 0).
        columns: The toleranced parameters.
        design_index: The design point's pose.
        noise: Shape (m, 3, M): the noise map (None or M = 0: no noise).
        noise_sigma: σ_m of each noise coordinate.

    Raises:
        InvalidRequestError: shapes that do not match, or a design index outside the grid.
    """
    L = np.asarray(L, dtype=float)
    cols = np.asarray(columns, dtype=int)
    s = np.asarray(sigma, dtype=float)
    if L.ndim != 3 or s.shape != (L.shape[2],):
        raise InvalidRequestError(f"need L of shape (m, 3, n) and σ of shape (n,), got {L.shape}, {s.shape}")
    if not 0 <= design_index < L.shape[0]:
        raise InvalidRequestError(f"design index {design_index} is outside the {L.shape[0]} poses")
    s = np.where(np.isfinite(s), s, 0.0)
    var = (np.linalg.norm(L[:, :, cols], axis=1) * s[cols][None, :]) ** 2  # (m, n)
    nv = np.zeros(L.shape[0])
    if noise is not None and noise.shape[2] and noise_sigma > 0:
        nv = noise_sigma**2 * np.sum(np.asarray(noise, dtype=float) ** 2, axis=(1, 2))
    total = var.sum(axis=1) + nv
    safe = np.where(total > 0, total, 1.0)
    return Contributions(
        columns=cols,
        shares=var / safe[:, None],
        noise_share=nv / safe,
        mean_square=total,
        design_index=int(design_index),
    )
