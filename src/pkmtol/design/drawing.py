"""Drawing tolerances: each σ_i as the ±t, the ISO 286 grade or the geometric zone that goes on a drawing.

Under the stated convention (:class:`pkmtol.model.drawing.DrawingSettings`: ±t = k·σ, k = 3 by
default, or ±t = √3·σ), each toleranced error becomes one callout, chosen from where the error
lives (its joint origin, from the parameter set's selection) and what it moves:

* a **length** error along a dimension of nominal size N > 0 (the D–H ``a``/``d`` value: the
  origin's offset along the error, or ``[drawing.nominals]``): **size N ± t** with the ISO 286-1 IT
  grade of the zone 2t (:func:`pkmtol.design.iso286.it_grade`);
* a length error along a dimension of nominal 0 (axes that intersect, a zero offset): a
  **position** tolerance, zone 2t;
* an **angle** error that changes the angle between a joint's axis (the feature) and its parent
  joint's axis (the datum; the base z axis for a limb's first joint, the last joint's axis for the
  platform attachment, whose feature is the tool axis) — a rotation about their common normal,
  the D–H δφ: a **perpendicularity** (nominal angle within 10° of 90°), **parallelism** (within
  10° of 0°) or **angularity** zone ``L·tan(δ)`` over the feature length L (``[drawing]
  feature_length``, per joint in ``[drawing.feature_lengths]``, default 100 mm), δ the tilt ±t
  makes;
* an angle that swings the feature about the datum's axis (the D–H δθ of a link): an
  **angularity** zone about the datum, which a secondary datum fixes;
* an angle about the feature's own axis: an **angular position** ±t (it tilts nothing);
* a joint's zero offset: **joint zero** ±t, set at assembly or by calibration (no feature).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from pkmtol.design.iso286 import MAX_SIZE_MM, ItGrade, it_grade
from pkmtol.error_model.parameters import ParameterSet, parameter_set
from pkmtol.exceptions import MechanismFormatError
from pkmtol.model.drawing import DrawingSettings
from pkmtol.model.limb import Limb
from pkmtol.model.mechanism import Mechanism

KINDS = (
    "size",
    "position",
    "perpendicularity",
    "parallelism",
    "angularity",
    "angular position",
    "joint zero",
)
#: Nominal angle between feature and datum within this of 90° (0°) reads as perpendicular (parallel).
RELATION_BAND_RAD = math.radians(10.0)
#: A nominal size below this is zero (position rather than size) [m].
ZERO_SIZE_M = 1e-9


@dataclass(frozen=True)
class DrawingTolerance:
    """What goes on the drawing for one toleranced error (SI inside; see ``callout``).

    Attributes:
        index: The parameter's index in the parameter set.
        name: Its name.
        unit: ``m`` or ``rad``.
        sigma: The design's standard deviation σ_i.
        tolerance: ±t = factor · σ_i.
        kind: One of :data:`KINDS`.
        feature: The joint (or platform attachment) whose geometry the error changes.
        datum: The datum feature of an orientation zone (a joint, ``base z``), else None.
        about_datum: True when the error swings the feature about the datum's axis (an
            angularity that a secondary datum fixes), False when it changes their angle.
        nominal_m: The nominal size of a length error [m] (0 for a position), else None.
        nominal_angle_rad: The nominal angle between feature and datum axes, else None.
        zone_m: The zone width: 2t for size/position, ``L·tan δ`` for an orientation [m]; None
            for an angle or a joint zero.
        feature_length_m: L of an orientation zone [m], else None.
        it: The ISO 286-1 grade of a size (None otherwise, or beyond 3150 mm).
    """

    index: int
    name: str
    unit: str
    sigma: float
    tolerance: float
    kind: str
    feature: str
    datum: str | None = None
    about_datum: bool = False
    nominal_m: float | None = None
    nominal_angle_rad: float | None = None
    zone_m: float | None = None
    feature_length_m: float | None = None
    it: ItGrade | None = None

    @property
    def callout(self) -> str:
        """The callout in words (mm, mrad)."""
        t = self.tolerance
        tol = f"±{1e3 * t:.4g} mm" if self.unit == "m" else f"±{1e3 * t:.4g} mrad"
        if self.kind == "size":
            assert self.nominal_m is not None
            grade = f", {self.it.label} (IT {self.it.it_um:g} µm ≤ 2t)" if self.it else ""
            beyond = "" if self.it else f" (beyond ISO 286's {MAX_SIZE_MM:g} mm)"
            return f"{1e3 * self.nominal_m:.6g} mm {tol}{grade}{beyond}"
        if self.kind == "position":
            assert self.zone_m is not None
            return f"position of {self.feature}, zone {1e3 * self.zone_m:.4g} mm (nominal 0, {tol})"
        if self.kind in ("perpendicularity", "parallelism", "angularity"):
            assert self.zone_m is not None and self.feature_length_m is not None
            to = (
                f"about {self.datum}'s axis (to a secondary datum)"
                if self.about_datum
                else f"to {self.datum}"
            )
            return (
                f"{self.kind} of {self.feature}'s axis {to}: {1e3 * self.zone_m:.4g} mm over "
                f"L = {1e3 * self.feature_length_m:.4g} mm ({tol})"
            )
        if self.kind == "angular position":
            return f"angular position about {self.feature}'s axis {tol}"
        return f"zero of {self.feature} {tol} (set at assembly or by calibration)"


def _joint_axis(limb: Limb, j: int) -> np.ndarray:
    """Unit axis of joint ``j`` (1-based Pinocchio index) in its own frame."""
    data = limb.model.createData()
    pin.computeJointJacobians(limb.model, data, pin.neutral(limb.model))
    s = pin.getJointJacobian(limb.model, data, j, pin.LOCAL)[:, limb.model.joints[j].idx_v]
    axis = s[3:] if np.linalg.norm(s[3:]) > 0.5 else s[:3]
    return axis / np.linalg.norm(axis)


def _origin(limb: Limb, o: int, tool_axis: np.ndarray) -> tuple[pin.SE3, np.ndarray, np.ndarray, str, str]:
    """Origin ``o``: placement, feature axis and datum axis (both in its frame), and their names."""
    nq = limb.nq
    if o < nq:
        placement = limb.model.jointPlacements[o + 1]
        feature_axis, feature = _joint_axis(limb, o + 1), limb.joint_names[o]
    else:
        placement = limb.model.frames[limb.platform_frame].placement
        feature_axis, feature = tool_axis, limb.attach_name
    if o == 0:
        parent_axis, datum = np.array([0.0, 0.0, 1.0]), "base z"
    else:
        parent_axis, datum = _joint_axis(limb, o), limb.joint_names[o - 1]
    return placement, feature_axis, placement.rotation.T @ parent_axis, feature, datum


def drawing_tolerances(
    mechanism: Mechanism,
    pset: ParameterSet,
    columns: np.ndarray,
    sigma: np.ndarray,
    settings: DrawingSettings,
    tool_axis: np.ndarray | None = None,
) -> list[DrawingTolerance]:
    """The drawing callout of every toleranced error.

    Args:
        mechanism: The mechanism.
        pset: Its parameter set.
        columns: Indices of the toleranced parameters.
        sigma: Shape (len(pset),): the design's σ_i (SI). A σ that is not finite and positive gets
            no callout: a free error (no effect on Δλ anywhere on the grid) has no zone to draw.
        settings: The convention, nominals and feature lengths.
        tool_axis: The tool axis in the platform frame (the platform attachment's feature; z).

    Raises:
        MechanismFormatError: ``[drawing.nominals]`` names a parameter of neither parameter set.
    """
    _check_nominals(mechanism, pset, settings)
    axis = np.array([0.0, 0.0, 1.0]) if tool_axis is None else np.asarray(tool_axis, dtype=float)
    out = []
    for i in np.asarray(columns, dtype=int):
        s = float(sigma[i])
        if not (math.isfinite(s) and s > 0.0):  # free: σ = +inf, or 0 where a caller zeroed it
            continue
        p = pset.parameters[i]
        if p.limb >= len(mechanism.limbs) and mechanism.tool is not None:  # a hybrid's tool chain
            limb = mechanism.tool.as_limb()
            tool_sel, tool_part = getattr(pset, "tool_selection"), getattr(pset, "tool_slice")  # noqa: B009
            raw = tool_sel[:, i - tool_part.start]
        else:
            limb = mechanism.limbs[p.limb]
            raw = pset.selections[p.limb][:, i - pset.slices[p.limb].start]
        t = settings.factor * s
        fields = _callout(limb, raw, p.unit, t, axis, settings, p.name)
        out.append(DrawingTolerance(index=int(i), name=p.name, unit=p.unit, sigma=s, tolerance=t, **fields))
    return out


def _callout(
    limb: Limb,
    raw: np.ndarray,
    unit: str,
    t: float,
    tool_axis: np.ndarray,
    settings: DrawingSettings,
    name: str,
) -> dict[str, Any]:
    """The callout's fields for one error of ``limb`` (``raw``: its raw-error combination) at ±t."""
    n_orig = 6 * (limb.nq + 1)
    blocks = raw[:n_orig].reshape(limb.nq + 1, 6)
    if np.abs(blocks).max(initial=0.0) <= 1e-12:
        joint = int(np.argmax(np.abs(raw[n_orig:])))
        return {"kind": "joint zero", "feature": limb.joint_names[joint]}
    o = int(np.argmax(np.linalg.norm(blocks, axis=1)))
    placement, feature_axis, datum_axis, feature, datum = _origin(limb, o, tool_axis)
    v, w = blocks[o, :3], blocks[o, 3:]
    if unit == "m":
        nominal = settings.nominals_m.get(name)
        if nominal is None:
            offset = placement.rotation.T @ placement.translation  # the origin's offset, own frame
            nominal = abs(float(offset @ (v / np.linalg.norm(v))))
        if nominal <= ZERO_SIZE_M:
            return {"kind": "position", "feature": feature, "nominal_m": 0.0, "zone_m": 2 * t}
        fits = 1e3 * nominal <= MAX_SIZE_MM
        it = it_grade(2e6 * t, 1e3 * nominal) if fits else None
        return {"kind": "size", "feature": feature, "nominal_m": nominal, "zone_m": 2 * t, "it": it}
    # split the rotation in the feature's own frame: about its axis (tilts nothing), about the
    # common normal of feature and datum (changes the angle between them), and about the third
    # direction (swings the feature about the datum, a direction only a secondary datum fixes)
    w_hat = w / np.linalg.norm(w)
    angle = math.acos(min(1.0, abs(float(feature_axis @ datum_axis))))
    normal = np.cross(feature_axis, datum_axis)
    if np.linalg.norm(normal) < math.sin(RELATION_BAND_RAD):  # parallel axes: every tilt counts
        parts = {
            "own": abs(float(w_hat @ feature_axis)),
            "angle": float(np.linalg.norm(np.cross(w_hat, feature_axis))),
        }
    else:
        n = normal / np.linalg.norm(normal)
        parts = {
            "own": abs(float(w_hat @ feature_axis)),
            "angle": abs(float(w_hat @ n)),
            "swing": abs(float(w_hat @ np.cross(feature_axis, n))),
        }
    which = max(parts, key=lambda k: parts[k])
    if which == "own":
        return {"kind": "angular position", "feature": feature}
    if which == "swing":
        kind = "angularity"
    elif angle >= math.pi / 2 - RELATION_BAND_RAD:
        kind = "perpendicularity"
    elif angle <= RELATION_BAND_RAD:
        kind = "parallelism"
    else:
        kind = "angularity"
    length = settings.feature_length(feature)
    return {
        "kind": kind,
        "feature": feature,
        "datum": datum,
        "about_datum": which == "swing",
        "nominal_angle_rad": angle,
        "feature_length_m": length,
        # the axis tilts by that component of the rotation: over L its end moves L·tan(it · t)
        "zone_m": length * math.tan(parts[which] * t),
    }


def _check_nominals(mechanism: Mechanism, pset: ParameterSet, settings: DrawingSettings) -> None:
    if not settings.nominals_m:
        return
    names = set(pset.names)
    if pset.kind == "dh":
        names |= set(parameter_set(mechanism, "urdf").names)
    elif all(lb.dh is not None for lb in mechanism.limbs):
        names |= set(parameter_set(mechanism, "dh").names)
    bad = [n for n in settings.nominals_m if n not in names]
    if bad:
        close = difflib.get_close_matches(bad[0], sorted(names), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        path = (mechanism.root / "mechanism.toml") if mechanism.root is not None else "<mechanism>"
        raise MechanismFormatError(path, f'drawing.nominals."{bad[0]}"', f"no such error parameter{hint}")
