"""pkmtol: accuracy design of lower-mobility parallel kinematic machines on Pinocchio.

The pipeline, one module each: :mod:`~pkmtol.mechanism` (limbs from URDF or ``pin.Model``),
:mod:`~pkmtol.kinematics` (closed chain), :mod:`~pkmtol.error_model` (error parameters and their
twists), :mod:`~pkmtol.separation` (wrenches, compensatable/uncompensatable split),
:mod:`~pkmtol.sweep` (over many poses), :mod:`~pkmtol.allocation` (FOSM tolerances),
:mod:`~pkmtol.montecarlo` (pose search, verification), :mod:`~pkmtol.reliability` (exact R),
:mod:`~pkmtol.exact_design` and :mod:`~pkmtol.cost` (better designs), :mod:`~pkmtol.design` (the
main job), :mod:`~pkmtol.report` (tables and files). Everything is SI (m, rad); frames are named
in every docstring (K: base, K': platform point with base axes).

>>> import pkmtol
>>> mech = pkmtol.load_mechanism("robots/r2rps_ups")   # doctest: +SKIP
>>> result = pkmtol.allocate(mech)                       # doctest: +SKIP
"""

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
from pkmtol.exceptions import (
    ClosedLoopError,
    ClosureFrameError,
    ConvergenceError,
    InvalidRequestError,
    JointLimitError,
    KinematicsError,
    LostElementError,
    MechanismFormatError,
    MJCFError,
    MobilityError,
    MultiDofJointError,
    NoLoopError,
    OutputError,
    PkmtolError,
    PlatformMismatchError,
    PointLoopError,
    SingularPoseError,
    TendonError,
    UnknownJointError,
    UnknownMotorError,
    UnreachableTargetError,
    UnsupportedEqualityError,
    URDFError,
)
from pkmtol.kinematics.closed_chain import ClosedChain, Pose
from pkmtol.kinematics.perturbation import perturbed_limb_models
from pkmtol.model.closed_loop import closed_loop_limbs, load_closed_loop
from pkmtol.model.constraints import ConstrainedModel, constraint_models
from pkmtol.model.drawing import DrawingSettings
from pkmtol.model.limb import Limb
from pkmtol.model.loader import load_mechanism
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.mjcf import load_mjcf, mjcf_limbs
from pkmtol.model.taskspace import TaskSpace
from pkmtol.present.html_report import write_report
from pkmtol.present.tables import summary_text, to_json, write_outputs

__all__ = [
    "ClosedChain",
    "ClosedLoopError",
    "ClosureFrameError",
    "ConstrainedModel",
    "ConvergenceError",
    "DesignOptions",
    "DesignResult",
    "DrawingSettings",
    "ErrorParameter",
    "ErrorTable",
    "FailureStats",
    "InvalidRequestError",
    "JointLimitError",
    "KinematicsError",
    "Limb",
    "LostElementError",
    "MJCFError",
    "Mechanism",
    "MechanismFormatError",
    "MethodDesign",
    "MobilityError",
    "MultiDofJointError",
    "NoLoopError",
    "OutputError",
    "ParameterSet",
    "PkmtolError",
    "PlatformMismatchError",
    "PointLoopError",
    "Pose",
    "PoseSearch",
    "Separation",
    "SignOff",
    "SingularPoseError",
    "Sweep",
    "TaskSpace",
    "TendonError",
    "Traditional",
    "URDFError",
    "UnknownJointError",
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
    "sign_off",
    "summary_text",
    "sweep",
    "to_json",
    "verify",
    "write_outputs",
    "write_report",
]
__version__ = "0.1.0"
