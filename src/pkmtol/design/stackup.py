"""Stack-up numbers of a tolerance box: the exact worst case of ``‖L η‖`` over ``|η_i| ≤ t_i``, bounds, RSS.

For a linear error map ``L`` (3 × n, e.g. the post-compensation map of P at one pose) and the
tolerance box ``B = {η : |η_i| ≤ t_i}``, the image ``L B`` is a zonotope with the generators
``g_i = t_i L[:, i]``. ``‖L η‖`` is convex, so its maximum over ``B`` sits at a vertex of ``B``; and
the vertex that maximises ``uᵀ L η`` for a direction ``u`` is ``η = t ∘ sign(Lᵀ u)``. So only the
zonotope's vertices can win, and a zonotope in 3-D has at most ``n(n − 1) + 2`` of them (not
``2ⁿ``): they are the cells of the arrangement of the planes ``g_iᵀ u = 0`` on the unit sphere.
Every cell has a corner where two of those planes meet, at ``u = ±(g_a × g_b)``; perturbing ``u``
around each corner gives every sign pattern of the cells that touch it. :func:`worst_case_norm`
enumerates them all — exact for any ``n`` in ``O(n³)`` — with parallel generators merged and
coplanar ones (several planes through one corner) enumerated in their plane.
:func:`worst_case_norm_vertices` is the brute force over all ``2ⁿ`` vertices (``n ≤ 20``), used to
check it.

Two stated bounds go beside it: the arithmetic stack-up ``Σ ‖g_i‖`` (triangle inequality, an upper
bound) and the root sum of squares ``RSS = √Σ ‖g_i‖²``, which is the root-mean-square of
``‖L η‖`` over random signs and hence a lower bound: ``RSS ≤ worst case ≤ Σ ‖g_i‖``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pkmtol.exceptions import InvalidRequestError

#: Largest ``n`` for the brute-force vertex enumeration (``2ⁿ⁻¹`` vertices are evaluated).
MAX_BRUTE_FORCE = 20
#: Relative size below which a generator is zero, and relative distance below which two generator
#: directions are parallel or a third lies in the plane of two.
_ZERO = 1e-12
_PARALLEL = 1e-9
_COPLANAR = 1e-9


@dataclass(frozen=True, eq=False)
class WorstCase:
    """The largest ``‖L η‖`` over the box ``|η_i| ≤ t_i``.

    Attributes:
        value: ``max ‖L η‖`` over the box (unit of ``L η``, e.g. m).
        signs: Shape (n,): a maximising vertex is ``η = signs · t`` (entries ±1).
        candidates: Number of vertices evaluated.
    """

    value: float
    signs: np.ndarray
    candidates: int


def _check(L: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    L = np.asarray(L, dtype=float)
    t = np.asarray(t, dtype=float)
    if L.ndim != 2 or L.shape[0] > 3 or t.shape != (L.shape[1],):
        raise InvalidRequestError(
            f"need a map L of shape (d ≤ 3, n) and tolerances t of shape (n,), got {L.shape} and {t.shape}"
        )
    if not (np.all(np.isfinite(L)) and np.all(np.isfinite(t)) and np.all(t >= 0)):
        raise InvalidRequestError("the map and the tolerances must be finite, the tolerances ≥ 0")
    if L.shape[0] < 3:
        L = np.vstack([L, np.zeros((3 - L.shape[0], L.shape[1]))])
    return L, t


def worst_case_norm(L: np.ndarray, t: np.ndarray) -> WorstCase:
    """Exact ``max ‖L η‖₂`` over ``|η_i| ≤ t_i`` by enumerating the zonotope's vertices (any ``n``).

    Args:
        L: Shape (d, n), d ≤ 3: the linear map (e.g. m per m or rad).
        t: Shape (n,): half-widths of the box (SI), ≥ 0.

    Returns:
        The maximum, a maximising vertex's signs, and the number of vertices evaluated.

    Raises:
        InvalidRequestError: wrong shapes, non-finite values or negative tolerances.

    >>> L = np.array([[1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
    >>> round(worst_case_norm(L, np.array([1.0, 1.0])).value, 9)   # ‖(2, 1, 0)‖ = √5
    2.236067977
    """
    L, t = _check(L, t)
    n = t.size
    G = L * t[None, :]
    norms = np.linalg.norm(G, axis=0)
    signs = np.ones(n)
    top = float(norms.max(initial=0.0))
    if top <= 0.0:
        return WorstCase(0.0, signs, 1)
    live = np.flatnonzero(norms > _ZERO * top)
    # merge parallel generators: each group acts as one generator of the summed length
    d = G[:, live] / norms[live]
    lead = np.argmax(np.abs(d), axis=0)
    d = d * np.sign(d[lead, np.arange(live.size)])
    near = np.linalg.norm(d[:, :, None] - d[:, None, :], axis=0) <= _PARALLEL  # (k, k)
    group = -np.ones(live.size, dtype=int)
    heads: list[int] = []
    for k in range(live.size):
        if group[k] < 0:
            group[near[k] & (group < 0)] = len(heads)
            heads.append(k)
    H = np.zeros((3, len(heads)))
    for k in range(live.size):
        H[:, group[k]] += d[:, heads[group[k]]] * norms[live[k]]
    orient = np.sign(np.einsum("ik,ik->k", G[:, live], d))  # each generator's sign within its group
    s_group, value, count = _zonotope_max(H)
    signs[live] = s_group[group] * orient
    return WorstCase(value, signs, count)


def _zonotope_max(H: np.ndarray) -> tuple[np.ndarray, float, int]:
    """Maximum norm of the zonotope ``{H c : |c| ≤ 1}`` (generators pairwise non-parallel)."""
    m = H.shape[1]
    if m == 1:
        return np.ones(1), float(np.linalg.norm(H[:, 0])), 1
    hn = np.linalg.norm(H, axis=0)
    a, b = np.triu_indices(m, 1)
    W = np.cross(H[:, a].T, H[:, b].T)
    W /= np.linalg.norm(W, axis=1)[:, None]
    C = W @ H  # (pairs, m): side of every generator's plane at each corner
    coplanar = np.abs(C) <= _COPLANAR * hn[None, :]
    # a and b span the plane: in it by construction (round-off in W can say otherwise when they
    # are nearly parallel, which left _plane_patterns no generator to turn around)
    coplanar[np.arange(a.size), a] = True
    coplanar[np.arange(a.size), b] = True
    base = np.sign(C)
    base[coplanar] = 0.0
    best_value, best_signs, count = -1.0, np.ones(m), 0
    generic = coplanar.sum(axis=1) == 2
    if generic.any():
        # only a and b lie in the corner's plane: the four cells around it take every sign of theirs
        X0 = (H @ base[generic].T).T
        ga, gb = H[:, a[generic]].T, H[:, b[generic]].T
        for sa in (1.0, -1.0):
            for sb in (1.0, -1.0):
                x = X0 + sa * ga + sb * gb
                v = np.linalg.norm(x, axis=1)
                k = int(np.argmax(v))
                count += v.size
                if v[k] > best_value:
                    row = np.flatnonzero(generic)[k]
                    best_value = float(v[k])
                    best_signs = base[row].copy()
                    best_signs[a[row]], best_signs[b[row]] = sa, sb
    seen: set[bytes] = set()
    for row in np.flatnonzero(~generic):
        key = coplanar[row].tobytes() + base[row].astype(np.int8).tobytes()
        if key in seen:
            continue
        seen.add(key)
        for s in _plane_patterns(H, coplanar[row], W[row], a[row]):
            signs = base[row].copy()
            signs[coplanar[row]] = s
            v = float(np.linalg.norm(H @ signs))
            count += 1
            if v > best_value:
                best_value, best_signs = v, signs
    # the sign-reversed candidates have the same norms: nothing more to evaluate
    return best_signs, best_value, 2 * count


def _plane_patterns(H: np.ndarray, in_plane: np.ndarray, normal: np.ndarray, first: int) -> list[np.ndarray]:
    """Sign patterns of the generators lying in one plane, for directions turning around in it."""
    e1 = H[:, first] / np.linalg.norm(H[:, first])
    e2 = np.cross(normal, e1)
    P = H[:, in_plane]
    phi = np.arctan2(e2 @ P, e1 @ P)
    # sign(cos(ψ − φ_k)) changes at ψ = φ_k ± π/2: one pattern per arc between those angles
    crit = np.sort(np.mod(np.concatenate([phi + math.pi / 2, phi - math.pi / 2]), 2 * math.pi))
    mids = (crit + np.roll(crit, -1) + np.r_[np.zeros(crit.size - 1), 2 * math.pi]) / 2
    return [np.where(np.cos(psi - phi) >= 0, 1.0, -1.0) for psi in mids]


def worst_case_norm_vertices(L: np.ndarray, t: np.ndarray) -> WorstCase:
    """The same maximum by brute force over every vertex of the box (``n ≤ 20``; a check).

    Raises:
        InvalidRequestError: more than :data:`MAX_BRUTE_FORCE` parameters, or bad input.
    """
    L, t = _check(L, t)
    n = t.size
    if n > MAX_BRUTE_FORCE:
        raise InvalidRequestError(
            f"brute-force vertex enumeration is for n ≤ {MAX_BRUTE_FORCE} parameters, got {n}; "
            "use worst_case_norm (exact for any n)"
        )
    G = L * t[None, :]
    if n == 0:
        return WorstCase(0.0, np.ones(0), 1)
    best, best_signs = -1.0, np.ones(n)
    # the first sign is fixed to +1: a vertex and its negative have the same norm
    rest = n - 1
    chunk = 1 << min(rest, 16)
    codes = np.arange(chunk)
    bits = ((codes[:, None] >> np.arange(min(rest, 16))) & 1) * -2 + 1
    for high in range(1 << max(rest - 16, 0)):
        hbits = ((high >> np.arange(max(rest - 16, 0))) & 1) * -2 + 1
        S = np.hstack([np.ones((chunk, 1)), bits, np.tile(hbits, (chunk, 1))]).astype(float)
        v = np.linalg.norm(S @ G.T, axis=1)
        k = int(np.argmax(v))
        if v[k] > best:
            best, best_signs = float(v[k]), S[k].copy()
    return WorstCase(best, best_signs, 1 << n)


@dataclass(frozen=True, eq=False)
class StackUp:
    """Stack-up numbers of the drawing tolerances ``±t_i`` at every pose of a grid.

    Attributes:
        worst_case_m: Shape (m,): exact ``max ‖L_k η‖`` over the tolerance box [m].
        arithmetic_m: Shape (m,): ``Σ_i ω_{k,i} t_i``, the arithmetic (linear) stack-up, an upper
            bound of the worst case [m].
        rss_m: Shape (m,): ``√Σ_i (ω_{k,i} t_i)²``, the root sum of squares [m].
        worst_signs: Shape (m, n): the signs of a worst-case vertex at each pose.
    """

    worst_case_m: np.ndarray
    arithmetic_m: np.ndarray
    rss_m: np.ndarray
    worst_signs: np.ndarray


def stack_up(L: np.ndarray, t: np.ndarray) -> StackUp:
    """Worst case, arithmetic and RSS stack-ups of ``±t`` for the maps ``L`` (m, 3, n) of m poses."""
    L = np.asarray(L, dtype=float)
    t = np.asarray(t, dtype=float)
    if L.ndim != 3:
        raise InvalidRequestError(f"need maps of shape (m, 3, n), got {L.shape}")
    effect = np.linalg.norm(L, axis=1) * t[None, :]  # (m, n)
    results = [worst_case_norm(Lk, t) for Lk in L]
    return StackUp(
        worst_case_m=np.array([r.value for r in results]),
        arithmetic_m=effect.sum(axis=1),
        rss_m=np.sqrt((effect**2).sum(axis=1)),
        worst_signs=np.array([r.signs for r in results]).reshape(len(L), t.size),
    )
