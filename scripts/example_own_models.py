"""Your own ``pin.Model`` limbs → ``Mechanism.from_models`` → tolerance table.

A Tricept-like 3-UPS&UP mechanism built joint by joint in Python (no URDF): three actuated UPS
legs around a passive UP column that carries the platform. Every limb starts at the base frame K
and ends in a frame called ``platform``; at home the platform frame O' is at (0, 0, 0.8) m with the
axes of K, which fixes the legs' joint values there. The tolerance table (the paper's Table III) is
printed for Δλ* = 0.05 mm at P = O' + (0, 0, 0.2) m.

Usage:
    python scripts/example_own_models.py                 # 10^4 Monte Carlo samples
    python scripts/example_own_models.py --samples 500   # quicker
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pinocchio as pin

from pkmtol import DesignOptions, Mechanism, TaskSpace, allocate
from pkmtol.present.tables import table_rows, text_table

BASE_RADIUS_M = 0.5  # UPS universal joints on a circle in the base plane
PLATFORM_RADIUS_M = 0.2  # UPS spherical joints on a circle in the platform plane
HOME_HEIGHT_M = 0.8  # O' above the base at home
DEG = math.pi / 180.0


def add_revolute(
    model: pin.Model,
    parent: int,
    joint: pin.JointModel,
    placement: pin.SE3,
    name: str,
    lower: float,
    upper: float,
) -> int:
    """Add a 1-DOF joint with position limits [rad or m] and a massless body."""
    jid = model.addJoint(
        parent, joint, placement, name, np.array([1e3]), np.array([1.0]), np.array([lower]), np.array([upper])
    )
    model.appendBodyToJoint(jid, pin.Inertia.Zero(), pin.SE3.Identity())
    model.addJointFrame(jid)
    return jid


def ups_leg(k: int) -> tuple[pin.Model, list[float]]:
    """UPS leg k (0, 1, 2): U at the base circle, P along the leg, S at the platform circle.

    Returns the model and the joint values at home. The universal joint is RX·RY, so the leg's
    axis is ``Rx(a) Ry(b) e_z``; the spherical joint is RX·RY·RZ and is at zero at home (its
    frame is then parallel to the leg's), so the platform attachment rotates back to K's axes.
    """
    angle = 2.0 * math.pi * k / 3.0
    b = BASE_RADIUS_M * np.array([math.cos(angle), math.sin(angle), 0.0])
    p = np.array([0.0, 0.0, HOME_HEIGHT_M]) + PLATFORM_RADIUS_M * np.array(
        [math.cos(angle), math.sin(angle), 0.0]
    )
    d = p - b
    length = float(np.linalg.norm(d))
    u = d / length
    rot_b = math.asin(u[0])
    rot_a = math.atan2(-u[1], u[2])
    leg_rotation = pin.utils.rotate("x", rot_a) @ pin.utils.rotate("y", rot_b)

    m = pin.Model()
    m.name = f"leg{k + 1}"
    j = add_revolute(m, 0, pin.JointModelRX(), pin.SE3(np.eye(3), b), f"leg{k + 1}_ux", -60 * DEG, 60 * DEG)
    j = add_revolute(m, j, pin.JointModelRY(), pin.SE3.Identity(), f"leg{k + 1}_uy", -60 * DEG, 60 * DEG)
    j = add_revolute(m, j, pin.JointModelPZ(), pin.SE3.Identity(), f"leg{k + 1}_slide", 0.4, 1.4)
    j = add_revolute(m, j, pin.JointModelRX(), pin.SE3.Identity(), f"leg{k + 1}_sx", -90 * DEG, 90 * DEG)
    j = add_revolute(m, j, pin.JointModelRY(), pin.SE3.Identity(), f"leg{k + 1}_sy", -90 * DEG, 90 * DEG)
    j = add_revolute(m, j, pin.JointModelRZ(), pin.SE3.Identity(), f"leg{k + 1}_sz", -90 * DEG, 90 * DEG)
    # the platform frame O', seen from the S joint at home (S at zero): back to K's axes
    attach = pin.SE3(leg_rotation.T, leg_rotation.T @ (np.array([0.0, 0.0, HOME_HEIGHT_M]) - p))
    m.addFrame(
        pin.Frame("platform", j, m.getFrameId(f"leg{k + 1}_sz"), attach, pin.FrameType.OP_FRAME), False
    )
    return m, [rot_a, rot_b, length, 0.0, 0.0, 0.0]


def up_column() -> tuple[pin.Model, list[float]]:
    """The passive UP column: U at O, a slide along the platform's z axis ending at O'."""
    m = pin.Model()
    m.name = "column"
    j = add_revolute(m, 0, pin.JointModelRX(), pin.SE3.Identity(), "column_ux", -60 * DEG, 60 * DEG)
    j = add_revolute(m, j, pin.JointModelRY(), pin.SE3.Identity(), "column_uy", -60 * DEG, 60 * DEG)
    j = add_revolute(m, j, pin.JointModelPZ(), pin.SE3.Identity(), "column_slide", 0.3, 1.4)
    m.addFrame(
        pin.Frame("platform", j, m.getFrameId("column_slide"), pin.SE3.Identity(), pin.FrameType.OP_FRAME),
        False,
    )
    return m, [0.0, 0.0, HOME_HEIGHT_M]


def build_mechanism() -> Mechanism:
    """The 3-UPS&UP mechanism from the four models above."""
    legs = [ups_leg(k) for k in range(3)]
    column = up_column()
    models = [column[0]] + [m for m, _ in legs]
    homes = [column[1]] + [h for _, h in legs]
    return Mechanism.from_models(
        "tricept_like_in_python",
        models,
        actuated=[[], ["leg1_slide"], ["leg2_slide"], ["leg3_slide"]],
        platform_frame="platform",
        reference_point_m=[0.0, 0.0, 0.2],
        task_space=TaskSpace(kind="cylinder", radius_m=0.15, z_range_m=(0.95, 1.05), layers=2, rings=(6, 12)),
        limb_names=["column", "leg1", "leg2", "leg3"],
        homes=homes,
        target_m=5e-5,
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=10_000, help="Monte Carlo samples (default 10000)")
    ap.add_argument("--exact-samples", type=int, default=100, help="exact-kinematics samples (default 100)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    mech = build_mechanism()
    options = DesignOptions(
        samples=args.samples,
        verification_poses=min(args.samples, 2_000),
        exact_samples=args.exact_samples,
        claim_poses=min(args.samples, 300),
        seed=args.seed,
    )
    result = allocate(mech, options)
    n_unc = len(result.uncompensatable)
    p = result.worst_point_m * 1e3
    print(
        f"{mech.name}: {len(mech.limbs)} limbs, {mech.n_joints} joints, {len(result.pset)} error parameters "
        f"({result.pset.kind} set), {n_unc} uncompensatable"
    )
    print(
        f"most error-sensitive point P = ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm; "
        f"Δλ* = {result.target_m * 1e3:g} mm"
    )
    print()
    print(text_table(table_rows(result)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
