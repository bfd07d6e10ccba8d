"""Geometric error parameters of every limb and their error twists (paper Eqs. 1–4).

Two parameter sets (DESIGN.md, "Geometric error parameters"):

* ``urdf``: every joint origin, the platform attachment included, perturbed as
  ``origin · exp6(ε)`` with ``ε = (dx, dy, dz, rx, ry, rz)`` in the origin's frame, plus each
  joint's zero offset ``q_actual = q + δq``. Names ``<limb>.<joint>.<component>``.
* ``dh``: for limbs with a D–H table, the paper's ``δθ_j, δd_j, δa_j, δφ_j`` per link and
  ``δd_e, δθ_e`` for the end link (named ``δd_{j,i}`` with ``i`` the 1-based limb number); the
  actuated joint's zero offset is named ``ξ_{a,i}`` (the paper's Table IV).

Every parameter is a fixed linear combination of "raw" limb errors: the 6 components of each
origin error (``6·(nq+1+loops)`` of them: the joints, the platform attachment, then each internal
loop's frame b, named ``<limb>.<loop>.<component>``; a ``3d`` loop contributes only its 3
translations) and the ``nq`` joint offsets. At a pose, the raw columns are Pinocchio's kinematic
regressor (origin errors, which ``computeFrameKinematicRegressor`` linearises exactly as
``jointPlacements[j] · exp6(ε)``), the identity (platform attachment) and the frame Jacobian
(offsets), all in the platform frame; they are then expressed in K' (``diag(R, R)``, i.e.
Pinocchio's LOCAL_WORLD_ALIGNED). A limb's internal loops are eliminated from them by
:mod:`pkmtol.error_model.limb_motion`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError, InvalidRequestError
from pkmtol.model.dh import dh_error_directions
from pkmtol.model.limb import Limb
from pkmtol.model.mechanism import Mechanism

COMPONENTS = ("dx", "dy", "dz", "rx", "ry", "rz")
_EYE6 = np.eye(6)
PARAMETER_SETS = ("urdf", "dh")


@dataclass(frozen=True)
class ErrorParameter:
    """One geometric error parameter.

    Attributes:
        name: Where it lives (``limb4.limb4_u1.dx``, ``δd_{2,4}``, ``ξ_{a,1}``).
        limb: Index of its limb in ``mechanism.limbs``.
        unit: ``"m"`` or ``"rad"``.
        actuator: True for the zero offset of an actuated joint (the paper's ξ_a).
    """

    name: str
    limb: int
    unit: str
    actuator: bool = False


@dataclass(frozen=True, eq=False)
class ParameterSet:
    """A named set of error parameters and how each maps to raw limb errors.

    Attributes:
        kind: ``"urdf"`` or ``"dh"``.
        parameters: All parameters, limb by limb.
        selections: Per limb, shape ``(Limb.n_raw, m_i)``: column ``k`` is parameter ``k`` of the
            limb as a combination of raw errors (origin components — joints, platform attachment,
            loops — then joint offsets).
        slices: Per limb, the slice of ``parameters`` that belongs to it.
    """

    kind: str
    parameters: tuple[ErrorParameter, ...]
    selections: tuple[np.ndarray, ...]
    slices: tuple[slice, ...]

    def __len__(self) -> int:
        return len(self.parameters)

    def _eta(self, eta: object, mechanism: object, shape: tuple[int | None, ...]) -> np.ndarray:
        """``eta`` as finite parameter values of ``shape``, for a ``mechanism`` of this set's limbs."""
        check_set(self, mechanism)
        return values.array_of_shape("eta", eta, shape)

    @property
    def names(self) -> list[str]:
        """Parameter names in order."""
        return [p.name for p in self.parameters]

    @property
    def units(self) -> list[str]:
        """Parameter units in order."""
        return [p.unit for p in self.parameters]

    def perturbation(self, eta: np.ndarray, mechanism: Mechanism) -> tuple[list[np.ndarray], np.ndarray]:
        """Split a parameter vector into origin errors and joint offsets.

        Args:
            eta: Parameter values, shape (n,) [m, rad].
            mechanism: The mechanism this set belongs to.

        Returns:
            ``(eps, offsets)``: per limb ``ε`` of shape (``Limb.n_origins``, 6) for
            :func:`pkmtol.kinematics.perturbation.perturbed_limb_models`, and joint offsets (Σ nq_i,).
        """
        eta = self._eta(eta, mechanism, (len(self),))
        eps, offsets = [], []
        for limb, sel, sl in zip(mechanism.limbs, self.selections, self.slices, strict=True):
            raw = sel @ eta[sl]
            n_orig = 6 * limb.n_origins
            eps.append(raw[:n_orig].reshape(limb.n_origins, 6))
            offsets.append(raw[n_orig:])
        return eps, np.concatenate(offsets)

    def perturbations(self, eta: np.ndarray, mechanism: Mechanism) -> tuple[list[np.ndarray], np.ndarray]:
        """:meth:`perturbation` of many parameter vectors at once.

        Args:
            eta: Shape (c, n): parameter values [m, rad].
            mechanism: The mechanism this set belongs to.

        Returns:
            ``(eps, offsets)``: per limb ``ε`` of shape (c, ``Limb.n_origins``, 6) (the ``eps`` of
            :meth:`pkmtol.kinematics.batch.BatchChain.forward`), and offsets (c, Σ nq_i).
        """
        eta = self._eta(eta, mechanism, (None, len(self)))
        eps, offsets = [], []
        for limb, sel, sl in zip(mechanism.limbs, self.selections, self.slices, strict=True):
            raw = eta[:, sl] @ sel.T
            n_orig = 6 * limb.n_origins
            eps.append(raw[:, :n_orig].reshape(-1, limb.n_origins, 6))
            offsets.append(raw[:, n_orig:])
        return eps, np.concatenate(offsets, axis=1)


def parameter_set(mechanism: Mechanism, kind: str = "urdf") -> ParameterSet:
    """The ``urdf`` or ``dh`` parameter set of a mechanism.

    Raises:
        InvalidRequestError: unknown kind, or ``dh`` asked for a limb without a D–H table.
    """
    _check_mechanism(mechanism)
    if kind == "urdf":
        per_limb = [_urdf_limb(i, limb) for i, limb in enumerate(mechanism.limbs)]
    elif kind == "dh":
        missing = [lb.name for lb in mechanism.limbs if lb.dh is None]
        if missing:
            raise InvalidRequestError(
                f"the dh parameter set needs a D–H table for every limb; missing for "
                f"{', '.join(missing)} (add [limbs.dh] in mechanism.toml or use --set urdf)"
            )
        per_limb = [_dh_limb(i, limb) for i, limb in enumerate(mechanism.limbs)]
    else:
        raise InvalidRequestError(f"unknown parameter set {kind!r}; use one of {', '.join(PARAMETER_SETS)}")
    params: list[ErrorParameter] = []
    sels, slices = [], []
    for plist, sel in per_limb:
        slices.append(slice(len(params), len(params) + len(plist)))
        params.extend(plist)
        sels.append(sel)
    return ParameterSet(kind=kind, parameters=tuple(params), selections=tuple(sels), slices=tuple(slices))


def default_set(mechanism: Mechanism) -> str:
    """``dh`` when every limb has a D–H table, else ``urdf``."""
    _check_mechanism(mechanism)
    return "dh" if all(lb.dh is not None for lb in mechanism.limbs) else "urdf"


def _urdf_limb(i: int, limb: Limb) -> tuple[list[ErrorParameter], np.ndarray]:
    nq = limb.nq
    n_raw = limb.n_raw
    params: list[ErrorParameter] = []
    origins = list(limb.joint_names) + [limb.attach_name]
    for oname in origins:
        for c, comp in enumerate(COMPONENTS):
            params.append(ErrorParameter(f"{limb.name}.{oname}.{comp}", i, "m" if c < 3 else "rad"))
    raw_cols = list(range(6 * (nq + 1)))
    for k, lp in enumerate(limb.loops):
        # a point loop's closure error is where its point b sits: the rotation of frame b is idle
        comps = range(6) if lp.kind == "6d" else range(3)
        for c in comps:
            params.append(
                ErrorParameter(f"{limb.name}.{lp.name}.{COMPONENTS[c]}", i, "m" if c < 3 else "rad")
            )
            raw_cols.append(6 * (nq + 1 + k) + c)
    for k, jname in enumerate(limb.joint_names):
        unit = "rad" if limb.joint_kinds[k] == "R" else "m"
        params.append(ErrorParameter(f"{limb.name}.{jname}.offset", i, unit, actuator=k in limb.actuated))
        raw_cols.append(6 * limb.n_origins + k)
    if len(raw_cols) == n_raw:
        return params, np.eye(n_raw)
    return params, np.eye(n_raw)[:, raw_cols]


def _dh_limb(i: int, limb: Limb) -> tuple[list[ErrorParameter], np.ndarray]:
    assert limb.dh is not None
    nq = limb.nq
    n_raw = 6 * (nq + 1) + nq
    num = i + 1
    params: list[ErrorParameter] = []
    cols: list[np.ndarray] = []
    for j, link in enumerate(dh_error_directions(limb.dh)):
        for symbol, origin, c in link:
            col = np.zeros(n_raw)
            # the joint variable of joint j-1 enters θ_j (R) or d_j (P): that parameter is the
            # joint's zero offset; for the actuated joint it is the paper's ξ_a.
            joint = j - 1
            is_offset = joint >= 0 and (
                (symbol == "θ" and limb.dh.joint_types[joint] == "R")
                or (symbol == "d" and limb.dh.joint_types[joint] == "P")
            )
            if is_offset and joint in limb.actuated:
                col[6 * (nq + 1) + joint] = 1.0
                name = f"ξ_{{a,{num}}}"
                params.append(ErrorParameter(name, i, "rad" if symbol == "θ" else "m", actuator=True))
            else:
                col[6 * origin : 6 * origin + 6] = c
                idx = "e" if symbol.endswith("_e") else str(j + 1)
                sym = symbol.removesuffix("_e")
                unit = "rad" if sym in ("θ", "φ") else "m"
                params.append(ErrorParameter(f"δ{sym}_{{{idx},{num}}}", i, unit))
            cols.append(col)
    return params, np.column_stack(cols)


def _check_mechanism(mechanism: object) -> None:
    if not isinstance(mechanism, Mechanism):
        raise InvalidArgumentError(
            "mechanism", mechanism, "expected a pkmtol.Mechanism (pkmtol.load_mechanism)"
        )


def check_set(pset: object, mechanism: object) -> None:
    """InvalidArgumentError unless ``mechanism`` is a Mechanism and ``pset`` a parameter set of its limbs."""
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism (pkmtol.load_mechanism)")
    values.instance("pset", pset, ParameterSet, "a ParameterSet of the mechanism (pkmtol.parameter_set)")
    assert isinstance(mechanism, Mechanism) and isinstance(pset, ParameterSet)
    if len(mechanism.limbs) != len(pset.selections) or any(
        sel.shape[0] != lb.n_raw for sel, lb in zip(pset.selections, mechanism.limbs, strict=True)
    ):
        raise InvalidArgumentError("pset", pset.kind, f"is not a parameter set of '{mechanism.name}'")
