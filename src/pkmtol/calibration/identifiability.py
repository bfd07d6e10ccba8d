"""Identifiability of a controller model from a measurement plan: base parameters by pivoted QR.

The identification Jacobian ``H_id`` (rows: measured target coordinates at the calibration poses;
columns: the controller model's parameters) is scaled column by column by each parameter's
expected size ``s_i`` (its manufacturing σ or tolerance), so that lengths and angles compare. A
QR decomposition with column pivoting, ``H_id S P = Q R``, orders the columns by how much new
information each brings; the first ``r`` (``|R_ii| > tol · |R_00|``) are the **base parameters**
``δ_B``, the others ``δ_D`` are (to that tolerance) combinations of them:
``H_D = H_B K'`` with ``K' = S_B R₁₁⁻¹ R₁₂ S_D⁻¹``. The measurements then determine exactly
``β = δ_B + K' δ_D``; any change ``δ_D = e_j, δ_B = −K'_{:,j}`` is invisible.

The set is fixed once, at the nominal point, and kept through the iterations of the
identification (DESIGN.md, "Pitfalls"): away from the nominal parameters, directions that are
structurally unobservable become faintly observable and would make Gauss–Newton diverge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from pkmtol.exceptions import InvalidRequestError

#: Default rank tolerance: a direction is identifiable when its ``|R_ii|`` is above this fraction
#: of the largest (scaled columns). docs/calibration.md gives the gap it falls in.
RANK_TOLERANCE = 1e-6
#: Estimates correlated above this ``|ρ|`` are reported.
CORRELATION_LIMIT = 0.9
#: Entries of ``K'`` below this size (relative to the parameters' scales) are not written out.
COMBINATION_CUTOFF = 1e-9


@dataclass(frozen=True, eq=False)
class Identifiability:
    """What a plan's measurements determine of the controller model (``p`` parameters, rank ``r``).

    Attributes:
        columns: Shape (p,): indices (into the parameter set) of the controller model's parameters.
        names: Their names.
        units: Their units (``m`` or ``rad``).
        scale: Shape (p,): column scales ``s_i`` [m or rad] (expected size of each parameter).
        base: Shape (r,): positions in ``columns`` of the base parameters, in pivot order.
        dependent: Shape (p − r,): positions in ``columns`` of the others.
        combination: Shape (r, p − r): ``K'``; the identified quantities are
            ``β = δ_B + K' δ_D`` (SI).
        pivots: Shape (p,): ``|R_ii| / |R_00|`` in pivot order (the first ``r`` are kept).
        singular_values: Shape (r,): singular values of the scaled base Jacobian ``H_B S_B``
            (descending) [m per unit of scaled parameter].
        rank_tolerance: The tolerance that chose ``r``.
        poses: Number of calibration poses ``N``.
        rows: Number of measured coordinates (rows of ``H``).
        noise_m: Measurement noise σ_m per coordinate [m].
        covariance: Shape (r, r): ``σ_m² (H_Bᵀ H_B)⁻¹`` of the base estimate [SI²].
        correlated: Pairs ``(name_i, name_j, ρ)`` of base estimates with ``|ρ| > 0.9``.
    """

    columns: np.ndarray
    names: tuple[str, ...]
    units: tuple[str, ...]
    scale: np.ndarray
    base: np.ndarray
    dependent: np.ndarray
    combination: np.ndarray
    pivots: np.ndarray
    singular_values: np.ndarray
    rank_tolerance: float
    poses: int
    rows: int
    noise_m: float
    covariance: np.ndarray
    correlated: tuple[tuple[str, str, float], ...]

    @property
    def rank(self) -> int:
        """Number of identifiable combinations ``r``."""
        return int(self.base.size)

    @property
    def condition(self) -> float:
        """Condition number of the scaled base Jacobian (σ₁/σ_r)."""
        s = self.singular_values
        return float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")

    @property
    def observability(self) -> float:
        """Observability index O1 = (σ₁ ⋯ σ_r)^{1/r} / √N (Borm and Menq) of the scaled base Jacobian."""
        s = self.singular_values
        if not s.size or s[-1] <= 0:
            return 0.0
        return float(np.exp(np.mean(np.log(s))) / np.sqrt(self.poses))

    @property
    def base_columns(self) -> np.ndarray:
        """Indices (into the parameter set) of the base parameters, shape (r,)."""
        return self.columns[self.base]

    @property
    def base_names(self) -> list[str]:
        """Names of the base parameters, in pivot order."""
        return [self.names[i] for i in self.base]

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each base estimate, shape (r,) [SI]."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def identified_combinations(self) -> list[str]:
        """Each base quantity ``β_i = δ_Bi + Σ_j K'_ij δ_Dj``, in parameter names (one string each)."""
        out = []
        for i, b in enumerate(self.base):
            terms = [self.names[b]]
            for j, d in enumerate(self.dependent):
                k = self.combination[i, j]
                if abs(k) * self.scale[d] > COMBINATION_CUTOFF * self.scale[b]:
                    terms.append(f"{k:+.6g}·{self.names[d]}")
            out.append(" ".join(terms))
        return out

    def unidentifiable_combinations(self) -> list[str]:
        """Each invisible direction ``δ_Dj − Σ_i K'_ij δ_Bi`` in parameter names (one string each)."""
        out = []
        for j, d in enumerate(self.dependent):
            terms = [self.names[d]]
            for i, b in enumerate(self.base):
                k = -self.combination[i, j]
                if abs(k) * self.scale[b] > COMBINATION_CUTOFF * self.scale[d]:
                    terms.append(f"{k:+.6g}·{self.names[b]}")
            out.append(" ".join(terms))
        return out

    def true_base_values(self, delta: np.ndarray) -> np.ndarray:
        """``β = δ_B + K' δ_D`` of a full parameter vector ``delta`` (n,) [SI], shape (r,)."""
        sel = np.asarray(delta, dtype=float)[self.columns]
        return sel[self.base] + self.combination @ sel[self.dependent]

    def expand(self, base_values: np.ndarray, n: int) -> np.ndarray:
        """A full parameter vector (n,) with ``δ_B = base_values`` and every other entry 0."""
        out = np.zeros(n)
        out[self.base_columns] = base_values
        return out


def identifiability(
    H: np.ndarray,
    columns: np.ndarray,
    names: list[str],
    units: list[str],
    scale: np.ndarray,
    poses: int,
    noise_m: float,
    rank_tolerance: float = RANK_TOLERANCE,
) -> Identifiability:
    """Base parameters of the columns ``columns`` of the identification Jacobian ``H``.

    Args:
        H: Shape (rows, n): measured coordinates per unit parameter, every parameter of the set.
        columns: Shape (p,): the controller model's parameters (indices into the set).
        names: Names of all ``n`` parameters.
        units: Units of all ``n`` parameters.
        scale: Shape (n,): expected size of each parameter [m or rad] (column scaling).
        poses: Number of calibration poses.
        noise_m: σ_m per measured coordinate [m] (for the covariance).
        rank_tolerance: Relative ``|R_ii|`` below which a direction counts as unidentifiable.

    Raises:
        InvalidRequestError: no parameter to identify, or fewer measured coordinates than the rank.
    """
    cols = np.asarray(columns, dtype=int)
    if cols.size == 0:
        raise InvalidRequestError("the controller model has no parameter to identify; choose another set")
    if not 0 < rank_tolerance < 1:
        raise InvalidRequestError(f"the rank tolerance must be in (0, 1), got {rank_tolerance:g}")
    s = np.asarray(scale, dtype=float)[cols]
    Hs = H[:, cols] * s[None, :]
    _, R, piv = linalg.qr(Hs, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    top = diag[0] if diag.size and diag[0] > 0 else 1.0
    pivots = np.zeros(cols.size)
    pivots[: diag.size] = diag / top
    r = int(np.sum(pivots > rank_tolerance))
    if r == 0:
        raise InvalidRequestError("the measurements see none of the controller model's parameters")
    if H.shape[0] < r:  # pragma: no cover - QR's rank cannot exceed the rows
        raise InvalidRequestError(f"{H.shape[0]} measured coordinates for {r} identifiable combinations")
    base, dep = piv[:r], piv[r:]
    k_scaled = linalg.solve_triangular(R[:r, :r], R[:r, r:]) if dep.size else np.zeros((r, 0))
    combination = s[base][:, None] * k_scaled / s[dep][None, :]
    Hb = H[:, cols[base]]
    sv = linalg.svd(Hs[:, base], compute_uv=False)
    info = Hb.T @ Hb
    cov = noise_m**2 * linalg.pinvh(info)
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    rho = cov / np.outer(sd, sd)
    pairs = []
    for i in range(r):
        for j in range(i + 1, r):
            if abs(rho[i, j]) > CORRELATION_LIMIT:
                pairs.append((names[cols[base[i]]], names[cols[base[j]]], float(rho[i, j])))
    return Identifiability(
        columns=cols,
        names=tuple(names[c] for c in cols),
        units=tuple(units[c] for c in cols),
        scale=s,
        base=base,
        dependent=dep,
        combination=combination,
        pivots=pivots,
        singular_values=sv,
        rank_tolerance=float(rank_tolerance),
        poses=int(poses),
        rows=int(H.shape[0]),
        noise_m=float(noise_m),
        covariance=cov,
        correlated=tuple(pairs),
    )
