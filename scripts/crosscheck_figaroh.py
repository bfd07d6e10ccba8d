"""Cross-check of pkmtol's calibration building blocks with FIGAROH on one serial limb (issue 12, item 10).

The sub-problem: limb 1 (the UPS chain) of ``robots/r2rps_ups`` as a serial robot. Every joint is
commanded (read), and a tracker measures the position of the reference point P, fixed on the
platform link, at random configurations within the joint limits.

* **Truth** (neither tool): plain Pinocchio on the limb URDF, every joint placement perturbed as
  ``M · SE3(exp3(φ), p)`` (σ 0.1 mm / 0.5 mrad per component, every joint, its zero offset
  included) and P shifted by ``t`` (σ 0.1 mm per axis) on the platform. Any rigid placement
  error is both pkmtol's ``exp6(ε)`` and FIGAROH's ``SE3(exp3(φ), p)``: neither tool is favoured.
* **pkmtol**: the limb's urdf parameter set (48 parameters), the position rows of P from
  ``raw_columns_local`` (Pinocchio's ``computeFrameKinematicRegressor``), base parameters by
  ``identifiability`` (pivoted QR on scaled columns), and a Gauss–Newton fit of the base parameters
  with that Jacobian frozen, the residual being exact forward kinematics of the limb perturbed as
  ``perturbed_limb_models`` does (``origin · exp6(ε)``, joint readings + zero offsets).
* **FIGAROH**: ``BaseCalibration`` from a YAML config and a CSV of the measurements, as a FIGAROH
  user runs it: ``full_params`` on the 6 joints, known base frame, unknown tip (``pEEx/y/z_1``),
  structural base parameters by QR on random configurations, its data-level elimination of
  parameters absorbed by the tip, and its Levenberg–Marquardt fit (``scipy.optimize.least_squares``).

What is compared: the number of base parameters (rank), the column spaces of the two base
Jacobians at the calibration configurations, the predicted positions of P at held-out
configurations (invariant: the two tools choose different base columns), and pkmtol's base
combinations ``β = δ_B + K' δ_D`` evaluated on FIGAROH's estimate (first order: equal up to
second-order terms of the errors). docs/figaroh-crosscheck.md gives the method and the output.

Usage:
    python scripts/crosscheck_figaroh.py
    python scripts/crosscheck_figaroh.py --poses 60 --holdout 200 --noise-um 10 --seed 1
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from scipy import linalg
from scipy.optimize import least_squares

from pkmtol.calibration.identifiability import Identifiability, identifiability
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.twists import raw_columns_local
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.loader import load_mechanism

REPO = Path(__file__).resolve().parents[1]
ROBOT = REPO / "robots" / "r2rps_ups"
LIMB = "limb1"
SIGMA_M = 1e-4  # manufacturing σ of a translation error [m]
SIGMA_RAD = 5e-4  # manufacturing σ of a rotation error [rad]
#: pkmtol's Gauss–Newton stops when every step is below this fraction of its parameter's scale.
STEP_TOLERANCE = 1e-10
FIGAROH_COMPONENTS = ("d_px", "d_py", "d_pz", "d_phix", "d_phiy", "d_phiz")
TIP = ("pEEx_1", "pEEy_1", "pEEz_1")


# ---- the simulated experiment (plain Pinocchio: neither tool) ---------------------------------


@dataclass(frozen=True)
class Experiment:
    """Configurations, true errors and measured positions of P (SI)."""

    q_cal: np.ndarray  # (N, 6) joint readings of the calibration poses
    q_hold: np.ndarray  # (M, 6) held-out readings
    placement_errors: np.ndarray  # (6, 6) per joint (p, φ): M · SE3(exp3(φ), p)
    tip_error: np.ndarray  # (3,) shift of P on the platform
    measured: np.ndarray  # (N, 3) P at q_cal, with noise
    truth_hold: np.ndarray  # (M, 3) true P at q_hold, no noise
    noise_m: float


def truth_positions(
    urdf: Path, point: np.ndarray, errors: np.ndarray, tip: np.ndarray, qs: np.ndarray
) -> np.ndarray:
    """P of the perturbed limb at joint values ``qs`` (k, 6), shape (k, 3) [m]."""
    model = pin.buildModelFromUrdf(str(urdf))
    for j in range(1, model.njoints):
        p, phi = errors[j - 1, :3], errors[j - 1, 3:]
        model.jointPlacements[j] = model.jointPlacements[j] * pin.SE3(pin.exp3(phi), p)
    data = model.createData()
    frame = model.frames[model.getFrameId("platform")]
    local = frame.placement.act(point + tip)  # P in the last joint's frame
    out = np.empty((len(qs), 3))
    for k, q in enumerate(qs):
        pin.forwardKinematics(model, data, q)
        out[k] = data.oMi[frame.parentJoint].act(local)
    return out


def make_experiment(
    poses: int, holdout: int, noise_m: float, seed: int, error_scale: float = 1.0
) -> Experiment:
    """Random configurations in the joint limits, random errors (σ × ``error_scale``), noisy measurements."""
    mech = load_mechanism(ROBOT)
    limb = mech.limb(LIMB)
    lo, hi = limb.model.lowerPositionLimit, limb.model.upperPositionLimit
    rng = np.random.default_rng(seed)
    q_cal = rng.uniform(lo, hi, size=(poses, limb.nq))
    q_hold = rng.uniform(lo, hi, size=(holdout, limb.nq))
    errors = error_scale * np.hstack(
        [rng.normal(0.0, SIGMA_M, (limb.nq, 3)), rng.normal(0.0, SIGMA_RAD, (limb.nq, 3))]
    )
    tip = error_scale * rng.normal(0.0, SIGMA_M, 3)
    assert limb.urdf_path is not None
    point = mech.reference_point_m
    exact = truth_positions(limb.urdf_path, point, errors, tip, q_cal)
    measured = exact + rng.normal(0.0, noise_m, exact.shape)
    truth_hold = truth_positions(limb.urdf_path, point, errors, tip, q_hold)
    return Experiment(q_cal, q_hold, errors, tip, measured, truth_hold, noise_m)


# ---- pkmtol ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class PkmtolFit:
    """pkmtol's base parameters and Gauss–Newton estimate on the limb."""

    names: list[str]  # the limb's urdf parameters (48)
    ident: Identifiability
    H: np.ndarray  # (3N, 48) position rows of P at the nominal point
    estimate: np.ndarray  # (48,) δ_B at the base columns, 0 elsewhere
    iterations: int
    rms_m: float  # residual RMS at the estimate
    predicted_hold: np.ndarray  # (M, 3)
    predicted_hold_exact: np.ndarray  # (M, 3) at the least-squares minimum of the same model


class PkmtolLimb:
    """The limb as pkmtol models it: urdf parameter set, error columns, perturbed models."""

    def __init__(self) -> None:
        self.mech = load_mechanism(ROBOT)
        self.index = [lb.name for lb in self.mech.limbs].index(LIMB)
        self.limb = self.mech.limbs[self.index]
        self.pset = parameter_set(self.mech, "urdf")
        self.slice = self.pset.slices[self.index]
        self.names = self.pset.names[self.slice]
        self.units = self.pset.units[self.slice]
        self.point = self.mech.reference_point_m
        self.offset_start = sum(lb.nq for lb in self.mech.limbs[: self.index])

    def rows(self, qs: np.ndarray) -> np.ndarray:
        """Position rows of P per unit parameter at the nominal point, shape (3·k, 48), in K."""
        model = self.limb.model
        data = model.createData()
        out = []
        for q in qs:
            raw, _jac, oMp = raw_columns_local(self.limb, model, data, q)
            # the platform's pose error δ = (v, ω) (local) moves P by v + ω × p (local)
            out.append(oMp.rotation @ (raw[:3] - pin.skew(self.point) @ raw[3:]))
        return np.vstack(out)

    def positions(self, delta: np.ndarray, qs: np.ndarray) -> np.ndarray:
        """P of the limb perturbed by the 48 parameters ``delta`` at readings ``qs``, shape (k, 3)."""
        eta = np.zeros(len(self.pset))
        eta[self.slice] = delta
        eps, offsets = self.pset.perturbation(eta, self.mech)
        model = perturbed_limb_models(self.mech, eps)[self.index]
        off = offsets[self.offset_start : self.offset_start + self.limb.nq]
        data = model.createData()
        out = np.empty((len(qs), 3))
        for k, q in enumerate(qs):
            pin.framesForwardKinematics(model, data, q + off)
            out[k] = data.oMf[self.limb.platform_frame].act(self.point)
        return out

    def scale(self) -> np.ndarray:
        """Expected size of each parameter (column scaling of the QR) [m or rad]."""
        return np.array([SIGMA_M if u == "m" else SIGMA_RAD for u in self.units])


def pkmtol_fit(exp: Experiment) -> PkmtolFit:
    """Base parameters by pkmtol's pivoted QR, then Gauss–Newton on exact forward kinematics.

    The Jacobian is the nominal one, frozen, as :func:`pkmtol.calibration.identification.identify` starts;
    its fixed point solves ``H_Bᵀ r = 0`` at the nominal ``H_B``. The least-squares minimum of the
    same model (``J(x)ᵀ r = 0``) is found after it by scipy's Levenberg–Marquardt from that point.
    """
    side = PkmtolLimb()
    n = len(side.names)
    H = side.rows(exp.q_cal)
    scale = side.scale()
    ident = identifiability(H, np.arange(n), side.names, side.units, scale, len(exp.q_cal), exp.noise_m)
    cols = ident.base_columns

    def residual(x: np.ndarray) -> np.ndarray:
        return (exp.measured - side.positions(ident.expand(x, n), exp.q_cal)).reshape(-1)

    q_h, r_h = linalg.qr(H[:, cols], mode="economic")
    x = np.zeros(cols.size)
    iterations = 0
    while iterations < 50:
        iterations += 1
        step = linalg.solve_triangular(r_h, q_h.T @ residual(x))
        x = x + step
        if np.all(np.abs(step) < STEP_TOLERANCE * scale[cols]):
            break
    exact = least_squares(residual, x, method="lm", x_scale=scale[cols], ftol=1e-15, xtol=1e-15, gtol=1e-15)
    estimate = ident.expand(x, n)
    return PkmtolFit(
        names=side.names,
        ident=ident,
        H=H,
        estimate=estimate,
        iterations=iterations,
        rms_m=float(np.sqrt(np.mean(residual(x) ** 2))),
        predicted_hold=side.positions(estimate, exp.q_hold),
        predicted_hold_exact=side.positions(ident.expand(exact.x, n), exp.q_hold),
    )


# ---- FIGAROH --------------------------------------------------------------------------------


@dataclass(frozen=True)
class FigarohFit:
    """FIGAROH's base parameters and Levenberg–Marquardt estimate on the limb."""

    version: str
    candidates: int  # parameters of its model: full_params of every joint and the tip
    names: list[str]  # the identified parameters, in FIGAROH's order
    structural: list[str]  # joint base parameters of the structural QR, before the elimination
    absorbed: list[str]  # dropped by the data-level elimination (absorbed by the tip)
    estimate: np.ndarray  # values of ``names``
    rms_m: float
    predicted_hold: np.ndarray  # (M, 3)
    jacobian: np.ndarray  # (3N, len(names)) FIGAROH's measurement Jacobian at 0, calibration poses
    holdout_rmse_mm: float  # FIGAROH's own validation metric on the held-out file


CONFIG = """\
meta:
  schema_version: "2.0"
robot:
  name: {limb}
tasks:
  calibration:
    type: kinematic_calibration
    kinematics:
      base_frame: universe
      tool_frame: P
    measurements:
      markers:
        - measurable_dof: [true, true, true, false, false, false]
    parameters:
      calibration_level: full_params
      outlier_threshold: 1.0  # m: no sample is excluded as an outlier
      random_seed: 0
    data:
      number_of_samples: {samples}
      source_file: {data}
      validation_data_file: {validation}
"""


class FigarohRobot:
    """What FIGAROH's ``BaseCalibration`` takes: ``model``, ``data`` and ``q0``, with a frame at P."""

    def __init__(self, urdf: Path, point: np.ndarray) -> None:
        self.model = pin.buildModelFromUrdf(str(urdf))
        pf = self.model.getFrameId("platform")
        parent = self.model.frames[pf]
        placement = parent.placement * pin.SE3(np.eye(3), np.asarray(point, dtype=float))
        self.model.addFrame(pin.Frame("P", parent.parentJoint, pf, placement, pin.FrameType.OP_FRAME))
        self.data = self.model.createData()
        self.q0 = pin.neutral(self.model)


def _write_csv(path: Path, joint_names: list[str], qs: np.ndarray, points: np.ndarray) -> None:
    """FIGAROH's measurement CSV: ``x1, y1, z1`` and one column per joint."""
    header = ["x1", "y1", "z1", *joint_names]
    lines = [",".join(header)]
    for p, q in zip(points, qs, strict=True):
        lines.append(",".join(repr(float(v)) for v in (*p, *q)))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def figaroh_fit(exp: Experiment) -> FigarohFit:
    """FIGAROH's calibration of the limb from a config file and a measurement CSV."""
    with warnings.catch_warnings():  # ndcurves re-registers a converter Pinocchio has
        warnings.simplefilter("ignore", RuntimeWarning)
        import figaroh
        from figaroh.calibration.base_calibration import BaseCalibration
        from figaroh.calibration.calibration_tools import calc_updated_fkm, measurement_jacobian
        from figaroh.calibration.parameter import get_fullparam_offset

    class LimbCalibration(BaseCalibration):  # type: ignore[misc]
        """World-frame position residuals (FIGAROH asks each robot for its cost function)."""

        def cost_function(self, var: np.ndarray) -> Any:
            est = calc_updated_fkm(self.model, self.data, var, self.q_measured, self.calib_config)
            return self._compute_logmap_residuals(self.PEE_measured, est, position_frame="world")

    mech = load_mechanism(ROBOT)
    limb = mech.limb(LIMB)
    assert limb.urdf_path is not None
    robot = FigarohRobot(limb.urdf_path, mech.reference_point_m)
    joints = list(robot.model.names[1:])
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        _write_csv(folder / "data.csv", joints, exp.q_cal, exp.measured)
        _write_csv(folder / "holdout.csv", joints, exp.q_hold, exp.truth_hold)
        (folder / "limb.yaml").write_text(
            CONFIG.format(
                limb=LIMB,
                samples=len(exp.q_cal),
                data=folder / "data.csv",
                validation=folder / "holdout.csv",
            ),
            encoding="utf-8",
        )
        quiet = logging.getLogger("figaroh")
        level = quiet.level
        quiet.setLevel(logging.ERROR)
        try:
            with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                calib = LimbCalibration(robot, str(folder / "limb.yaml"))
                calib.calib_config["known_baseframe"] = True
                calib.calib_config["known_tipframe"] = False
                calib.initialize()
                result = calib.solve(enable_logging=False)
        finally:
            quiet.setLevel(level)
    cfg = calib.calib_config
    names = list(cfg["param_name"])
    x = np.asarray(result.x, dtype=float)
    hold_cfg = dict(cfg, NbSample=len(exp.q_hold))
    pred = calc_updated_fkm(robot.model, robot.data, x, exp.q_hold, hold_cfg).reshape(3, -1).T
    fit = calc_updated_fkm(robot.model, robot.data, x, exp.q_cal, cfg).reshape(3, -1).T
    J = measurement_jacobian(robot.model, robot.data, np.zeros(len(names)), exp.q_cal, cfg)
    # FIGAROH's rows are component-major (x over the samples, then y, z); pkmtol's pose-major
    J = J.reshape(3, len(exp.q_cal), len(names)).transpose(1, 0, 2).reshape(-1, len(names))
    validation = getattr(calib, "results_data", {}).get("validation_metrics") or {}
    return FigarohFit(
        version=str(getattr(figaroh, "__version__", "?")),
        candidates=len(get_fullparam_offset(joints)) + len(TIP),
        names=names,
        structural=list(cfg.get("base_mapping_row_names_full", [])),
        absorbed=list(cfg.get("absorbed_param_name", [])),
        estimate=x,
        rms_m=float(np.sqrt(np.mean((exp.measured - fit) ** 2))),
        predicted_hold=pred,
        jacobian=J,
        holdout_rmse_mm=float(validation.get("pos_rmse_calibrated_mm", np.nan)),
    )


def figaroh_to_pkmtol(names: list[str], values: np.ndarray, pk_names: list[str]) -> np.ndarray:
    """FIGAROH's estimate as pkmtol's 48 urdf parameters, exactly.

    FIGAROH's joint error ``M · SE3(exp3(φ), p)`` is pkmtol's ``M · exp6(ε)`` with
    ``ε = log6(SE3(exp3(φ), p))``; its tip shift ``pEE`` (platform axes, at P) is the platform
    attachment's pure translation ``ε = (pEE, 0)``; its zero offsets are in ``d_phiz`` / ``d_pz``
    (pkmtol's ``.offset`` stays 0). Parameters FIGAROH did not estimate are 0.
    """
    given = dict(zip(names, values, strict=True))
    out = np.zeros(len(pk_names))
    index = {name: k for k, name in enumerate(pk_names)}
    joints = sorted({n.rsplit(".", 2)[1] for n in pk_names if not n.endswith(".offset")})
    for joint in joints:
        if joint.endswith("platform_attach"):
            eps = np.array([given.get(t, 0.0) for t in TIP] + [0.0, 0.0, 0.0])
        else:
            e = np.array([given.get(f"{c}_{joint}", 0.0) for c in FIGAROH_COMPONENTS])
            eps = pin.log6(pin.SE3(pin.exp3(e[3:]), e[:3])).vector
        for c, comp in enumerate(("dx", "dy", "dz", "rx", "ry", "rz")):
            out[index[f"{LIMB}.{joint}.{comp}"]] = eps[c]
    return out


def figaroh_name(name: str, kinds: dict[str, str]) -> str | None:
    """The FIGAROH parameter with the same column as pkmtol's ``name`` (None: FIGAROH has none).

    ``<joint>.dx … rz`` are ``d_px … d_phiz_<joint>``; a zero offset is the placement error about
    or along the joint's own z axis (``d_phiz`` revolute, ``d_pz`` prismatic); the platform
    attachment's translations are the tip ``pEE*_1``, its rotations (which move P by ``ω × p``)
    have no FIGAROH name. ``kinds`` gives ``"R"``/``"P"`` per joint.
    """
    _limb, joint, comp = name.split(".")
    if joint.endswith("platform_attach"):
        return dict(zip(("dx", "dy", "dz"), TIP, strict=True)).get(comp)
    if comp == "offset":
        return f"{'d_phiz' if kinds[joint] == 'R' else 'd_pz'}_{joint}"
    return f"{dict(zip(('dx', 'dy', 'dz', 'rx', 'ry', 'rz'), FIGAROH_COMPONENTS, strict=True))[comp]}_{joint}"


# ---- the comparison -------------------------------------------------------------------------


@dataclass(frozen=True)
class Comparison:
    """Both fits on the same experiment, and what is compared."""

    exp: Experiment
    pk: PkmtolFit
    fg: FigarohFit
    common: int  # base columns both tools chose (pkmtol's named as FIGAROH's)
    max_angle_rad: float  # largest principal angle between the two base column spaces
    joint_rank: int  # rank of [H_pkmtol | J_figaroh]: both span the same space iff = each rank
    hold_pk_truth_m: float  # max |P_pkmtol − P_true| over the held-out poses
    hold_fg_truth_m: float
    mapped_fg_m: float  # max |P(pkmtol model, FIGAROH's estimate mapped) − P_figaroh|, held out
    hold_pk_fg_m: float  # max |P_pkmtol − P_figaroh| over the held-out poses
    hold_exact_fg_m: float  # the same with pkmtol's model solved to the least-squares minimum
    beta_diff_scale: float  # max_i |β_i(pkmtol) − β_i(FIGAROH's estimate)| / s_i (parameter scale)
    beta_diff_sigma: float  # the same in σ(β_i) (nan without noise)


def _max_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between corresponding points of (k, 3) arrays [m]."""
    return float(np.max(np.linalg.norm(a - b, axis=1)))


def compare(
    poses: int = 60, holdout: int = 200, noise_m: float = 1e-5, seed: int = 1, error_scale: float = 1.0
) -> Comparison:
    """Simulate, identify with both tools, compare."""
    exp = make_experiment(poses, holdout, noise_m, seed, error_scale)
    pk = pkmtol_fit(exp)
    fg = figaroh_fit(exp)
    Hb = pk.H[:, pk.ident.base_columns]
    angles = linalg.subspace_angles(Hb, fg.jacobian)
    both = np.hstack([Hb / np.linalg.norm(Hb, axis=0), fg.jacobian / np.linalg.norm(fg.jacobian, axis=0)])
    sv = linalg.svd(both, compute_uv=False)
    joint_rank = int(np.sum(sv > 1e-8 * sv[0]))
    beta_pk = pk.ident.true_base_values(pk.estimate)
    mapped = figaroh_to_pkmtol(fg.names, fg.estimate, pk.names)
    beta_fg = pk.ident.true_base_values(mapped)
    diff = np.abs(beta_pk - beta_fg)
    std = pk.ident.std
    side = PkmtolLimb()
    kinds = dict(zip(side.limb.joint_names, side.limb.joint_kinds, strict=True))
    common = {figaroh_name(n, kinds) for n in pk.ident.base_names} & set(fg.names)
    return Comparison(
        exp=exp,
        pk=pk,
        fg=fg,
        common=len(common),
        max_angle_rad=float(np.max(angles)),
        joint_rank=joint_rank,
        hold_pk_truth_m=_max_distance(pk.predicted_hold, exp.truth_hold),
        hold_fg_truth_m=_max_distance(fg.predicted_hold, exp.truth_hold),
        mapped_fg_m=_max_distance(side.positions(mapped, exp.q_hold), fg.predicted_hold),
        hold_pk_fg_m=_max_distance(pk.predicted_hold, fg.predicted_hold),
        hold_exact_fg_m=_max_distance(pk.predicted_hold_exact, fg.predicted_hold),
        beta_diff_scale=float(np.max(diff / pk.ident.scale[pk.ident.base])),
        beta_diff_sigma=float(np.max(diff / std)) if np.all(std > 0) else float("nan"),
    )


def report(c: Comparison, names: bool = False) -> str:
    """The printed table (lengths in m)."""
    pk, fg, exp = c.pk, c.fg, c.exp
    n_tip = len([n for n in fg.names if n in TIP])
    r = pk.ident.rank
    gap = pk.ident.pivots[r - 1], pk.ident.pivots[r]

    def row(label: str, a: object, b: object) -> str:
        return f"{label:46}{a!s:>12}{b!s:>12}"

    def pair(label: str, value: str) -> str:
        return f"{label:55}{value}"

    lines = [
        f"{LIMB} of {ROBOT.relative_to(REPO)} as a serial robot: {len(exp.q_cal)} calibration poses, "
        f"{len(exp.q_hold)} held-out, P measured in position, noise {exp.noise_m * 1e6:g} µm per axis",
        f"FIGAROH {fg.version}, Pinocchio {pin.__version__}",
        "",
        row("", "pkmtol", "FIGAROH"),
        row("parameters of the model", len(pk.names), fg.candidates),
        row("structural base parameters of the joints", "", len(fg.structural)),
        row("dropped as absorbed by the tip", "", len(fg.absorbed)),
        row("base parameters (rank)", pk.ident.rank, len(fg.names)),
        row("  of which joints / tip", "", f"{len(fg.names) - n_tip} / {n_tip}"),
        row("residual RMS at the estimate [m]", f"{pk.rms_m:.3e}", f"{fg.rms_m:.3e}"),
        row("held-out max |P - P_true| [m]", f"{c.hold_pk_truth_m:.3e}", f"{c.hold_fg_truth_m:.3e}"),
        row("held-out RMSE, FIGAROH's validation [m]", "", f"{fg.holdout_rmse_mm * 1e-3:.3e}"),
        "",
        f"pkmtol's pivoted QR, |R_ii|/|R_00|: last kept {gap[0]:.1e}, first dropped {gap[1]:.1e} "
        f"(tolerance {pk.ident.rank_tolerance:g})",
        pair("base columns chosen by both (names mapped)", f"{c.common} of {pk.ident.rank}"),
        pair("rank of [pkmtol base columns | FIGAROH base columns]", f"{c.joint_rank}"),
        pair("largest principal angle between the column spaces", f"{c.max_angle_rad:.2e} rad"),
        pair("FIGAROH's estimate on pkmtol's parameters, held-out", f"{c.mapped_fg_m:.2e} m"),
        pair("held-out max |P_pkmtol - P_FIGAROH|", f"{c.hold_pk_fg_m:.2e} m"),
        pair("  pkmtol's model at the least-squares minimum", f"{c.hold_exact_fg_m:.2e} m"),
        pair("pkmtol's β on FIGAROH's estimate, max |Δβ_i| / s_i", f"{c.beta_diff_scale:.2e}"),
    ]
    if np.isfinite(c.beta_diff_sigma):
        lines.append(pair("  in σ(β_i) of this plan and noise", f"{c.beta_diff_sigma:.2e}"))
    if names:
        lines += ["", "pkmtol base parameters:", *("  " + n for n in pk.ident.identified_combinations())]
        lines += ["FIGAROH base parameters:", *("  " + n for n in fg.names)]
        lines += ["FIGAROH dropped as absorbed by the tip:", *("  " + n for n in fg.absorbed)]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=60, help="calibration poses (default 60)")
    ap.add_argument("--holdout", type=int, default=200, help="held-out poses (default 200)")
    ap.add_argument("--noise-um", type=float, nargs="+", default=[0.0, 10.0], help="noise σ per axis [µm]")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--error-scale", type=float, default=1.0, help="multiply the true errors' σ by this")
    ap.add_argument("--names", action="store_true", help="list both tools' base parameters")
    args = ap.parse_args(argv)
    for k, noise in enumerate(args.noise_um):
        if k:
            print()
        c = compare(args.poses, args.holdout, noise * 1e-6, args.seed, args.error_scale)
        print(report(c, names=args.names))
    return 0


if __name__ == "__main__":
    sys.exit(main())
