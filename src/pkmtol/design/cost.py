"""Cost-optimal tolerances: minimise manufacturing cost subject to exact reliability everywhere.

Each toleranced parameter ``i`` costs ``C_i(t_i) = A_i + B_i / t_i^k_i`` with ``t_i`` its tolerance
in display units (mm for lengths, mrad for angles), within process limits ``t_min ≤ t ≤ t_max``.
The design minimises ``Σ C_i`` subject to the exact Gaussian reliability
``R_j(σ) = P(‖J_j η‖ ≤ Δλ*) ≥ R*`` at every task-space grid pose ``j`` (``σ = t`` in SI).

Optimisation: SLSQP over ``x = log σ`` with analytic gradients — ``∂C/∂x_i = −k_i B_i t_i^{−k_i}``
and ``∂R_j/∂x_i = 2 σ_i² J_{j,i}ᵀ (∂R_j/∂Σ) J_{j,i}`` from :func:`exact_reliability` — on an active
set of poses grown by cutting planes: solve with the poses that bind, check all poses, add the
violated ones, repeat. The reliabilities of all poses (and the gradients of the active ones) are
evaluated together by :func:`pkmtol.design.reliability.exact_reliability_many`.

Defaults (overridable in ``mechanism.toml``, ``[cost.length]``, ``[cost.angle]`` and
``[cost.parameters."<name>"]``): ``A = 0``, ``B = 1``, ``k = 1``; lengths 0.001–1 mm, angles
0.005–10 mrad.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pkmtol.design.reliability import exact_reliability_many
from pkmtol.error_model.parameters import ErrorParameter
from pkmtol.exceptions import InvalidRequestError
from pkmtol.units import display

DEFAULT_COST: dict[str, dict[str, float]] = {
    "m": {"A": 0.0, "B": 1.0, "k": 1.0, "t_min": 0.001, "t_max": 1.0},  # t in mm
    "rad": {"A": 0.0, "B": 1.0, "k": 1.0, "t_min": 0.005, "t_max": 10.0},  # t in mrad
}
_KIND = {"m": "length", "rad": "angle"}
_FIELDS = ("A", "B", "k", "t_min", "t_max")


@dataclass(frozen=True)
class CostModel:
    """Cost-tolerance model of the toleranced parameters (arrays of shape (k,)).

    Attributes:
        A: Fixed cost.
        B: Cost coefficient [cost · display-unit^k].
        k: Exponent.
        t_min_si: Lower process limit [m or rad].
        t_max_si: Upper process limit [m or rad].
        scale: SI → display factor per parameter (1e3 for m → mm and rad → mrad).
    """

    A: np.ndarray
    B: np.ndarray
    k: np.ndarray
    t_min_si: np.ndarray
    t_max_si: np.ndarray
    scale: np.ndarray

    def cost(self, sigma: np.ndarray) -> float:
        """Total cost of tolerances ``σ`` (SI)."""
        t = sigma * self.scale
        return float(np.sum(self.A + self.B / t**self.k))


def cost_model(parameters: Sequence[ErrorParameter], overrides: Mapping[str, Any] | None = None) -> CostModel:
    """Cost model of ``parameters`` from the defaults and the ``[cost]`` table of mechanism.toml.

    Raises:
        InvalidRequestError: an override names an unknown field or parameter, or is not positive.
    """
    overrides = dict(overrides or {})
    per_param = dict(overrides.pop("parameters", {}) or {})
    names = {p.name for p in parameters}
    unknown = set(per_param) - names
    if unknown:
        raise InvalidRequestError(
            f"[cost.parameters] names unknown parameters {sorted(unknown)}; see `pkmtol errors` for names"
        )
    unknown_kinds = set(overrides) - {"length", "angle"}
    if unknown_kinds:
        raise InvalidRequestError(
            f"[cost] tables must be 'length', 'angle' or 'parameters', got {sorted(unknown_kinds)}"
        )
    cols: dict[str, list[float]] = {f: [] for f in _FIELDS}
    for p in parameters:
        entry = dict(DEFAULT_COST[p.unit])
        for src in (overrides.get(_KIND[p.unit], {}), per_param.get(p.name, {})):
            for key, val in src.items():
                if key not in _FIELDS:
                    raise InvalidRequestError(f"cost field {key!r} unknown; use {', '.join(_FIELDS)}")
                entry[key] = float(val)
        if entry["B"] <= 0 or entry["k"] <= 0 or not 0 < entry["t_min"] < entry["t_max"]:
            raise InvalidRequestError(
                f"cost of {p.name}: need B > 0, k > 0 and 0 < t_min < t_max, got {entry}"
            )
        for f in _FIELDS:
            cols[f].append(entry[f])
    scale = np.array([display(1.0, p.unit) for p in parameters])
    return CostModel(
        A=np.array(cols["A"]),
        B=np.array(cols["B"]),
        k=np.array(cols["k"]),
        t_min_si=np.array(cols["t_min"]) / scale,
        t_max_si=np.array(cols["t_max"]) / scale,
        scale=scale,
    )


@dataclass(frozen=True)
class CostDesign:
    """A cost-optimal design.

    Attributes:
        sigma: Tolerances (k,) [SI].
        cost: Total cost.
        reliability: Exact Gaussian R at each grid pose (m,).
        active_poses: Grid indices whose constraints were in the final problem.
        iterations: Cutting-plane rounds.
    """

    sigma: np.ndarray
    cost: float
    reliability: np.ndarray
    active_poses: tuple[int, ...]
    iterations: int


def _cov(J: np.ndarray, sigma: np.ndarray, extra: np.ndarray | None) -> np.ndarray:
    """``J diag(σ²) Jᵀ`` (m, 3, 3), plus the fixed covariance ``extra`` (m, 3, 3) if any."""
    a = J * sigma[None, None, :]
    cov = a @ np.swapaxes(a, 1, 2)
    return cov if extra is None else cov + extra


def _rel_and_grad(
    J: np.ndarray, sigma: np.ndarray, target_m: float, extra: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Exact R (m,) at poses ``J`` (m, 3, k) and ``∂R/∂(log σ)`` (m, k) (``extra``: fixed covariance)."""
    r, g = exact_reliability_many(_cov(J, sigma, extra), target_m, gradient=True)
    assert g is not None
    # ∂R/∂x_i (x = log σ) = σ_i ∂R/∂σ_i = 2 σ_i² J_iᵀ G J_i
    d = 2.0 * sigma**2 * np.einsum("mji,mjk,mki->mi", J, g, J)
    return r, d


def _rel(J: np.ndarray, sigma: np.ndarray, target_m: float, extra: np.ndarray | None = None) -> np.ndarray:
    """Exact R (m,) at poses ``J`` (m, 3, k) for tolerances ``σ`` (k,) (``extra``: fixed covariance)."""
    return exact_reliability_many(_cov(J, sigma, extra), target_m)[0]


def cost_optimal(
    J: np.ndarray,
    model: CostModel,
    target_m: float,
    r_star: float,
    start: np.ndarray,
    names: Sequence[str],
    max_rounds: int = 10,
    extra_cov: np.ndarray | None = None,
) -> CostDesign:
    """Minimise total cost subject to exact R ≥ R* at every grid pose.

    Args:
        J: Grid maps (m, 3, k) of the toleranced parameters.
        model: Cost model (k parameters).
        target_m: Δλ* [m].
        r_star: Target reliability.
        start: Feasible starting tolerances (k,) [SI], e.g. the equal-effect design scaled to
            meet R* at every pose.
        names: Parameter names (for error messages).
        max_rounds: Cutting-plane rounds at most.
        extra_cov: Fixed covariance (m, 3, 3) added at each pose [m²] (calibration noise).

    Raises:
        InvalidRequestError: no tolerances within the process limits reach R* at every pose;
            the message names the parameters whose lower limits bind.
    """
    from scipy import optimize  # SLSQP and a root finder: only the cost design needs them

    m, _, k = J.shape
    r_tight = _rel(J, model.t_min_si, target_m, extra_cov)
    if r_tight.min() < r_star:
        j = int(np.argmin(r_tight))
        contrib = np.linalg.norm(J[j], axis=0) * model.t_min_si
        order = np.argsort(contrib)[::-1][:3]
        raise InvalidRequestError(
            f"infeasible: even with every tolerance at its lower process limit the reliability at "
            f"grid pose {j} is {100 * r_tight[j]:.4f} % < {100 * r_star:.4f} %; the binding parameters "
            f"are {', '.join(names[i] for i in order)} — lower their t_min in [cost] of mechanism.toml, "
            "relax the target or lower β"
        )
    lo, hi = np.log(model.t_min_si), np.log(model.t_max_si)
    x0 = np.clip(np.log(start), lo, hi)
    c0 = max(model.cost(np.exp(x0)), 1e-300)

    def objective(x: np.ndarray) -> tuple[float, np.ndarray]:
        t = np.exp(x) * model.scale
        terms = model.B / t**model.k
        return float(np.sum(model.A + terms)) / c0, -model.k * terms / c0

    def r_all(x: np.ndarray) -> np.ndarray:
        return _rel(J, np.exp(x), target_m, extra_cov)

    active = [int(np.argmin(r_all(x0)))]
    x = x0
    rounds = 0
    while rounds < max_rounds:
        rounds += 1
        Ja = J[list(active)]
        Ea = None if extra_cov is None else extra_cov[list(active)]
        cons = {
            "type": "ineq",
            "fun": lambda x, Ja=Ja, Ea=Ea: _rel(Ja, np.exp(x), target_m, Ea) - r_star,
            "jac": lambda x, Ja=Ja, Ea=Ea: _rel_and_grad(Ja, np.exp(x), target_m, Ea)[1],
        }
        res = optimize.minimize(
            objective,
            x,
            jac=True,
            method="SLSQP",
            bounds=list(zip(lo, hi, strict=True)),
            constraints=[cons],
            options={"maxiter": 300, "ftol": 1e-12},
        )
        x = res.x
        r = r_all(x)
        viol = [j for j in np.argsort(r) if r[j] < r_star - 1e-9 and j not in active]
        if not viol:
            break
        active.extend(int(j) for j in viol[:5])
    # make the result feasible to round-off: shrink uniformly if a constraint is still violated
    r = r_all(x)
    if r.min() < r_star:
        # shrinking every tolerance raises R at every pose: only the violated poses can bind
        bad = np.flatnonzero(r < r_star)
        Jb, Eb = J[bad], None if extra_cov is None else extra_cov[bad]

        def gap(d: float) -> float:
            return float(_rel(Jb, np.exp(np.clip(x - d, lo, hi)), target_m, Eb).min() - r_star)

        d = optimize.brentq(gap, 0.0, 5.0, xtol=1e-13)
        x = np.clip(x - d, lo, hi)
        r = r_all(x)
    sigma = np.exp(x)
    return CostDesign(
        sigma=sigma, cost=model.cost(sigma), reliability=r, active_poses=tuple(active), iterations=rounds
    )
