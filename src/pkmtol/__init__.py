"""pkmtol: accuracy design of lower-mobility parallel kinematic machines on Pinocchio.

The pipeline, one module each: :mod:`~pkmtol.mechanism` (limbs from URDF or ``pin.Model``),
:mod:`~pkmtol.kinematics` (closed chain), :mod:`~pkmtol.error_model` (error parameters and their
twists), :mod:`~pkmtol.separation` (wrenches, compensatable/uncompensatable split),
:mod:`~pkmtol.sweep` (over many poses), :mod:`~pkmtol.allocation` (FOSM tolerances),
:mod:`~pkmtol.montecarlo` (pose search, verification), :mod:`~pkmtol.reliability` (exact R),
:mod:`~pkmtol.exact_design` and :mod:`~pkmtol.cost` (better designs), :mod:`~pkmtol.design` (the
main job), :mod:`~pkmtol.report` (tables and files). Everything is SI (m, rad); frames are named
in every docstring (K: base, K': platform point with base axes).

Importing the package is cheap: a name of :data:`__all__` imports its module on first use
(PEP 562), so ``pkmtol check`` never loads what only ``allocate`` needs.

>>> import pkmtol
>>> mech = pkmtol.load_mechanism("robots/r2rps_ups")   # doctest: +SKIP
>>> result = pkmtol.allocate(mech)                       # doctest: +SKIP
"""

from __future__ import annotations

import importlib
import os
import sys

# One BLAS thread per process, unless the caller chose: pkmtol's matrices are small (a few hundred
# rows), so threads buy nothing, and on a loaded machine OpenBLAS's spinning threads made a 120×53
# SVD 100× slower (0.1 s instead of 1 ms; docs/scale.md). Parallel work is spread over processes
# (the executor). The variables only act before numpy is first imported.
if "numpy" not in sys.modules:
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the names as static tools see them; at run time they load on first use
    from pkmtol.design.fosm import fosm_tolerances
    from pkmtol.design.job import DesignOptions, DesignResult, Traditional, allocate
    from pkmtol.design.methods import MethodDesign, method_design_for
    from pkmtol.design.pose_search import PoseSearch, search_sensitive_pose
    from pkmtol.design.reliability import exact_reliability, reliability_fosm
    from pkmtol.design.signoff import SignOff, sign_off
    from pkmtol.design.verification import FailureStats, Verification, verify
    from pkmtol.error_model.accuracy import norm_moments, sensitivities
    from pkmtol.error_model.parameters import ErrorParameter, ParameterSet, default_set, parameter_set
    from pkmtol.error_model.separation import Separation, separate
    from pkmtol.error_model.sweep import Sweep, sweep
    from pkmtol.error_model.table import ErrorTable, error_table
    from pkmtol.error_model.tool_chain import HybridParameterSet, hybrid_parameter_set
    from pkmtol.error_model.tool_sweep import ToolSweep, hybrid_sweep
    from pkmtol.error_model.tree_parameters import TreeParameters, tree_urdf_set
    from pkmtol.error_model.tree_separation import frame_maps, separate_tree, tree_sweep
    from pkmtol.exceptions import (
        ClosedLoopError,
        ClosureFrameError,
        ConvergenceError,
        DHMismatchError,
        InvalidArgumentError,
        InvalidRequestError,
        JointLimitError,
        KinematicsError,
        LoopMismatchError,
        LostElementError,
        MechanismFormatError,
        MissingLimitError,
        MissingLimitWarning,
        MissingMeshWarning,
        MJCFError,
        MobilityError,
        MultiDofJointError,
        NoLoopError,
        OutputError,
        OutputLockedError,
        PkmtolError,
        PkmtolWarning,
        PlatformMismatchError,
        PointLoopError,
        ResourceLimitError,
        RobotCheckError,
        SingularPoseError,
        TendonError,
        UnknownJointError,
        UnknownKeyError,
        UnknownMotorError,
        UnreachableTargetError,
        UnsupportedEqualityError,
        URDFError,
    )
    from pkmtol.kinematics.closed_chain import ClosedChain, Pose
    from pkmtol.kinematics.hybrid import HybridChain
    from pkmtol.kinematics.hybrid_pose import HybridPose
    from pkmtol.kinematics.perturbation import perturbed_limb_models
    from pkmtol.kinematics.tree_chain import TreeBatch, TreeChain
    from pkmtol.model.closed_loop import closed_loop_limbs, load_closed_loop
    from pkmtol.model.constraints import ConstrainedModel, constraint_models
    from pkmtol.model.drawing import DrawingSettings
    from pkmtol.model.limb import Limb, LimbLoop
    from pkmtol.model.loader import load_mechanism
    from pkmtol.model.loop_tree import LoopTree, PointTask
    from pkmtol.model.mechanism import Mechanism
    from pkmtol.model.mjcf import load_mjcf, mjcf_limbs, tree_from_mjcf
    from pkmtol.model.taskspace import TaskSpace, ToolDirections
    from pkmtol.model.tool import Tool
    from pkmtol.model.tree_from_limbs import tree_from_mechanism
    from pkmtol.model.tree_inputs import tree_from_constraint_models, tree_from_urdf
    from pkmtol.present.html_report import write_report
    from pkmtol.present.outputs import write_outputs
    from pkmtol.present.tables import summary_text, to_json

_EXPORTS = {
    "ClosedChain": "pkmtol.kinematics.closed_chain",
    "ClosedLoopError": "pkmtol.exceptions",
    "ClosureFrameError": "pkmtol.exceptions",
    "ConstrainedModel": "pkmtol.model.constraints",
    "ConvergenceError": "pkmtol.exceptions",
    "DHMismatchError": "pkmtol.exceptions",
    "DesignOptions": "pkmtol.design.job",
    "DesignResult": "pkmtol.design.job",
    "DrawingSettings": "pkmtol.model.drawing",
    "ErrorParameter": "pkmtol.error_model.parameters",
    "ErrorTable": "pkmtol.error_model.table",
    "FailureStats": "pkmtol.design.verification",
    "HybridChain": "pkmtol.kinematics.hybrid",
    "HybridParameterSet": "pkmtol.error_model.tool_chain",
    "HybridPose": "pkmtol.kinematics.hybrid_pose",
    "InvalidArgumentError": "pkmtol.exceptions",
    "InvalidRequestError": "pkmtol.exceptions",
    "JointLimitError": "pkmtol.exceptions",
    "KinematicsError": "pkmtol.exceptions",
    "Limb": "pkmtol.model.limb",
    "LimbLoop": "pkmtol.model.limb",
    "LoopMismatchError": "pkmtol.exceptions",
    "LoopTree": "pkmtol.model.loop_tree",
    "LostElementError": "pkmtol.exceptions",
    "MJCFError": "pkmtol.exceptions",
    "Mechanism": "pkmtol.model.mechanism",
    "MechanismFormatError": "pkmtol.exceptions",
    "MethodDesign": "pkmtol.design.methods",
    "MissingLimitError": "pkmtol.exceptions",
    "MissingLimitWarning": "pkmtol.exceptions",
    "MissingMeshWarning": "pkmtol.exceptions",
    "MobilityError": "pkmtol.exceptions",
    "MultiDofJointError": "pkmtol.exceptions",
    "NoLoopError": "pkmtol.exceptions",
    "OutputError": "pkmtol.exceptions",
    "OutputLockedError": "pkmtol.exceptions",
    "ParameterSet": "pkmtol.error_model.parameters",
    "PkmtolError": "pkmtol.exceptions",
    "PkmtolWarning": "pkmtol.exceptions",
    "PlatformMismatchError": "pkmtol.exceptions",
    "PointLoopError": "pkmtol.exceptions",
    "PointTask": "pkmtol.model.loop_tree",
    "Pose": "pkmtol.kinematics.closed_chain",
    "PoseSearch": "pkmtol.design.pose_search",
    "ResourceLimitError": "pkmtol.exceptions",
    "RobotCheckError": "pkmtol.exceptions",
    "Separation": "pkmtol.error_model.separation",
    "SignOff": "pkmtol.design.signoff",
    "SingularPoseError": "pkmtol.exceptions",
    "Sweep": "pkmtol.error_model.sweep",
    "TaskSpace": "pkmtol.model.taskspace",
    "TendonError": "pkmtol.exceptions",
    "Tool": "pkmtol.model.tool",
    "ToolDirections": "pkmtol.model.taskspace",
    "ToolSweep": "pkmtol.error_model.tool_sweep",
    "Traditional": "pkmtol.design.job",
    "TreeBatch": "pkmtol.kinematics.tree_chain",
    "TreeChain": "pkmtol.kinematics.tree_chain",
    "TreeParameters": "pkmtol.error_model.tree_parameters",
    "URDFError": "pkmtol.exceptions",
    "UnknownJointError": "pkmtol.exceptions",
    "UnknownKeyError": "pkmtol.exceptions",
    "UnknownMotorError": "pkmtol.exceptions",
    "UnreachableTargetError": "pkmtol.exceptions",
    "UnsupportedEqualityError": "pkmtol.exceptions",
    "Verification": "pkmtol.design.verification",
    "allocate": "pkmtol.design.job",
    "closed_loop_limbs": "pkmtol.model.closed_loop",
    "constraint_models": "pkmtol.model.constraints",
    "default_set": "pkmtol.error_model.parameters",
    "error_table": "pkmtol.error_model.table",
    "exact_reliability": "pkmtol.design.reliability",
    "fosm_tolerances": "pkmtol.design.fosm",
    "frame_maps": "pkmtol.error_model.tree_separation",
    "hybrid_parameter_set": "pkmtol.error_model.tool_chain",
    "hybrid_sweep": "pkmtol.error_model.tool_sweep",
    "load_closed_loop": "pkmtol.model.closed_loop",
    "load_mechanism": "pkmtol.model.loader",
    "load_mjcf": "pkmtol.model.mjcf",
    "method_design_for": "pkmtol.design.methods",
    "mjcf_limbs": "pkmtol.model.mjcf",
    "norm_moments": "pkmtol.error_model.accuracy",
    "parameter_set": "pkmtol.error_model.parameters",
    "perturbed_limb_models": "pkmtol.kinematics.perturbation",
    "reliability_fosm": "pkmtol.design.reliability",
    "search_sensitive_pose": "pkmtol.design.pose_search",
    "sensitivities": "pkmtol.error_model.accuracy",
    "separate": "pkmtol.error_model.separation",
    "separate_tree": "pkmtol.error_model.tree_separation",
    "sign_off": "pkmtol.design.signoff",
    "summary_text": "pkmtol.present.tables",
    "sweep": "pkmtol.error_model.sweep",
    "to_json": "pkmtol.present.tables",
    "tree_from_constraint_models": "pkmtol.model.tree_inputs",
    "tree_from_mechanism": "pkmtol.model.tree_from_limbs",
    "tree_from_mjcf": "pkmtol.model.mjcf",
    "tree_from_urdf": "pkmtol.model.tree_inputs",
    "tree_sweep": "pkmtol.error_model.tree_separation",
    "tree_urdf_set": "pkmtol.error_model.tree_parameters",
    "verify": "pkmtol.design.verification",
    "write_outputs": "pkmtol.present.outputs",
    "write_report": "pkmtol.present.html_report",
}

__all__ = [
    "ClosedChain",
    "ClosedLoopError",
    "ClosureFrameError",
    "ConstrainedModel",
    "ConvergenceError",
    "DHMismatchError",
    "DesignOptions",
    "DesignResult",
    "DrawingSettings",
    "ErrorParameter",
    "ErrorTable",
    "FailureStats",
    "HybridChain",
    "HybridParameterSet",
    "HybridPose",
    "InvalidArgumentError",
    "InvalidRequestError",
    "JointLimitError",
    "KinematicsError",
    "Limb",
    "LimbLoop",
    "LoopMismatchError",
    "LoopTree",
    "LostElementError",
    "MJCFError",
    "Mechanism",
    "MechanismFormatError",
    "MethodDesign",
    "MissingLimitError",
    "MissingLimitWarning",
    "MissingMeshWarning",
    "MobilityError",
    "MultiDofJointError",
    "NoLoopError",
    "OutputError",
    "OutputLockedError",
    "ParameterSet",
    "PkmtolError",
    "PkmtolWarning",
    "PlatformMismatchError",
    "PointLoopError",
    "PointTask",
    "Pose",
    "PoseSearch",
    "ResourceLimitError",
    "RobotCheckError",
    "Separation",
    "SignOff",
    "SingularPoseError",
    "Sweep",
    "TaskSpace",
    "TendonError",
    "Tool",
    "ToolDirections",
    "ToolSweep",
    "Traditional",
    "TreeBatch",
    "TreeChain",
    "TreeParameters",
    "URDFError",
    "UnknownJointError",
    "UnknownKeyError",
    "UnknownMotorError",
    "UnreachableTargetError",
    "UnsupportedEqualityError",
    "Verification",
    "allocate",
    "closed_loop_limbs",
    "constraint_models",
    "default_set",
    "error_table",
    "exact_reliability",
    "fosm_tolerances",
    "frame_maps",
    "hybrid_parameter_set",
    "hybrid_sweep",
    "load_closed_loop",
    "load_mechanism",
    "load_mjcf",
    "method_design_for",
    "mjcf_limbs",
    "norm_moments",
    "parameter_set",
    "perturbed_limb_models",
    "reliability_fosm",
    "search_sensitive_pose",
    "sensitivities",
    "separate",
    "separate_tree",
    "sign_off",
    "summary_text",
    "sweep",
    "to_json",
    "tree_from_constraint_models",
    "tree_from_mechanism",
    "tree_from_mjcf",
    "tree_from_urdf",
    "tree_sweep",
    "tree_urdf_set",
    "verify",
    "write_outputs",
    "write_report",
]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    """Import the module of a public name on first use and keep the name here."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'pkmtol' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
