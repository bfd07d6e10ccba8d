"""Identification on exact kinematics: Gauss–Newton fit of the controller model to tracker data.

Every residual is a measured target position minus the exact forward kinematics of the mechanism
perturbed by the current estimate, at the commanded actuator readings (:class:`Machine`). The
unknowns are the base parameters of :mod:`pkmtol.calibration.identifiability` (least squares), or
every parameter of the controller model with a Gaussian prior (MAP, ``prior_sigma``).

The Jacobian is the error model's analytic one at the nominal point (``H``, rows of
:meth:`PoseMaps.measurement_rows`), computed once and kept: the iteration is then a contraction
whose rate is the relative change of the Jacobian over the estimate (about ``|δ|/|link|``, 1e-3 for
0.1 mm errors on a 0.5 m machine), it needs no finite differences, and it cannot jitter
(DESIGN.md, "Pitfalls"). A step that raises the residual is halved.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from pkmtol.calibration.identifiability import Identifiability
from pkmtol.calibration.instruments.base import Instrument
from pkmtol.calibration.instruments.tracker import TrackerPoints
from pkmtol.calibration.linear_system import value_weights
from pkmtol.calibration.machine import Machine
from pkmtol.calibration.maps import PoseMaps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import IdentificationError, InvalidRequestError
from pkmtol.model.mechanism import Mechanism

#: Stop when every step component is below this fraction of its parameter's scale (1e-12 m for a
#: 0.1 mm scale: the exact solves themselves stop at a 1e-13 residual).
STEP_TOLERANCE = 1e-8
#: A step that raises the cost by more than this (relative) is halved.
COST_RISE = 1e-6
MAX_ITERATIONS = 30
#: The size of the exact solves' round-off in a value [m]: below it a rise of the cost is noise.
SOLVE_NOISE = 1e-13
#: With nuisance parameters, also converged when every step is below this fraction of its estimate's
#: own standard deviation (the weakest directions are known only to their noise, and a frozen
#: machine Jacobian cannot settle them beyond it).
STEP_OF_STD = 1e-3
#: ... or when no step lowers the cost and the offered step would change the fitted values by less
#: than this many σ in all: a cost change below 1 σ², far inside the spread √(2M) of the noise's χ².
FIT_CHANGE = 1.0
#: The residuals "show the noise" when their whitened RMS is at least this fraction of σ_m.
NOISY = 0.1
#: Levenberg–Marquardt damping tried (relative to the largest singular value squared) when no
#: halving of the Gauss–Newton step lowers the cost, with nuisance parameters.
DAMPING = (1e-8, 1e-6, 1e-4, 1e-2)
#: Halvings of a step that raises the residual before giving up.
MAX_HALVINGS = 8


@dataclass(frozen=True, eq=False)
class Identification:
    """Result of one identification (SI units; ``N`` poses, ``t`` targets, ``n`` parameters).

    Attributes:
        method: ``least-squares`` (base parameters) or ``map`` (every controller parameter, prior).
        names: Names of the estimated quantities (base parameters in pivot order, or the
            controller model's parameters for ``map``).
        identified: The estimated quantities [m or rad].
        covariance: Their covariance: ``σ_m² (H_Bᵀ H_B)⁻¹`` (least squares) or the posterior
            ``(Hᵀ H / σ_m² + Σ_p⁻¹)⁻¹`` (MAP) [SI²].
        estimate: Shape (n,): the controller model's full parameter vector (zeros outside it, and
            at the dependent parameters for least squares).
        residuals_m: Shape (N, t, 3): measured − model at the estimate [m].
        residuals_before_m: Shape (N, t, 3): measured − nominal model [m].
        iterations: Gauss–Newton iterations taken.
        converged: Whether the last step was below :data:`STEP_TOLERANCE` of every scale before
            :data:`MAX_ITERATIONS` (False: the result is the last accepted iterate; say so).
        q: Shape (N, Σ nq): the model's joint values at the calibration poses.
        nuisance: Shape (q,): the instrument's nuisance parameters at the estimate (relative to
            ``instrument``'s reference) [m or rad].
        nuisance_covariance: Shape (q, q): their covariance [SI²].
        instrument: The measurement model linearised at the start (a tracker's registered frame).
        weighted_rms: RMS of the residuals divided by each value's σ (≈ 1 for a fit at the noise).
    """

    method: str
    names: tuple[str, ...]
    identified: np.ndarray
    covariance: np.ndarray
    estimate: np.ndarray
    residuals_m: np.ndarray
    residuals_before_m: np.ndarray
    iterations: int
    converged: bool
    q: np.ndarray
    nuisance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nuisance_covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    instrument: Instrument | None = None
    weighted_rms: float = float("nan")

    @property
    def nuisance_std(self) -> np.ndarray:
        """Standard deviation of each nuisance parameter [SI]."""
        return np.sqrt(np.clip(np.diag(self.nuisance_covariance), 0.0, None))

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each estimated quantity [SI]."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def _lengths(self, res: np.ndarray) -> np.ndarray:
        if self.instrument is None or res.ndim != 2:
            return res
        mask = np.array([u == "m" for u in self.instrument.value_units])
        return res[:, mask] if mask.any() else res

    @property
    def rms_before_m(self) -> float:
        """RMS of the measured lengths' residuals against the nominal model [m] (angles left out)."""
        return float(np.sqrt(np.mean(self._lengths(self.residuals_before_m) ** 2)))

    @property
    def rms_after_m(self) -> float:
        """RMS of the lengths' residuals at the estimate [m]."""
        return float(np.sqrt(np.mean(self._lengths(self.residuals_m) ** 2)))


def model_positions(
    machine: Machine, commands: np.ndarray, q0: np.ndarray, targets_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact target positions of ``machine`` at readings ``commands`` (N, f).

    Returns:
        ``(positions (N, t, 3) [m], q (N, Σ nq))``.

    Raises:
        IdentificationError: a pose cannot be solved (names it).
    """
    targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
    sols = machine.forward_many(commands, q0)
    for k, err in enumerate(sols.errors):
        if err is not None:
            raise IdentificationError(
                f"calibration pose {k} (commands {np.round(commands[k], 6).tolist()}): the model cannot be "
                f"solved there ({err}); the estimate left the range where the mechanism assembles — "
                "check the measurements of that pose and the controller model"
            ) from err
    out = sols.translation[:, None, :] + np.einsum("kij,tj->kti", sols.rotation, targets)
    return out, sols.q


def machine_poses(
    machine: Machine, commands: np.ndarray, q0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact platform poses of ``machine`` at readings ``commands`` (N, f).

    Returns:
        ``(origin (N, 3) [m], rotation (N, 3, 3), q (N, Σ nq))``.

    Raises:
        IdentificationError: a pose cannot be solved (names it).
    """
    sols = machine.forward_many(commands, q0)
    for k, err in enumerate(sols.errors):
        if err is not None:
            raise IdentificationError(
                f"calibration pose {k} (commands {np.round(commands[k], 6).tolist()}): the model cannot be "
                f"solved there ({err}); the estimate left the range where the mechanism assembles — "
                "check the measurements of that pose and the controller model"
            ) from err
    return sols.translation, sols.rotation, sols.q


def identify(
    mechanism: Mechanism,
    pset: ParameterSet,
    ident: Identifiability,
    H: np.ndarray,
    commands: np.ndarray,
    q_guess: np.ndarray,
    measured_m: np.ndarray,
    targets_m: np.ndarray,
    prior_sigma: np.ndarray | None = None,
) -> Identification:
    """Fit the controller model to tracker positions (a registered frame) by Gauss–Newton on exact kinematics.

    Args:
        mechanism: The nominal mechanism.
        pset: Its parameter set (``n`` parameters).
        ident: The base parameters of the controller model on these poses.
        H: Shape (3·N·t, n): measured coordinates per unit parameter at the nominal point, rows in
            the order pose, target, axis (:meth:`PoseMaps.measurement_rows`, reshaped).
        commands: Shape (N, f): commanded actuator readings of the calibration poses.
        q_guess: Shape (N, Σ nq): initial joint values at those poses (e.g. the nominal ones).
        measured_m: Shape (N, t, 3): measured target positions in K [m].
        targets_m: Shape (t, 3): targets in the platform frame [m].
        prior_sigma: Shape (p,): prior σ of each controller parameter (MAP); None: least squares on
            the base parameters.

    Raises:
        InvalidRequestError: the shapes disagree.
        IdentificationError: the model cannot be solved at a pose during the iterations.
    """
    N = len(commands)
    targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
    measured = np.asarray(measured_m, dtype=float)
    if measured.shape != (N, targets.shape[0], 3) or H.shape[0] != measured.size:
        raise InvalidRequestError(
            f"measurements of shape {measured.shape} and a Jacobian of {H.shape[0]} rows do not fit "
            f"{N} poses × {targets.shape[0]} targets × 3 coordinates"
        )
    tracker = TrackerPoints(targets, ident.noise_m)
    out = _gauss_newton(
        mechanism,
        pset,
        ident,
        tracker,
        np.zeros(N, dtype=int),
        commands,
        q_guess,
        measured.reshape(N, -1),
        H,
        np.zeros((H.shape[0], 0)),
        np.ones(H.shape[0]),
        prior_sigma,
    )
    return _reshaped(out, (N, targets.shape[0], 3))


def identify_with(
    mechanism: Mechanism,
    pset: ParameterSet,
    ident: Identifiability,
    maps: PoseMaps,
    instrument: Instrument,
    measured: np.ndarray,
    prior_sigma: np.ndarray | None = None,
) -> Identification:
    """Fit the controller model and the instrument's nuisance parameters to any instrument's data.

    The instrument first fixes where to linearise (:meth:`Instrument.start`: a tracker frame is
    registered in closed form); the frozen Jacobian is its twist rows times the nominal twist maps
    and its nuisance rows there, every value whitened by its σ to ``ident.noise_m``.

    Args:
        mechanism: The nominal mechanism.
        pset: Its parameter set.
        ident: The base parameters of the controller model (on the projected system).
        maps: The nominal maps at the measured poses (commands, joints, twists, stations).
        instrument: The measurement model.
        measured: Shape (N, r): the measured values [m or rad].
        prior_sigma: The MAP prior of each controller parameter (None: least squares).

    Raises:
        InvalidRequestError: the shapes disagree, or the data cannot start the instrument.
        IdentificationError: the model cannot be solved at a pose during the iterations.
    """
    N, r = len(maps), instrument.values_per_pose
    y = np.asarray(measured, dtype=float)
    if y.shape != (N, r):
        raise InvalidRequestError(f"measurements of shape {y.shape} do not fit {N} poses × {r} values")
    nominal = Machine(mechanism, pset, np.zeros(len(pset)))
    origin, rot, q0 = machine_poses(nominal, maps.commands, maps.q)
    inst, pi0 = instrument.start(y, origin, rot, maps.station_index)
    st = maps.station_index

    def rows_at(o: np.ndarray, R: np.ndarray, pi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rows = inst.twist_rows(o, R, st, pi)
        H = np.einsum("kra,kan->krn", rows, maps.measurement_twist).reshape(N * r, -1)
        return H, inst.nuisance_rows(o, R, st, pi).reshape(N * r, -1)

    H, Hp = rows_at(origin, rot, pi0)
    w = value_weights(inst, N, ident.noise_m)
    refresh = rows_at if inst.refresh_rows else None
    return _gauss_newton(
        mechanism, pset, ident, inst, st, maps.commands, q0, y, H, Hp, w, prior_sigma, pi0, refresh
    )


def _reshaped(out: Identification, shape: tuple[int, ...]) -> Identification:
    return Identification(
        method=out.method,
        names=out.names,
        identified=out.identified,
        covariance=out.covariance,
        estimate=out.estimate,
        residuals_m=out.residuals_m.reshape(shape),
        residuals_before_m=out.residuals_before_m.reshape(shape),
        iterations=out.iterations,
        converged=out.converged,
        q=out.q,
        nuisance=out.nuisance,
        nuisance_covariance=out.nuisance_covariance,
        instrument=out.instrument,
        weighted_rms=out.weighted_rms,
    )


def _gauss_newton(
    mechanism: Mechanism,
    pset: ParameterSet,
    ident: Identifiability,
    inst: Instrument,
    stations: np.ndarray,
    commands: np.ndarray,
    q_guess: np.ndarray,
    measured: np.ndarray,
    H: np.ndarray,
    Hp: np.ndarray,
    weights: np.ndarray,
    prior_sigma: np.ndarray | None,
    pi0: np.ndarray | None = None,
    refresh: Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
) -> Identification:
    """Gauss–Newton with the Jacobian ``[W H_x, W H_π]`` (whitened); residuals (N, r) raw.

    The Jacobian is frozen at the start, or (``refresh``) the instrument's rows are re-evaluated
    at every accepted iterate's platform poses and nuisance, times the nominal twist maps.
    """
    n, q_n = len(pset), Hp.shape[1]
    if prior_sigma is None:
        method, cols, scale, names = (
            "least-squares",
            ident.base_columns,
            ident.scale[ident.base],
            ident.base_names,
        )
        prior_precision = np.zeros(cols.size)
    else:
        method, cols, scale, names = "map", ident.columns, ident.scale, list(ident.names)
        prior = np.asarray(prior_sigma, dtype=float)
        if prior.shape != (cols.size,) or np.any(~(prior > 0)):
            raise InvalidRequestError(
                f"prior_sigma needs {cols.size} positive values (one per controller parameter), "
                f"got shape {prior.shape}"
            )
        prior_precision = ident.noise_m**2 / prior**2  # relative to the (whitened) measurement precision
    root = np.concatenate([np.sqrt(prior_precision), np.zeros(q_n)])

    def system(H_: np.ndarray, Hp_: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        J = np.concatenate([H_[:, cols], Hp_], axis=1) * weights[:, None]
        J_aug_ = np.concatenate([J, np.diag(root)[root > 0]], axis=0)
        return J_aug_, linalg.pinv(J_aug_)

    J_aug, J_pinv = system(H, Hp)
    std_all = ident.noise_m * np.sqrt(np.clip(np.diag(linalg.pinvh(J_aug.T @ J_aug)), 0.0, None))
    # steps below STEP_OF_STD of the noise of their estimate end the iteration (nuisance only)
    settle = np.where(std_all > 0, STEP_OF_STD * std_all, 0.0) if q_n else np.zeros_like(std_all)

    def noisy(c: float) -> bool:
        """With nuisance parameters, whether the residuals show the noise (RMS ≥ NOISY of σ_m, whitened).

        Only then is an estimate's standard deviation what it knows; noise-free data are iterated
        to :data:`STEP_TOLERANCE`.
        """
        return bool(q_n) and np.sqrt(c / max(measured.size, 1)) >= NOISY * ident.noise_m

    poses_now: list[tuple[np.ndarray, np.ndarray]] = []
    all_scale = np.concatenate([scale, np.asarray(inst.nuisance_scale, dtype=float)])
    pi_start = np.zeros(q_n) if pi0 is None else np.asarray(pi0, dtype=float)

    def evaluate(x: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        delta = np.zeros(n)
        delta[cols] = x[: cols.size]
        origin, rot, q_new = machine_poses(Machine(mechanism, pset, delta), commands, q0)
        poses_now.append((origin, rot))
        model = inst.measure(origin, rot, stations, pi_start + x[cols.size :])
        res = inst.residual(measured, model)
        xm = x[: cols.size]
        cost = float(np.sum((res.reshape(-1) * weights) ** 2) + np.sum(prior_precision * xm**2))
        return res, q_new, cost

    # the exact solves stop at a 1e-13 residual: costs closer than that to zero cannot be compared
    floor = max(1e-28, measured.size * (SOLVE_NOISE * float(np.max(weights, initial=1.0))) ** 2)
    x = np.zeros(cols.size + q_n)
    resid, q, cost = evaluate(x, q_guess)
    before = resid.copy()
    converged = False
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        rhs = np.concatenate([resid.reshape(-1) * weights, -(root * x)[root > 0]])
        step = J_pinv @ rhs
        full_step = step
        accepted = False
        for _ in range(MAX_HALVINGS + 1):
            x_new = x + step
            try:
                resid_new, q_new, new_cost = evaluate(x_new, q)
            except IdentificationError:
                step = step / 2
                continue
            # the frozen Jacobian's fixed point is not exactly the cost's minimum (they differ at
            # second order): only a clear rise of the cost is a divergence
            if new_cost <= cost * (1 + COST_RISE) + floor:
                accepted = True
                break
            step = step / 2
        if not accepted and q_n:
            # instruments with nuisance parameters: Levenberg–Marquardt damping of the weak
            # directions, where the nominal machine Jacobian is least exact
            u_, s_, vt_ = np.linalg.svd(J_aug, full_matrices=False)
            proj = u_.T @ rhs
            for lam in DAMPING:
                step = vt_.T @ (s_ / (s_**2 + lam * s_[0] ** 2) * proj)
                try:
                    resid_new, q_new, new_cost = evaluate(x + step, q)
                except IdentificationError:
                    continue
                if new_cost <= cost * (1 + COST_RISE) + floor:
                    accepted, x_new = True, x + step
                    break
        if not accepted:
            # at the optimum to the noise: the step the Jacobian offers would change the fitted
            # values by less than FIT_CHANGE σ in all (nuisance instruments only)
            if noisy(cost) and float(np.linalg.norm(J_aug @ full_step)) <= FIT_CHANGE * ident.noise_m:
                converged = True
            if it == 1 and cost > 0:
                raise IdentificationError(
                    f"Gauss–Newton found no step that lowers the residual (RMS "
                    f"{np.sqrt(np.mean(resid**2)) * 1e3:.4g} mm against the nominal model); the "
                    "measurements may not belong to these commands, or the errors are too large for "
                    "the nominal Jacobian"
                )
            break
        x, q, resid, cost = x_new, q_new, resid_new, new_cost
        if np.max(np.abs(step) / all_scale) < STEP_TOLERANCE or (
            noisy(cost) and np.all(np.abs(step) <= settle)
        ):
            converged = True
            break
        if refresh is not None:
            J_aug, J_pinv = system(*refresh(*poses_now[-1], pi_start + x[cols.size :]))
    estimate = np.zeros(n)
    estimate[cols] = x[: cols.size]
    cov = ident.noise_m**2 * linalg.pinvh(J_aug.T @ J_aug)
    p = cols.size
    return Identification(
        method=method,
        names=tuple(names),
        identified=x[:p],
        covariance=cov[:p, :p],
        estimate=estimate,
        residuals_m=resid,
        residuals_before_m=before,
        iterations=it,
        converged=converged,
        q=q,
        nuisance=pi_start + x[p:],
        nuisance_covariance=cov[p:, p:],
        instrument=inst,
        weighted_rms=float(np.sqrt(np.mean((resid.reshape(-1) * weights / max(ident.noise_m, 1e-300)) ** 2))),
    )
