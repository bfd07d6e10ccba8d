"""Checks of the main job's options (``DesignOptions``), run when they are made: each names the field.

:func:`check_options` is called by ``DesignOptions.__post_init__``, so that a wrong value fails
where it is written, not minutes later inside :func:`~pkmtol.design.job.allocate`.
"""

from __future__ import annotations

from typing import Any

import pkmtol.values as values
from pkmtol.calibration.settings import CalibrationSettings
from pkmtol.design.exact import CRITERIA
from pkmtol.error_model.compensation import COMPENSATIONS
from pkmtol.error_model.parameters import PARAMETER_SETS
from pkmtol.exceptions import InvalidArgumentError

#: Design methods of :func:`~pkmtol.design.job.allocate`.
METHODS = ("fosm", "exact", "cost")
#: The default design method of ``allocate`` and ``sweep``.
DEFAULT_METHOD = "exact"
#: The default criterion of the ``exact`` method: R ≥ R* at every grid pose.
DEFAULT_CRITERION = "every"
#: Fewest Monte Carlo samples (a sample standard deviation needs two).
MIN_SAMPLES = 2


def check_options(opt: Any) -> None:
    """Raise InvalidArgumentError naming the first wrong field of a ``DesignOptions``.

    Checked: ``target_m`` a positive number of metres (or None); ``betas`` positive numbers (or
    None; stored as a tuple); ``design_beta`` positive (or None); ``parameter_set`` one of
    :data:`~pkmtol.error_model.parameters.PARAMETER_SETS` (or None); ``samples`` ≥ 2,
    ``verification_poses`` ≥ 1, ``exact_samples`` ≥ 0, ``claim_poses`` ≥ 1 and ``seed`` ≥ 0 whole
    numbers (not bool, not float); ``progress`` a bool; ``method`` one of :data:`METHODS`;
    ``criterion`` one of ``CRITERIA``, and other than ``"every"`` only with ``method="exact"``
    (the only method that reads it); ``compensation`` one of ``COMPENSATIONS``; ``calibration``
    a ``CalibrationSettings`` (or None); ``orientation_target_rad`` positive (or None);
    ``tool_axis`` three finite numbers, not all zero (or None).
    """
    if opt.target_m is not None:
        if isinstance(opt.target_m, str):
            values.length_m("target_m", opt.target_m)
        if isinstance(opt.target_m, bool) or not _is_positive(opt.target_m):
            raise InvalidArgumentError(
                "target_m", opt.target_m, "the required accuracy Δλ* must be positive, in metres (e.g. 5e-5)"
            )
        values.length_m("target_m", opt.target_m)  # and within ±1e4 m
    if opt.betas is not None:
        betas = values.array("betas", opt.betas, ndim=1)
        if betas.size == 0 or (betas <= 0).any():
            raise InvalidArgumentError("betas", opt.betas, "every reliability index β must be positive")
        object.__setattr__(opt, "betas", tuple(float(b) for b in betas))
    if opt.design_beta is not None and (
        isinstance(opt.design_beta, bool) or not _is_positive(opt.design_beta)
    ):
        raise InvalidArgumentError("design_beta", opt.design_beta, "the design β must be positive")
    if opt.parameter_set is not None:
        values.choice("parameter_set", opt.parameter_set, PARAMETER_SETS)
    values.count("samples", opt.samples, low=MIN_SAMPLES)
    values.count("verification_poses", opt.verification_poses, low=1)
    values.count("exact_samples", opt.exact_samples, low=0)
    values.count("claim_poses", opt.claim_poses, low=1)
    values.count("seed", opt.seed, low=0)
    values.flag("progress", opt.progress)
    values.choice("method", opt.method, METHODS)
    values.choice("criterion", opt.criterion, CRITERIA)
    values.choice("compensation", opt.compensation, COMPENSATIONS)
    if opt.calibration is not None and not isinstance(opt.calibration, CalibrationSettings):
        raise InvalidArgumentError("calibration", opt.calibration, "expected a CalibrationSettings (or None)")
    if opt.orientation_target_rad is not None:
        values.number("orientation_target_rad", opt.orientation_target_rad, positive=True)
    if opt.tool_axis is not None:
        axis = values.vector("tool_axis", opt.tool_axis, 3)
        if float(abs(axis).max()) == 0.0:
            raise InvalidArgumentError(
                "tool_axis", opt.tool_axis, "expected a non-zero [x, y, z] (platform frame)"
            )
    if opt.criterion != "every" and opt.method != "exact":
        raise InvalidArgumentError(
            "criterion",
            opt.criterion,
            f"only method 'exact' reads a criterion; method {opt.method!r} would ignore it "
            "(use method='exact', or leave criterion at 'every')",
        )


def _is_positive(x: Any) -> bool:
    try:
        return values.number("value", x, positive=True) > 0
    except InvalidArgumentError:
        return False
