"""An instrument's identification system at some poses: whitened, with its nuisance parameters projected out.

At pose ``k`` the instrument's values change by ``D_k $_k`` (:meth:`Instrument.twist_rows`) and the
platform twist at held commands is ``$_k = T_k δ``, so the machine Jacobian is ``H = D T`` (M × n,
M = N·r values). The nuisance parameters ``π`` enter as ``H_π`` (M × q). Each value is divided by
its σ and multiplied by the reference σ_m (:attr:`CalibrationSettings.noise_m`): ``W = σ_m / σ``,
so that every whitened value has the noise σ_m. The least-squares estimate of the machine
parameters with ``π`` unknown is the least-squares estimate on the projected system
``H_eff = (I − Q Qᵀ) W H`` (``Q`` an orthonormal basis of ``W H_π``): the rows of ``H_eff⁺`` are
orthogonal to every change of ``π``, so the nuisance never reaches the machine's estimate, to
first order. ``H_eff`` is what the base parameters, the D-optimal plan and the post-calibration
maps ``L``, ``N`` are computed from (DESIGN.md, "Compensation and calibration"); with a tracker
in a registered frame it is the plain ``H``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.calibration.instruments.base import Instrument
from pkmtol.calibration.maps import PoseMaps

#: Singular values of ``W H_π`` below this fraction of the largest are directions no data fixes.
NUISANCE_RANK = 1e-10


@dataclass(frozen=True, eq=False)
class LinearSystem:
    """The linear measurement model at ``N`` poses (``M = N·r`` values, ``n`` parameters, ``q`` nuisance).

    Attributes:
        machine: Shape (M, n): values per unit parameter, raw units [m or rad per unit].
        nuisance: Shape (M, q): values per unit nuisance parameter.
        weights: Shape (M,): ``σ_m / σ`` of every value (whitening to the reference σ_m).
        effective: Shape (M, n): ``(I − Q Qᵀ) W H``, the whitened system with ``π`` projected out.
        nuisance_rank: Rank of ``W H_π`` (how many nuisance directions the data fixes).
    """

    machine: np.ndarray
    nuisance: np.ndarray
    weights: np.ndarray
    effective: np.ndarray
    nuisance_rank: int


def value_weights(instrument: Instrument, poses: int, reference_noise_m: float) -> np.ndarray:
    """``σ_m / σ`` of every value of ``poses`` poses (M,), in the order pose, value."""
    noise = np.asarray(instrument.noise, dtype=float)
    if reference_noise_m <= 0 or np.any(noise <= 0):
        return np.ones(poses * noise.size)
    return np.tile(reference_noise_m / noise, poses)


def linear_system(
    instrument: Instrument,
    maps: PoseMaps,
    reference_noise_m: float,
    nuisance: np.ndarray | None = None,
) -> LinearSystem:
    """The instrument's system at the poses of ``maps`` (nominal platform poses, twist maps).

    Args:
        instrument: The measurement model.
        maps: The poses (their ``stations`` name the instrument's stations).
        reference_noise_m: σ_m the values are whitened to [m].
        nuisance: Where to linearise the nuisance parameters (q,) (default: 0, their nominal).
    """
    pi = np.zeros(instrument.nuisance_count) if nuisance is None else np.asarray(nuisance, dtype=float)
    origin, rot, st = maps.origins_m, maps.rotations, maps.station_index
    rows = instrument.twist_rows(origin, rot, st, pi)  # (N, r, 6)
    H = np.einsum("kra,kan->krn", rows, maps.measurement_twist).reshape(-1, maps.twist.shape[2])
    Hp = instrument.nuisance_rows(origin, rot, st, pi).reshape(H.shape[0], -1)
    w = value_weights(instrument, len(maps), reference_noise_m)
    Hw = H * w[:, None]
    rank = 0
    if Hp.shape[1]:
        u, s, _ = np.linalg.svd(Hp * w[:, None], full_matrices=False)
        rank = int(np.sum(s > NUISANCE_RANK * s[0])) if s.size and s[0] > 0 else 0
        Q = u[:, :rank]
        eff = Hw - Q @ (Q.T @ Hw)
    else:
        eff = Hw
    return LinearSystem(machine=H, nuisance=Hp, weights=w, effective=eff, nuisance_rank=rank)
