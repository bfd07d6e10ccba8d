"""Pose selection for calibration: D-optimal subsets of a candidate pool (greedy, then exchange).

The information of a set ``S`` of poses about the base parameters is ``M(S) = Σ_{k∈S} B_kᵀ B_k``
with ``B_k`` pose ``k``'s rows of the scaled base Jacobian (``H_B S_B``, one row per measured
coordinate). D-optimality maximises ``log det M(S)``. Greedy: add, one at a time, the pose with the
largest gain ``log det(I + B_k M⁻¹ B_kᵀ)`` (the matrix determinant lemma; ``M`` starts as a small
ridge so that the first poses can be compared). Exchange (Fedorov): swap a chosen pose for a
candidate while that raises ``log det M``. Both use only the small blocks ``B_k`` (3·t × r).
"""

from __future__ import annotations

import numpy as np

from pkmtol.exceptions import InvalidRequestError

#: Ridge of the greedy start, relative to the mean diagonal of the pool's information.
START_RIDGE = 1e-8
MAX_EXCHANGE_SWEEPS = 20


def log_det_information(blocks: np.ndarray, chosen: np.ndarray) -> float:
    """``log det Σ_{k∈chosen} B_kᵀ B_k`` for blocks (m, rows, r); ``-inf`` if singular."""
    M = np.einsum("kia,kib->ab", blocks[chosen], blocks[chosen])
    sign, value = np.linalg.slogdet(M)
    return float(value) if sign > 0 else float("-inf")


def d_optimal(
    blocks: np.ndarray, count: int, fixed: np.ndarray | None = None, nuisance: int = 0
) -> np.ndarray:
    """Indices of ``count`` poses of the pool that maximise ``log det`` of the information.

    With ``nuisance`` > 0 the last ``nuisance`` columns are an instrument's nuisance parameters
    (identified with the machine, then dropped): the criterion is then the information about the
    machine's base parameters with the nuisance unknown (Ds-optimality),
    ``log det M − log det M_ππ``, so that touching a new station once is worth nothing.

    Args:
        blocks: Shape (m, rows, r): each candidate pose's rows of the scaled base Jacobian.
        count: Number of poses to choose (``count · rows ≥ r`` for a non-singular information).
        fixed: Candidates that must be in the set (they are never exchanged).
        nuisance: Trailing nuisance columns of ``blocks``.

    Returns:
        Shape (count,): chosen candidate indices (greedy order, then exchanged in place).

    Raises:
        InvalidRequestError: ``count`` is out of range.
    """
    m, rows, r = blocks.shape
    if not 1 <= count <= m:
        raise InvalidRequestError(f"cannot choose {count} poses from a pool of {m}")
    fixed_idx = [] if fixed is None else [int(i) for i in fixed]
    info_pool = np.einsum("kia,kib->ab", blocks, blocks)
    ridge = START_RIDGE * float(np.trace(info_pool)) / max(r, 1) / m
    M = ridge * np.eye(r)
    chosen: list[int] = []
    available = np.ones(m, dtype=bool)
    for k in fixed_idx:
        M += blocks[k].T @ blocks[k]
        chosen.append(k)
        available[k] = False
    q = int(nuisance)

    def gains(M_: np.ndarray) -> np.ndarray:
        g = _gains(blocks, np.linalg.inv(M_))
        if q:
            g = g - _gains(blocks[:, :, r - q :], np.linalg.inv(M_[r - q :, r - q :]))
        return g

    def criterion(M_: np.ndarray) -> tuple[float, float]:
        sign, value = np.linalg.slogdet(M_)
        if q:
            s_n, v_n = np.linalg.slogdet(M_[r - q :, r - q :])
            return min(sign, s_n), value - v_n
        return sign, value

    while len(chosen) < count:
        gain = gains(M)
        gain[~available] = -np.inf
        k = int(np.argmax(gain))
        M += blocks[k].T @ blocks[k]
        chosen.append(k)
        available[k] = False
    chosen_arr = np.array(chosen, dtype=int)
    free = len(fixed_idx)
    for _ in range(MAX_EXCHANGE_SWEEPS):
        improved = False
        for pos in range(free, count):
            out = chosen_arr[pos]
            M_out = M - blocks[out].T @ blocks[out]
            sign, base = criterion(M_out)
            if sign <= 0:
                continue
            gain = gains(M_out)
            gain[~available] = -np.inf
            gain_out = criterion(M)[1] - base
            k = int(np.argmax(gain))
            if gain[k] > gain_out * (1 + 1e-12) + 1e-12:
                available[out], available[k] = True, False
                chosen_arr[pos] = k
                M = M_out + blocks[k].T @ blocks[k]
                improved = True
        if not improved:
            break
    return chosen_arr


def _gains(blocks: np.ndarray, M_inv: np.ndarray) -> np.ndarray:
    """``log det(I + B_k M⁻¹ B_kᵀ)`` of every candidate, shape (m,)."""
    inner = (blocks @ M_inv) @ np.swapaxes(blocks, 1, 2)
    inner += np.eye(blocks.shape[1])[None]
    sign, value = np.linalg.slogdet(inner)
    return np.where(sign > 0, value, -np.inf)


def random_subset(m: int, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` distinct pose indices out of ``m``, uniformly at random."""
    if not 1 <= count <= m:
        raise InvalidRequestError(f"cannot choose {count} poses from a pool of {m}")
    return np.sort(rng.choice(m, size=count, replace=False))
