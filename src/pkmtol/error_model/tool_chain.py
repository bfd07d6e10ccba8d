"""The error model of the whole machine: the module's platform error twist at the TCP, plus the tool's.

At a pose of a hybrid machine (docs/hybrid.md, "Error model"), with ``l`` the vector O' → TCP in K:

* the TCP error twist (at the TCP, K's axes) is ``$ = A η + B Δu``:
  ``A = [Ad_l · twist_map | R₆ E_t]`` — the module's uncompensated platform twist map
  (``Separation.twist_map``, at O') moved to the TCP (``Ad_l = [[I, −[l]×], [0, I]]``), beside the
  tool chain's own error columns ``E_t`` (Pinocchio's kinematic regressor at the TCP frame: joint
  placements, the TCP frame's placement, zero offsets; ``R₆ = diag(R, R)`` to K's axes);
  ``B = [Ad_l · actuation_map | R₆ J_w]`` — what the module's and the wrist's actuators do there;
* the task error is ``S $`` with ``S`` (5 × 6) = ``[[I, 0], [0, −Q[a]×]]``: the TCP position and
  the tool axis's displacement ``ω × a`` across the axis (``Q``: two unit rows across ``a``); the
  spin about the axis is free;
* the actuators compensate the part of each error's task error they can produce, in the metric
  ``D = diag(1/Δλ* · I₃, 1/Δα* · I₂)`` (each row in units of its own target):
  ``Δu = −(D S B)⁺ D S A η`` — with the wrist free, ``D S B`` is 5 × 5 and invertible at a
  non-singular pose, so the metric does not matter and every error that reaches the task is
  compensated; with a locked wrist (3-axis work) it is the weighted least-squares split;
* classes: an error is *compensatable* when its task error lies in the span of ``S B`` at every
  pose (the residual ``S C`` vanishes), *uncompensatable* otherwise, *absorbed* when it does not
  reach the task at all (``S A`` column zero: a module-absorbed error, the tool's spin).

The ``module`` scope keeps the paper's split of the module (Eq. 25: its actuators correct
``W_aᵀ $ = 0``) with the wrist's commands unchanged: the parallel module's own compensation
carried to the TCP, the reference the whole machine is compared against.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

import pkmtol.values as values
from pkmtol.error_model.parameters import COMPONENTS, ErrorParameter, ParameterSet, parameter_set
from pkmtol.error_model.separation import Separation
from pkmtol.exceptions import InvalidRequestError
from pkmtol.kinematics.closed_chain import Pose
from pkmtol.kinematics.hybrid import HybridPose
from pkmtol.kinematics.tool_chain import orthonormal_across, tool_regressor, world_axes
from pkmtol.model.dh import dh_error_directions
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.tool import Tool

#: The two compensation scopes of a hybrid machine.
SCOPES = ("machine", "module")
#: Sub-assemblies a parameter belongs to (the report's grouping).
SUB_ASSEMBLIES = ("module", "wrist", "tool")
#: Relative singular value below which ``D S B`` loses a direction (a singular pose of the task).
RANK_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class HybridParameterSet(ParameterSet):
    """The module's parameter set followed by the tool chain's parameters.

    The module's part (``selections``, ``slices``) is unchanged, so the module's functions read
    it as before; the tool chain's parameters come after it.

    Attributes:
        tool_slice: Where the tool chain's parameters sit in ``parameters``.
        tool_selection: Shape (6·nq_t + 6 + nq_t, k): each tool parameter as raw tool errors
            (joint placements, the TCP frame's placement, zero offsets).
        module_count: Number of the module's parameters.
    """

    tool_slice: slice = field(default_factory=lambda: slice(0, 0))
    tool_selection: np.ndarray | None = None
    module_count: int = 0

    def sub_assembly(self, index: int) -> str:
        """``module``, ``wrist`` (its joints' placements and zero offsets) or ``tool`` (the TCP frame)."""
        index = values.index("index", index, len(self))
        if index < self.module_count:
            return "module"
        return "tool" if self.parameters[index].name.startswith("tool.") else "wrist"

    def module_set(self) -> ParameterSet:
        """The module's parameter set alone (the first ``module_count`` parameters)."""
        return ParameterSet(self.kind, self.parameters[: self.module_count], self.selections, self.slices)

    def tool_raw(self, eta: np.ndarray) -> np.ndarray:
        """The raw tool errors (6·nq_t + 6 + nq_t,) of a parameter vector (n,)."""
        assert self.tool_selection is not None
        return self.tool_selection @ values.vector("eta", eta, len(self))[self.tool_slice]


def hybrid_parameter_set(mechanism: Mechanism, kind: str = "urdf") -> HybridParameterSet:
    """The module's ``urdf`` or ``dh`` set, then the tool chain's ``urdf`` parameters.

    Tool parameters: ``wrist.<joint>.<dx…rz>`` (each joint's placement), ``tool.tcp.<dx…rz>``
    (the TCP frame's placement relative to the last joint: spindle run-out ``dx, dy``, tilt
    ``rx, ry``, tool length ``dz``, spin ``rz``), ``wrist.<joint>.offset`` (zero offsets; the
    actuated ones flagged as actuators).

    Raises:
        InvalidRequestError: the mechanism has no tool chain, or the module has no such set.
    """
    values.instance("mechanism", mechanism, Mechanism, "a pkmtol.Mechanism with a [tool] chain")
    tool = _tool(mechanism)
    base = parameter_set(mechanism, kind)
    if kind == "dh" and tool.dh is not None:
        dh_params, selection = _tool_dh(tool, len(mechanism.limbs))
        n0 = len(base)
        return HybridParameterSet(
            kind=base.kind,
            parameters=base.parameters + tuple(dh_params),
            selections=base.selections,
            slices=base.slices,
            tool_slice=slice(n0, n0 + len(dh_params)),
            tool_selection=selection,
            module_count=n0,
        )
    limb = len(mechanism.limbs)
    params: list[ErrorParameter] = []
    for jname in tool.joint_names:
        params += [
            ErrorParameter(f"wrist.{jname}.{c}", limb, "m" if i < 3 else "rad")
            for i, c in enumerate(COMPONENTS)
        ]
    params += [
        ErrorParameter(f"tool.tcp.{c}", limb, "m" if i < 3 else "rad") for i, c in enumerate(COMPONENTS)
    ]
    for j, (jname, k) in enumerate(zip(tool.joint_names, tool.joint_kinds, strict=True)):
        params.append(
            ErrorParameter(f"wrist.{jname}.offset", limb, "rad" if k == "R" else "m", j in tool.actuated)
        )
    n0 = len(base)
    return HybridParameterSet(
        kind=base.kind,
        parameters=base.parameters + tuple(params),
        selections=base.selections,
        slices=base.slices,
        tool_slice=slice(n0, n0 + len(params)),
        tool_selection=np.eye(len(params)),
        module_count=n0,
    )


def _tool_dh(tool: Tool, limb: int) -> tuple[list[ErrorParameter], np.ndarray]:
    """The wrist's D–H parameters (``[tool.dh]``), then the tool's own at the TCP.

    Per link ``j`` of the wrist ``wrist.δθ_j, δd_j, δa_j, δφ_j`` (and ``wrist.δd_e, δθ_e`` for the
    spindle nose), the joint variables' zero offsets ``wrist.<joint>.offset`` (as the paper's
    ξ), then the tool in the spindle: ``tool.tcp.dx, dy`` (run-out), ``dz`` (length), ``rx, ry``
    (tilt) at the TCP. The nose's errors reach the TCP frame moved by ``Ad(Tz(L)⁻¹)``.
    """
    assert tool.dh is not None
    nq = tool.nq
    n_raw = 6 * (nq + 1) + nq
    to_tcp = pin.SE3(np.eye(3), np.array([0.0, 0.0, tool.length_m])).inverse().toActionMatrix()
    params: list[ErrorParameter] = []
    cols: list[np.ndarray] = []
    for j, link in enumerate(dh_error_directions(tool.dh)):
        for symbol, origin, c in link:
            col = np.zeros(n_raw)
            joint = j - 1
            kind = tool.dh.joint_types[joint] if joint >= 0 else ""
            if joint >= 0 and ((symbol == "θ" and kind == "R") or (symbol == "d" and kind == "P")):
                col[6 * (nq + 1) + joint] = 1.0  # the joint's zero offset
                name = f"wrist.{tool.joint_names[joint]}.offset"
                params.append(
                    ErrorParameter(name, limb, "rad" if kind == "R" else "m", joint in tool.actuated)
                )
            else:
                col[6 * origin : 6 * origin + 6] = to_tcp @ c if origin == nq else c
                sym = symbol.removesuffix("_e")
                idx = "e" if symbol.endswith("_e") else str(j + 1)
                params.append(
                    ErrorParameter(f"wrist.δ{sym}_{idx}", limb, "rad" if sym in ("θ", "φ") else "m")
                )
            cols.append(col)
    for k, comp in enumerate(("dx", "dy", "dz", "rx", "ry")):
        col = np.zeros(n_raw)
        col[6 * nq + k] = 1.0
        params.append(ErrorParameter(f"tool.tcp.{comp}", limb, "m" if k < 3 else "rad"))
        cols.append(col)
    return params, np.column_stack(cols)


def task_targets(mechanism: Mechanism) -> tuple[float, float]:
    """``(Δλ* [m], Δα* [rad])``: the targets that weigh the task rows (the split's metric).

    Δα* is ``[design] orientation_target``; without it, ``Δλ* / ℓ`` with ``ℓ`` the distance from
    the module's task point P to the TCP at the tool chain's home (a tilt of Δα* then moves P by
    Δλ* about the TCP).
    """
    tool = _tool(mechanism)
    alpha = mechanism.extra.get("design", {}).get("orientation_target_rad")
    if alpha is not None:
        return float(mechanism.target_m), float(alpha)
    data = tool.model.createData()
    pin.framesForwardKinematics(tool.model, data, tool.home)
    lever = float(np.linalg.norm(data.oMf[tool.tcp_frame].translation - mechanism.reference_point_m))
    return float(mechanism.target_m), float(mechanism.target_m) / max(lever, 1e-3)


@dataclass(frozen=True, eq=False)
class ToolSeparation(Separation):
    """The whole machine's error model at one pose: a :class:`Separation` at the TCP.

    Its fields read as the module's do, at the TCP (K's axes) and over all parameters ``n``:
    ``pose`` is the TCP (``oMp`` its placement, ``p_m`` its position), ``twist_map`` is ``A``,
    ``uncompensated_map`` ``C = A + B · correction``, ``correction`` the commands of all the
    actuators (module's, then the wrist's) per unit error, ``actuation_map`` ``B``, ``J`` and
    ``J_total`` the TCP position rows of ``C`` and ``A``; ``Y_a`` (5, n) the task error the
    actuators remove, ``Y_c`` (5, n) the task error left (``S C``), ``W_condition`` the condition
    number of ``D S B``. The module's wrenches stay in ``W_a``/``W_c``.

    Attributes:
        hybrid: The machine's pose (module pose, tool joints, TCP).
        module: The module's own separation at its pose (at O').
        task_map: Shape (5, n) (3 for a locked wrist it is still 5): ``S A``, the task error before
            compensation [m, rad per unit].
        task_rows: Shape (5, 6): ``S``.
        scope: ``machine`` or ``module`` (see the module docstring).
        frame_map: Shape (6, n): the part of ``twist_map`` that moves the TCP frame alone: the
            tool's own errors (``tool.*``: run-out, length, tilt of the tool in the spindle); a
            point fixed on the spindle moves by ``twist_map − frame_map``.
    """

    hybrid: HybridPose | None = None
    module: Separation | None = None
    task_map: np.ndarray | None = None
    task_rows: np.ndarray | None = None
    scope: str = "machine"
    frame_map: np.ndarray | None = None


def tool_columns(
    tool: Tool, pset: HybridParameterSet, hpose: HybridPose, model: pin.Model | None = None
) -> np.ndarray:
    """The tool chain's error columns (6, k) at the TCP, K's axes, per tool parameter."""
    m = tool.model if model is None else model
    raw = tool_regressor(tool, m, m.createData(), hpose.q_tool)
    assert pset.tool_selection is not None
    return world_axes(hpose.oMt.rotation, raw @ pset.tool_selection)


def tool_separation(
    mechanism: Mechanism,
    pset: HybridParameterSet,
    hpose: HybridPose,
    module: Separation,
    scope: str = "machine",
    targets: tuple[float, float] | None = None,
) -> ToolSeparation:
    """The whole machine's error model and its split at a solved pose.

    Args:
        mechanism: The hybrid machine.
        pset: Its parameter set (:func:`hybrid_parameter_set`).
        hpose: The machine's pose.
        module: The module's separation at ``hpose.module`` for ``pset``'s module part.
        scope: ``machine`` (all actuators compensate, the default) or ``module`` (the module's
            Eq. 25, the wrist's commands unchanged).
        targets: ``(Δλ*, Δα*)`` of the metric (default :func:`task_targets`).

    Raises:
        InvalidRequestError: an unknown scope.
    """
    if scope not in SCOPES:
        raise InvalidRequestError(f"unknown compensation scope {scope!r}; use one of {', '.join(SCOPES)}")
    tool = _tool(mechanism)
    n, n0 = len(pset), pset.module_count
    lever = hpose.tcp_m - np.asarray(hpose.module.oMp.translation)
    shift = np.eye(6)
    shift[:3, 3:] = -pin.skew(lever)
    a_map = np.zeros((6, n))
    a_map[:, :n0] = shift @ module.twist_map
    a_map[:, pset.tool_slice] = tool_columns(tool, pset, hpose)
    assert pset.tool_selection is not None
    frame_map = np.zeros((6, n))  # the tool's own errors (``tool.*``: its placement in the spindle)
    frame_map[:, pset.tool_slice] = world_axes(
        hpose.oMt.rotation, pset.tool_selection[6 * tool.nq : 6 * tool.nq + 6]
    )
    frame_map[:, [i for i in range(n) if pset.sub_assembly(i) != "tool"]] = 0.0
    assert module.actuation_map is not None
    jt = pin.computeFrameJacobian(
        tool.model, tool.model.createData(), hpose.q_tool, tool.tcp_frame, pin.LOCAL
    )
    b_map = np.hstack(
        [shift @ module.actuation_map, world_axes(hpose.oMt.rotation, jt[:, list(tool.actuated)])]
    )
    s = np.zeros((5, 6))
    s[:3, :3] = np.eye(3)
    s[3:, 3:] = -orthonormal_across(hpose.axis) @ pin.skew(hpose.axis)
    lam, alpha = task_targets(mechanism) if targets is None else targets
    d = np.array([1 / lam] * 3 + [1 / alpha] * 2)
    sa = s @ a_map
    if scope == "machine":
        m = d[:, None] * (s @ b_map)
        sv = np.linalg.svd(m, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        correction = -np.linalg.pinv(m, rcond=RANK_TOLERANCE) @ (d[:, None] * sa)
    else:
        f = module.actuation_map.shape[1]
        correction = np.zeros((f + len(tool.actuated), n))
        correction[:f, :n0] = module.correction
        cond = float(module.W_condition)
    c_map = a_map + b_map @ correction
    sc = s @ c_map
    return ToolSeparation(
        pose=Pose(
            q=hpose.module.q,
            oMp=hpose.oMt,
            p_m=hpose.tcp_m,
            residual=hpose.residual,
            condition=hpose.condition,
        ),
        joint_twists=module.joint_twists,
        error_columns=a_map,
        W_a=module.W_a,
        W_c=module.W_c,
        constraint_limb=module.constraint_limb,
        actuated_limb=module.actuated_limb,
        Lambda_a=module.Lambda_a,
        Y_a=sa - sc,
        Y_c=sc,
        W_condition=cond,
        twist_map=a_map,
        correction=correction,
        uncompensated_map=c_map,
        lever_m=lever,
        J=c_map[:3],
        J_total=a_map[:3],
        redundancy=0,
        incompatible_map=None,
        actuation_map=b_map,
        hybrid=hpose,
        module=module,
        task_map=sa,
        task_rows=s,
        scope=scope,
        frame_map=frame_map,
    )


def _tool(mechanism: Mechanism) -> Tool:
    if mechanism.tool is None:
        raise InvalidRequestError(
            f"mechanism '{mechanism.name}' has no tool chain; add a [tool] table (docs/hybrid.md)"
        )
    return mechanism.tool
