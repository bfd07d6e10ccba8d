"""Hand a toleranced machine to Pinocchio's constrained dynamics: allocate, perturb, one step of motion.

1. load a mechanism (default: the seed robot written as MJCF, ``tests/data/r2rps_ups_mjcf``, whose
   geoms give every body a mass);
2. allocate its tolerances (``pkmtol.allocate``; small sample counts by default);
3. draw one machine at those tolerances: every toleranced (uncompensatable) error Gaussian with
   its design-β tolerance as standard deviation, and assemble it at the design point (actuators at
   their nominal values plus the Eq. 25 correction) with pkmtol's exact closed chain;
4. export that machine as one ``pin.Model`` plus a ``FrameAnchorConstraintModel`` per loop
   (``Mechanism.constraint_models``), convert them to the ``RigidConstraintModel``s that
   ``pin.constraintDynamics`` takes, and run one step: the machine at rest, gravity along −z, a
   push on every actuator.

It prints the closure residuals of the assembled machine (on the nominal and on the perturbed
constraints), the accelerations, the loop forces, and the state after one semi-implicit Euler step.

Usage:
    python scripts/example_constrained_dynamics.py [ROBOT] [--samples N] [--push N] [--dt S] [--seed S]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from pkmtol import ClosedChain, DesignOptions, DesignResult, Mechanism, allocate, load_mechanism
from pkmtol.design.verification import sample_errors
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.constraints import ConstrainedModel

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_ROBOT = ROOT / "tests" / "data" / "r2rps_ups_mjcf"


@dataclass(frozen=True)
class Machine:
    """One drawn machine, assembled at the design point.

    Attributes:
        eta: The drawn error parameters (n,) [m, rad] (zero where no tolerance was allocated).
        models: The perturbed limb models.
        q: The assembled machine's actual joint values, per limb (nq_i,) [rad or m].
        p_m: Where its P is, in K (3,) [m].
        p_nominal_m: Where the nominal machine's P is (the design point) (3,) [m].
    """

    eta: np.ndarray
    models: list[pin.Model]
    q: tuple[np.ndarray, ...]
    p_m: np.ndarray
    p_nominal_m: np.ndarray


@dataclass(frozen=True)
class Step:
    """One step of the constrained motion from rest.

    Attributes:
        tau: Joint forces applied (nv,) [N or N·m].
        a: Joint accelerations from ``pin.constraintDynamics`` (nv,) [m/s² or rad/s²].
        lambda_c: Loop forces, 6 per loop in Pinocchio's legacy constraint frame (6·(L−1),) [N, N·m].
        a_p: Acceleration of P in K (3,) [m/s²].
        constraint_acceleration: ``J a``, FrameAnchor Jacobian (6·(L−1),); zero: the loops stay closed.
        q_next: Joint values after one step of ``dt`` (nq,).
        p_move_m: How far P moved in that step, in K (3,) [m].
        residual_next: Pinocchio's closure residuals at ``q_next`` (6·(L−1),) [m, rad].
    """

    tau: np.ndarray
    a: np.ndarray
    lambda_c: np.ndarray
    a_p: np.ndarray
    constraint_acceleration: np.ndarray
    q_next: np.ndarray
    p_move_m: np.ndarray
    residual_next: np.ndarray


def draw_machine(mech: Mechanism, result: DesignResult, seed: int) -> Machine:
    """A machine with Gaussian errors at the design-β tolerances, assembled at the design point."""
    sigma = result.tolerances[:, result.design_column].copy()
    sigma[~np.isfinite(sigma)] = 0.0  # not allocated (nan) or free (inf): no error drawn
    eta = sample_errors("gaussian", sigma, 1, np.random.default_rng(seed))[0]
    eps, offsets = result.pset.perturbation(eta, mech)
    models = perturbed_limb_models(mech, eps)
    pose = result.grid.poses[result.worst_index]
    sep = result.grid.separations[result.worst_index]
    chain = ClosedChain(mech, models=models, check_limits=False)
    u = pose.q_all[chain.actuated_idx] + sep.correction @ eta
    actual = chain.forward(u, pose.q_all, offsets)
    return Machine(eta=eta, models=models, q=actual.q, p_m=actual.p_m, p_nominal_m=pose.p_m)


def one_step(cm: ConstrainedModel, q: np.ndarray, push: float, dt: float, p_ref: np.ndarray) -> Step:
    """One step from rest at ``q``: gravity −z, ``push`` on every actuator, ``pin.constraintDynamics``."""
    model, data = cm.model, cm.model.createData()
    rigid = pin.StdVec_RigidConstraintModel()
    for r in cm.rigid_constraints():
        rigid.append(r)
    rdatas = pin.StdVec_RigidConstraintData()
    for r in rigid:
        rdatas.append(r.createData())
    pin.initConstraintDynamics(model, data, rigid, rdatas)
    v = np.zeros(model.nv)
    tau = np.zeros(model.nv)
    tau[list(cm.actuated)] = push
    a = pin.constraintDynamics(model, data, q, v, tau, rigid, rdatas, pin.ProximalSettings(1e-12, 1e-12, 50))
    lam = np.array(data.lambda_c)
    # acceleration of P: platform frame's classical acceleration, plus α × (R p_ref) (at rest, ω = 0)
    pin.forwardKinematics(model, data, q, v, a)
    pin.updateFramePlacements(model, data)
    frame = cm.platform_frame
    acc = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
    lever = data.oMf[frame].rotation @ p_ref
    a_p = acc.linear + np.cross(acc.angular, lever)
    p_now = data.oMf[frame].act(p_ref)
    v_next = v + dt * a  # semi-implicit Euler
    q_next = pin.integrate(model, q, dt * v_next)
    pin.framesForwardKinematics(model, data, q_next)
    p_move = data.oMf[frame].act(p_ref) - p_now
    return Step(
        tau=tau,
        a=np.array(a),
        lambda_c=lam,
        a_p=a_p,
        constraint_acceleration=cm.jacobian(q) @ a,
        q_next=q_next,
        p_move_m=p_move,
        residual_next=cm.residuals(q_next),
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("robot", nargs="?", type=Path, default=DEFAULT_ROBOT, help="robot folder")
    ap.add_argument("--samples", type=int, default=300, help="Monte Carlo samples of the allocation")
    ap.add_argument("--exact-samples", type=int, default=4, help="exact-kinematics verification samples")
    ap.add_argument("--push", type=float, default=100.0, help="force on every actuator [N or N·m]")
    ap.add_argument("--dt", type=float, default=1e-3, help="time step [s]")
    ap.add_argument("--seed", type=int, default=1, help="seed of the drawn machine")
    args = ap.parse_args(argv)
    mech = load_mechanism(args.robot)
    cm = mech.constraint_models()
    mass = pin.computeTotalMass(cm.model)
    if not mass > 0:
        print(
            f"error: {mech.name} has no mass (its links carry no inertia): constrained dynamics needs "
            f"inertias; give its links <inertial> elements, or use {DEFAULT_ROBOT.relative_to(ROOT)}",
            file=sys.stderr,
        )
        return 2
    print(
        f"{mech.name}: {len(mech.limbs)} limbs, {mech.n_joints} joints, {mech.n_actuators} actuators, "
        f"{mass:.3f} kg -> one pin.Model (nq = {cm.model.nq}) + {len(cm.constraints)} "
        f"{type(cm.constraints[0]).__name__}s"
    )
    options = DesignOptions(
        parameter_set="urdf",
        samples=args.samples,
        verification_poses=20,
        exact_samples=args.exact_samples,
        claim_poses=10,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy quadrature round-off notes
        result = allocate(mech, options)
    col = result.design_column
    unc = result.uncompensatable
    tol = result.tolerances[unc, col]
    print(
        f"allocation at beta = {result.betas[col]:g}: {unc.size} uncompensatable errors toleranced, "
        f"sigma from {np.min(tol) * 1e6:.2f} to {np.max(tol[np.isfinite(tol)]) * 1e6:.2f} (um or urad)"
    )
    machine = draw_machine(mech, result, args.seed)
    print(
        f"drawn machine (seed {args.seed}): |eta| = {np.linalg.norm(machine.eta) * 1e6:.2f} (um, urad), "
        f"assembled at the design point P = {np.round(machine.p_nominal_m * 1e3, 1)} mm; "
        f"its P is {np.linalg.norm(machine.p_m - machine.p_nominal_m) * 1e6:.3f} um away"
    )
    perturbed = mech.constraint_models(machine.models)
    q = perturbed.q(machine.q)
    print(
        "closure residual of its joint values, max |log6| (Pinocchio): "
        f"nominal constraints {np.max(np.abs(cm.residuals(q))):.2e}, "
        f"perturbed constraints {np.max(np.abs(perturbed.residuals(q))):.2e}"
    )
    step = one_step(perturbed, q, args.push, args.dt, mech.reference_point_m)
    print(f"pin.constraintDynamics, at rest, gravity -z, {args.push:g} N (or N m) on every actuator:")
    names = [perturbed.model.names[1 + k] for k in perturbed.actuated]
    print(
        "  actuator accelerations: "
        + ", ".join(f"{n} {step.a[k]:+.4f}" for n, k in zip(names, perturbed.actuated, strict=True))
    )
    print(f"  acceleration of P in K [m/s^2]: {np.array2string(step.a_p, precision=4, sign='+')}")
    for k, c in enumerate(perturbed.constraints):
        f = step.lambda_c[6 * k : 6 * k + 6]
        print(
            f"  loop force {c.name}: |f| = {np.linalg.norm(f[:3]):.3f} N, "
            f"|tau| = {np.linalg.norm(f[3:]):.3f} N m"
        )
    print(f"  max |J a| (FrameAnchor Jacobian): {np.max(np.abs(step.constraint_acceleration)):.2e}")
    print(
        f"after one step of {args.dt:g} s: P moved {np.linalg.norm(step.p_move_m) * 1e6:.3f} um, "
        f"closure residual max |log6| {np.max(np.abs(step.residual_next)):.2e}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
