"""The Gauss–Newton iteration of the identification, and its result.

Every residual is a measured value minus the exact model of the mechanism perturbed by the current
estimate, at the commanded actuator readings (:class:`Machine`). The iteration starts on the error
model's analytic Jacobian at the nominal point, frozen: it is then a contraction whose rate is the
relative change of the Jacobian over the estimate (about ``|δ|/|link|``, 1e-3 for 0.1 mm errors
on a 0.5 m machine), it needs no finite differences, and it cannot jitter (DESIGN.md, "Pitfalls").
A step that raises the residual is halved.

On an ill-conditioned plan the frozen Jacobian's fixed point is not the least-squares optimum:
the Jacobian's error is amplified in the weak directions (the Delta's 53-parameter full plan,
smallest singular value 1e-4 of the largest, stopped 0.6–1.9 σ away, or crept to the iteration
limit). So a stop is *certified* on the analytic Jacobian at the estimate
(:mod:`pkmtol.calibration.estimate_maps`): converged when one more Gauss–Newton step on it would
lower the χ² by at most :data:`CERTIFY_CHI2`; otherwise the iteration goes on with that Jacobian,
re-evaluated at every accepted iterate. It also switches to it early, when the frozen Jacobian
mispredicts its own step (:data:`GAIN_RATIO`). Noise-free data are iterated to
:data:`STEP_TOLERANCE`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy import linalg

from pkmtol.calibration.identifiability import Identifiability
from pkmtol.calibration.instruments.base import Instrument
from pkmtol.calibration.machine import Machine
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import IdentificationError, InvalidRequestError
from pkmtol.kinematics.solutions import Solutions
from pkmtol.model.mechanism import Mechanism

if TYPE_CHECKING:
    from pkmtol.calibration.hybrid_machine import HybridSolutions

#: A Jacobian: the whitened values' rows per unit parameter (M, n) and per unit nuisance (M, q).
Rows = tuple[np.ndarray, np.ndarray]
#: The rows on the Jacobian at an estimate, from its machine, solved poses and nuisance (None: none).
EstimateRows = Callable[[Machine, Solutions, np.ndarray], Rows | None]

#: Stop when every step component is below this fraction of its parameter's scale (1e-12 m for a
#: 0.1 mm scale: the exact solves themselves stop at a 1e-13 residual).
STEP_TOLERANCE = 1e-8
#: A step that raises the cost by more than this (relative) is halved.
COST_RISE = 1e-6
MAX_ITERATIONS = 60
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
#: A stop of the iteration is certified when a Gauss–Newton step on the Jacobian at the estimate
#: would lower the χ² by at most this [σ_m²]: the estimate is then within √0.1 = 0.3 σ of the
#: least-squares optimum along every direction, far inside its own spread. When the residuals exceed
#: the noise (errors outside the controller model), σ_m² is replaced by the fit's reduced χ².
CERTIFY_CHI2 = 0.1
#: Certificates tried before the result is given as it stands (each continues the iteration on
#: the Jacobian at the estimate when it fails).
MAX_CERTIFICATES = 4
#: The frozen iteration is certified as soon as an accepted step lowers the χ² by less than this
#: [σ_m²] (it creeps: the nominal Jacobian's error, not the data, sets its pace there).
CREEP = 1.0
#: ... and left for the Jacobian at the estimate as soon as a step must be halved, or lowers the χ²
#: by less than this fraction of what the frozen Jacobian predicted for it.
GAIN_RATIO = 0.5
#: Levenberg–Marquardt on the Jacobian at the estimate: a step is taken when it realises at least
#: this fraction of the decrease its linear model predicts; the first damping tried after a miss.
LM_RATIO = 0.25
LM_START = 1e-10
#: Singular values below this fraction of the largest are directions the data do not resolve: the
#: cost is not quadratic over their spread (a 1e-5 direction of the Tricept's probe plan offered
#: 0.5 σ² to a step that raised the cost by 77 σ²). A stop is certified on the others.
LM_RESOLVED = 1e-4
#: Dampings tried in one iteration (each LM_FACTOR times the last) before it stops; the damping is
#: divided by LM_FACTOR after a step is taken.
MAX_DAMPINGS = 24
LM_FACTOR = 3.0


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


def solved_poses(machine: Machine, commands: np.ndarray, q0: np.ndarray) -> Solutions | HybridSolutions:
    """``machine.forward_many(commands, q0)``, every pose solved.

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
    return sols


def gauss_newton(
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
    refresh: Callable[[np.ndarray, np.ndarray, np.ndarray], Rows] | None = None,
    at_estimate: EstimateRows | None = None,
) -> Identification:
    """Gauss–Newton with the Jacobian ``[W H_x, W H_π]`` (whitened); residuals (N, r) raw.

    The Jacobian is frozen at the start, or (``refresh``) the instrument's rows are re-evaluated
    at every accepted iterate's platform poses and nuisance, times the nominal twist maps. When
    the frozen iteration stops, ``at_estimate`` (the analytic Jacobian of the machine at the
    estimate, :mod:`pkmtol.calibration.estimate_maps`) certifies the stop: converged when a
    Gauss–Newton step on it would lower the χ² by at most :data:`CERTIFY_CHI2`; otherwise the
    iteration goes on with the Jacobian at the estimate, re-evaluated at every accepted iterate.
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
        return bool(q_n) and shows_noise(c)

    def certify_level(c: float) -> float:
        """The cost decrease [m²] below which a stop is certified at cost ``c``.

        :data:`CERTIFY_CHI2` σ_m², scaled by the reduced χ² when the residuals exceed the noise
        (errors the controller model does not hold: the fit's own scatter is then the yardstick).
        """
        dof = max(measured.size - cols.size - q_n, 1)
        return CERTIFY_CHI2 * max(ident.noise_m**2, c / dof)

    def shows_noise(c: float) -> bool:
        """Whether the residuals show the noise (whitened RMS ≥ :data:`NOISY` of σ_m)."""
        return bool(np.sqrt(c / max(measured.size, 1)) >= NOISY * ident.noise_m)

    solved: list[tuple[Machine, Solutions]] = []
    all_scale = np.concatenate([scale, np.asarray(inst.nuisance_scale, dtype=float)])
    pi_start = np.zeros(q_n) if pi0 is None else np.asarray(pi0, dtype=float)

    def evaluate(x: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        delta = np.zeros(n)
        delta[cols] = x[: cols.size]
        machine = Machine(mechanism, pset, delta)
        sols = solved_poses(machine, commands, q0)
        solved[:] = [(machine, sols)]  # type: ignore[list-item]  # only the last evaluation is read
        model = inst.measure(sols.translation, sols.rotation, stations, pi_start + x[cols.size :])
        res = inst.residual(measured, model)
        xm = x[: cols.size]
        cost = float(np.sum((res.reshape(-1) * weights) ** 2) + np.sum(prior_precision * xm**2))
        return res, sols.q, cost

    def relinearised(state: tuple[Machine, Solutions], x: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The system on the Jacobian at the accepted iterate ``x`` (its machine and poses; None: none)."""
        if at_estimate is None:
            return None
        rows = at_estimate(*state, pi_start + x[cols.size :])
        return None if rows is None else system(*rows)

    def offered_chi2(x: np.ndarray, J_: np.ndarray, J_pinv_: np.ndarray) -> tuple[float, np.ndarray]:
        """What one Gauss–Newton step on ``J_`` would lower the cost by [σ_m²], and the step."""
        rhs_ = np.concatenate([resid.reshape(-1) * weights, -(root * x)[root > 0]])
        step_ = J_pinv_ @ rhs_
        return float(np.sum((J_ @ step_) ** 2)) / ident.noise_m**2, step_

    # the exact solves stop at a 1e-13 residual: costs closer than that to zero cannot be compared
    floor = max(1e-28, measured.size * (SOLVE_NOISE * float(np.max(weights, initial=1.0))) ** 2)
    x = np.zeros(cols.size + q_n)
    resid, q, cost = evaluate(x, q_guess)
    before = resid.copy()
    current = solved[-1]  # the machine and poses of the accepted iterate
    converged = False
    exact_jacobian = False  # iterating on the Jacobian at the estimate
    jacobian_at_x = True  # J_aug is the Jacobian at x (the nominal one at the start)
    certificates = 0
    damping = 0.0  # Levenberg–Marquardt's, relative to the largest singular value squared
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        rhs = np.concatenate([resid.reshape(-1) * weights, -(root * x)[root > 0]])
        step = J_pinv @ rhs
        full_step = step
        if exact_jacobian and jacobian_at_x and shows_noise(cost):
            # on the Jacobian at the estimate: stationary to CERTIFY_CHI2 (noise-free data go on
            # to STEP_TOLERANCE)
            if float(np.sum((J_aug @ step) ** 2)) <= certify_level(cost):
                converged = True
                break
        accepted = resolved = False
        if exact_jacobian:
            # on the Jacobian at the estimate: Levenberg–Marquardt, the damping kept between
            # iterations (a trust region): the weak directions are where the cost is least
            # quadratic, and halving the whole step there starves the strong ones
            u_, s_, vt_ = np.linalg.svd(J_aug, full_matrices=False)
            proj = u_.T @ rhs
            for _ in range(MAX_DAMPINGS):
                step = vt_.T @ (s_ / (s_**2 + damping * s_[0] ** 2) * proj)
                predicted = float(2 * step @ (J_aug.T @ rhs) - np.sum((J_aug @ step) ** 2))
                try:
                    resid_new, q_new, new_cost = evaluate(x + step, q)
                except IdentificationError:
                    damping = max(LM_FACTOR * damping, LM_START)
                    continue
                if new_cost <= cost * (1 + COST_RISE) + floor and cost - new_cost >= LM_RATIO * predicted:
                    accepted, x_new = True, x + step
                    # stationary in the directions the data resolve: the step, damped only below
                    # LM_RESOLVED of the largest singular value, offered at most CERTIFY_CHI2
                    resolved = damping <= LM_RESOLVED**2 and predicted <= certify_level(cost)
                    damping /= LM_FACTOR
                    break
                damping = max(LM_FACTOR * damping, LM_START)
        for _ in range(0 if exact_jacobian else MAX_HALVINGS + 1):
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
        if not accepted and q_n and not exact_jacobian:
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
        if accepted:
            gain = cost - new_cost
            x, q, resid, cost = x_new, q_new, resid_new, new_cost
            current, jacobian_at_x = solved[-1], False
            if resolved and shows_noise(cost):
                converged = True
                break
            stopped = bool(
                np.max(np.abs(step) / all_scale) < STEP_TOLERANCE
                or (noisy(cost) and np.all(np.abs(step) <= settle))
                # the frozen iteration creeps: a step buys less than CREEP σ² of the χ²
                or (
                    not exact_jacobian
                    and at_estimate is not None
                    and shows_noise(cost)
                    and gain < CREEP * ident.noise_m**2
                )
            )
            if (
                not exact_jacobian
                and at_estimate is not None
                and (step is not full_step or gain < GAIN_RATIO * float(np.sum((J_aug @ full_step) ** 2)))
            ):
                # the frozen Jacobian mispredicts its own step: go on with the one at the estimate
                exact_jacobian = True
            if not stopped:
                if exact_jacobian:
                    system_now = relinearised(current, x)
                    if system_now is not None:
                        (J_aug, J_pinv), jacobian_at_x = system_now, True
                elif refresh is not None:
                    at = current[1]
                    J_aug, J_pinv = system(*refresh(at.translation, at.rotation, pi_start + x[cols.size :]))
                continue
        # the iteration stopped: certify the stop on the Jacobian at the estimate
        if not jacobian_at_x and certificates < MAX_CERTIFICATES:
            system_now = relinearised(current, x)
            if system_now is not None:
                certificates += 1
                (J_aug, J_pinv), jacobian_at_x = system_now, True
                chi2, exact_step = offered_chi2(x, J_aug, J_pinv)
                if (chi2 * ident.noise_m**2 <= certify_level(cost) and shows_noise(cost)) or np.max(
                    np.abs(exact_step) / all_scale
                ) < STEP_TOLERANCE:
                    converged = True
                    break
                exact_jacobian = True  # go on with the Jacobian at the estimate
                continue
        if accepted:
            converged = True
        elif certificates and jacobian_at_x:
            # no halving of the step on the Jacobian at the estimate lowers the cost: stationary
            # when that step offers less than CERTIFY_CHI2 (or nothing the solves can resolve)
            converged = offered_chi2(x, J_aug, J_pinv)[0] * ident.noise_m**2 <= certify_level(cost)
        elif noisy(cost) and float(np.linalg.norm(J_aug @ full_step)) <= FIT_CHANGE * ident.noise_m:
            # at the optimum to the noise: the step the Jacobian offers would change the fitted
            # values by less than FIT_CHANGE σ in all (nuisance instruments only)
            converged = True
        elif it == 1 and cost > 0:
            raise IdentificationError(
                f"Gauss–Newton found no step that lowers the residual (RMS "
                f"{np.sqrt(np.mean(resid**2)) * 1e3:.4g} mm against the nominal model); the "
                "measurements may not belong to these commands, or the errors are too large for "
                "the nominal Jacobian"
            )
        break
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
