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

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from pkmtol.calibration.identifiability import Identifiability
from pkmtol.calibration.machine import Machine
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.exceptions import IdentificationError, InvalidRequestError
from pkmtol.model.mechanism import Mechanism

#: Stop when every step component is below this fraction of its parameter's scale (1e-12 m for a
#: 0.1 mm scale: the exact solves themselves stop at a 1e-13 residual).
STEP_TOLERANCE = 1e-8
#: A step that raises the cost by more than this (relative) is halved.
COST_RISE = 1e-6
MAX_ITERATIONS = 30
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

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each estimated quantity [SI]."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def rms_before_m(self) -> float:
        """RMS of the measured coordinates' residuals against the nominal model [m]."""
        return float(np.sqrt(np.mean(self.residuals_before_m**2)))

    @property
    def rms_after_m(self) -> float:
        """RMS of the residuals at the estimate [m]."""
        return float(np.sqrt(np.mean(self.residuals_m**2)))


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
    """Fit the controller model to measured target positions by Gauss–Newton on exact kinematics.

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
    n = len(pset)
    noise2 = ident.noise_m**2
    if prior_sigma is None:
        method, cols, scale, names = (
            "least-squares",
            ident.base_columns,
            ident.scale[ident.base],
            ident.base_names,
        )
        Hx = H[:, cols]
        prior_precision = np.zeros((cols.size, cols.size))
        normal = Hx.T @ Hx
        q_h, r_h = linalg.qr(Hx, mode="economic")  # base columns: full column rank

        def step_for(rvec: np.ndarray, x: np.ndarray) -> np.ndarray:
            return np.asarray(linalg.solve_triangular(r_h, q_h.T @ rvec))

    else:
        method, cols, scale, names = "map", ident.columns, ident.scale, list(ident.names)
        prior = np.asarray(prior_sigma, dtype=float)
        if prior.shape != (cols.size,) or np.any(~(prior > 0)):
            raise InvalidRequestError(
                f"prior_sigma needs {cols.size} positive values (one per controller parameter), "
                f"got shape {prior.shape}"
            )
        Hx = H[:, cols]
        prior_precision = np.diag(noise2 / prior**2)  # relative to the measurement precision
        normal = Hx.T @ Hx + prior_precision
        factor = linalg.cho_factor(normal)

        def step_for(rvec: np.ndarray, x: np.ndarray) -> np.ndarray:
            return np.asarray(linalg.cho_solve(factor, Hx.T @ rvec - prior_precision @ x))

    x = np.zeros(cols.size)
    machine = Machine(mechanism, pset, np.zeros(n))
    pos, q = model_positions(machine, commands, q_guess, targets)
    resid = measured - pos
    before = resid.copy()
    cost = float(np.sum(resid**2))
    converged = False
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        step = step_for(resid.reshape(-1), x)
        accepted = False
        for _ in range(MAX_HALVINGS + 1):
            x_new = x + step
            delta = np.zeros(n)
            delta[cols] = x_new
            try:
                pos_new, q_new = model_positions(Machine(mechanism, pset, delta), commands, q, targets)
            except IdentificationError:
                step = step / 2
                continue
            resid_new = measured - pos_new
            new_cost = float(np.sum(resid_new**2) + x_new @ prior_precision @ x_new)
            # the frozen Jacobian's fixed point is not exactly the cost's minimum (they differ at
            # second order): only a clear rise of the cost is a divergence
            if new_cost <= cost * (1 + COST_RISE) + 1e-28:
                accepted = True
                break
            step = step / 2
        if not accepted:
            if it == 1 and cost > 0:
                raise IdentificationError(
                    f"Gauss–Newton found no step that lowers the residual (RMS "
                    f"{np.sqrt(cost / resid.size) * 1e3:.4g} mm against the nominal model); the "
                    "measurements may not belong to these commands, or the errors are too large for "
                    "the nominal Jacobian"
                )
            break
        x, q, resid, cost = x_new, q_new, resid_new, new_cost
        if np.max(np.abs(step) / scale) < STEP_TOLERANCE:
            converged = True
            break
    estimate = np.zeros(n)
    estimate[cols] = x
    covariance = noise2 * linalg.pinvh(normal)
    return Identification(
        method=method,
        names=tuple(names),
        identified=x,
        covariance=covariance,
        estimate=estimate,
        residuals_m=resid,
        residuals_before_m=before,
        iterations=it,
        converged=converged,
        q=q,
    )
