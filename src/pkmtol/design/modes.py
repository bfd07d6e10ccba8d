"""The compensation mode of a design: which errors it tolerances and the maps it allocates against.

``ideal`` (default, the paper): the uncompensatable errors, maps ``J = W⁻ᵀ [0; G_c]`` at P.
``none`` (the traditional method): every non-absorbed error, maps ``J_total``.
``calibrated``: every parameter whose effect survives the calibration plan of the mechanism's
``[calibration]`` table — a non-zero column of the post-calibration map ``L`` somewhere on the
task-space grid (relative to its uncalibrated effect, as in :meth:`Sweep.classify`) — allocated
against ``L`` with the tracker noise ``σ_m² N Nᵀ`` as a fixed covariance (docs/theory.md,
"Tolerances after calibration"). Its classes are ``identified`` (removed by the calibration),
``toleranced`` (something survives) and ``absorbed``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.calibration.maps import pose_maps
from pkmtol.calibration.plan import CalibrationPlan, candidate_pool, make_plan
from pkmtol.calibration.postcal import calibrated_maps
from pkmtol.calibration.settings import CalibrationSettings, settings_from_table
from pkmtol.design.fosm import allocation_sensitivity, fosm_tolerances
from pkmtol.error_model.accuracy import first_max, grid_norm_moments, sensitivities
from pkmtol.error_model.compensation import COMPENSATIONS, AccuracyMaps, mode_maps
from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import ZERO_TOLERANCE, Sweep
from pkmtol.error_model.table import ErrorTable, error_table
from pkmtol.error_model.task import grid_sweep, machine_parameter_set
from pkmtol.exceptions import InvalidRequestError
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True, eq=False)
class GridModel:
    """The error model on the task-space grid (the first stage of the main job).

    Attributes:
        chain: The solver workspace it was solved with.
        grid: The grid sweep (error twists, separation, maps at every grid pose).
        classes: The error model's class of each parameter (absorbed / compensatable /
            uncompensatable).
    """

    chain: ClosedChain
    grid: Sweep
    classes: list[str]


def grid_model(mechanism: Mechanism, pset: ParameterSet, progress: bool = False) -> GridModel:
    """Solve the task-space grid and classify the parameters (a hybrid's: at the TCP)."""
    chain = ClosedChain(mechanism)
    grid = grid_sweep(mechanism, pset, chain, progress=progress)
    return GridModel(chain=chain, grid=grid, classes=grid.classify())


def calibration_settings(mechanism: Mechanism, given: CalibrationSettings | None) -> CalibrationSettings:
    """The calibration plan's settings: ``given``, else the mechanism's ``[calibration]`` table."""
    if given is not None:
        return given
    path = (mechanism.root / "mechanism.toml") if mechanism.root is not None else "<mechanism>"
    return settings_from_table(dict(mechanism.extra.get("calibration") or {}), path)


def plan_scale(
    pset: ParameterSet, model: GridModel, settings: CalibrationSettings, target_m: float, design_beta: float
) -> np.ndarray:
    """Expected size of every parameter: the plan's column scaling (and MAP prior).

    The manufacturing σ, and for the uncompensatable errors the ideal design's FOSM tolerances.
    """
    scale = settings.manufacturing_sigma(pset)
    unc0 = np.array([i for i, c in enumerate(model.classes) if c == "uncompensatable"], dtype=int)
    if unc0.size:
        w0 = first_max(grid_norm_moments(model.grid.J[:, :, unc0])[:, 1])
        om0, _ = allocation_sensitivity(model.grid.J, unc0, w0)
        t_ideal = fosm_tolerances(om0, target_m, np.array([design_beta]))[:, 0]
        scale[unc0] = np.where(np.isfinite(t_ideal), t_ideal, scale[unc0])
    return scale


@dataclass(frozen=True, eq=False)
class ModeSetup:
    """What a compensation mode allocates against.

    Attributes:
        mode: ``ideal``, ``calibrated`` or ``none``.
        grid_maps: The accuracy maps at the task-space grid poses.
        columns: Indices of the toleranced parameters.
        classes: Each parameter's class in this mode.
        plan: The calibration plan (``calibrated`` only).
        background: Indices of the parameters drawn at their manufacturing σ in verification
            (``calibrated``: the identified ones, whose columns vanish; empty otherwise).
    """

    mode: str
    grid_maps: AccuracyMaps
    columns: np.ndarray
    classes: list[str]
    plan: CalibrationPlan | None
    background: np.ndarray
    settings: CalibrationSettings | None = None

    def background_sigma(self, pset: ParameterSet) -> tuple[np.ndarray, np.ndarray] | None:
        """``(columns, manufacturing σ)`` of the background errors, or None without any."""
        if not self.background.size or self.settings is None:
            return None
        return self.background, self.settings.manufacturing_sigma(pset)[self.background]

    def maps_at(
        self,
        sweep_: Sweep,
        actuated_idx: np.ndarray,
        reference_point_m: np.ndarray,
        task_projection: np.ndarray | None = None,
    ) -> AccuracyMaps:
        """The same mode's maps at other poses (e.g. the random verification poses).

        ``task_projection``: the mechanism's (``Mechanism.task_projection``; default the position task).
        """
        if self.plan is None:
            return mode_maps(sweep_, self.mode)
        maps = pose_maps(sweep_, actuated_idx, reference_point_m, task_projection)
        return calibrated_maps(maps, self.plan.H, self.plan.ident, self.plan.prior_sigma)


def mode_setup(
    mechanism: Mechanism,
    pset: ParameterSet,
    grid: Sweep,
    classes: list[str],
    mode: str,
    chain: ClosedChain,
    settings: CalibrationSettings | None = None,
    scale: np.ndarray | None = None,
    tilt_axis: np.ndarray | None = None,
) -> ModeSetup:
    """Build the maps and the toleranced set of a compensation mode.

    Args:
        mechanism: The mechanism.
        pset: Its parameter set.
        grid: The task-space grid sweep.
        classes: The error model's classes (absorbed / compensatable / uncompensatable).
        mode: ``ideal``, ``calibrated`` or ``none``.
        chain: Solver workspace.
        settings: The calibration settings (``calibrated``).
        scale: Expected size of every parameter (column scaling and MAP prior of the plan).
        tilt_axis: With an orientation target, the tool axis: a parameter that tilts it survives too.

    Raises:
        InvalidRequestError: unknown mode.
    """
    if mode not in COMPENSATIONS:
        raise InvalidRequestError(f"unknown compensation {mode!r}; use one of {', '.join(COMPENSATIONS)}")
    nonabs = np.array([i for i, c in enumerate(classes) if c != "absorbed"], dtype=int)
    if mode == "ideal":
        cols = np.array([i for i, c in enumerate(classes) if c == "uncompensatable"], dtype=int)
        return ModeSetup(mode, mode_maps(grid, "ideal"), cols, list(classes), None, np.zeros(0, dtype=int))
    if mode == "none":
        mode_classes = ["absorbed" if c == "absorbed" else "toleranced" for c in classes]
        return ModeSetup(mode, mode_maps(grid, "none"), nonabs, mode_classes, None, np.zeros(0, dtype=int))
    settings = settings or CalibrationSettings()
    pool = candidate_pool(mechanism, pset, settings, chain, grid=grid)
    plan = make_plan(mechanism, pset, classes, settings, pool, scale)
    maps = calibrated_maps(
        pose_maps(grid, chain.actuated_idx, mechanism.reference_point_m, mechanism.task_projection),
        plan.H,
        plan.ident,
        plan.prior_sigma,
    )
    survives = _surviving(maps, grid, tilt_axis)
    cols = np.array([i for i in nonabs if survives[i]], dtype=int)
    mode_classes = [
        "absorbed" if c == "absorbed" else ("toleranced" if survives[i] else "identified")
        for i, c in enumerate(classes)
    ]
    background = np.array([i for i in nonabs if not survives[i]], dtype=int)
    return ModeSetup(mode, maps, cols, mode_classes, plan, background, settings)


def mode_stage(
    mechanism: Mechanism,
    pset: ParameterSet,
    model: GridModel,
    mode: str,
    calibration: CalibrationSettings | None,
    target_m: float,
    design_beta: float,
    tilt_axis: np.ndarray | None = None,
) -> ModeSetup:
    """The main job's mode-maps stage: :func:`mode_setup`, under ``calibrated`` with its plan settings.

    ``calibration``: the options' settings (None: the mechanism's ``[calibration]`` table); the
    plan's scaling comes from :func:`plan_scale`.
    """
    settings = scale = None
    if mode == "calibrated":
        settings = calibration_settings(mechanism, calibration)
        scale = plan_scale(pset, model, settings, target_m, design_beta)
    return mode_setup(
        mechanism, pset, model.grid, model.classes, mode, model.chain, settings, scale, tilt_axis
    )


def _surviving(maps: AccuracyMaps, grid: Sweep, tilt_axis: np.ndarray | None) -> np.ndarray:
    """Per parameter: whether its calibrated column is non-zero at some grid pose (relative)."""
    scale = np.maximum(1.0, np.max(np.linalg.norm(grid.J_total, axis=1), axis=0))
    effect = np.max(np.linalg.norm(maps.position, axis=1), axis=0)
    if tilt_axis is not None:
        tilt, _ = maps.tilt_maps(tilt_axis)
        effect = np.maximum(effect, np.max(np.linalg.norm(tilt, axis=1), axis=0))
    return effect / scale > ZERO_TOLERANCE


def mode_error_table(
    mechanism: Mechanism,
    kind: str | None,
    mode: str,
    settings: CalibrationSettings | None = None,
    progress: bool = False,
) -> ErrorTable:
    """The ``pkmtol errors`` table in a compensation mode: its classes, sensitivities from its maps.

    The worst pose is the largest analytic σ[Δλ] for unit errors of the toleranced parameters; the
    sensitivity of each toleranced parameter is ``‖L_{:,i}‖`` there (``J`` under ``ideal``).
    ``progress`` shows a progress bar over the grid.
    """
    if mode == "ideal":
        return error_table(mechanism, kind, progress=progress)
    pset = machine_parameter_set(mechanism, kind)
    chain = ClosedChain(mechanism)
    grid = grid_sweep(mechanism, pset, chain, progress=progress)
    classes = grid.classify()
    setup = mode_setup(mechanism, pset, grid, classes, mode, chain, settings)
    cols = setup.columns
    maps = setup.grid_maps
    worst = first_max(grid_norm_moments(maps.position[:, :, cols])[:, 1]) if cols.size else 0
    sens = np.zeros(len(pset))
    sens[cols] = sensitivities(maps.position[worst][:, cols])
    return ErrorTable(
        pset=pset,
        classes=setup.classes,
        grid=grid,
        worst_index=worst,
        sensitivity=sens,
        sensitivity_uncompensated=sensitivities(grid.J_total[worst]),
    )
