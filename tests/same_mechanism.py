"""Checks that one mechanism read two ways (its limb URDFs, and one closed-loop tree or MJCF file) gives
the same error table and allocation; shared by test_closed_loop.py and test_mjcf.py."""

from __future__ import annotations

import warnings
from collections.abc import Mapping

import numpy as np

from pkmtol.design.job import DesignOptions, allocate
from pkmtol.error_model.table import error_table
from pkmtol.model.mechanism import Mechanism

RTOL = 1e-9
SMALL = DesignOptions(
    parameter_set="urdf", samples=300, verification_poses=20, exact_samples=4, claim_poses=10
)


def rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference relative to the largest |a| (inf entries — free tolerances — must match)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert np.array_equal(np.isfinite(a), np.isfinite(b))
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(a)), 1e-300))


def assert_same_error_table(limbs: Mechanism, other: Mechanism, renamed: Mapping[str, str]) -> None:
    """The urdf-set error tables agree: parameter names (the attachments ``renamed``), classes, worst
    pose and sensitivities to :data:`RTOL`; the seed robot's 18 uncompensatable errors are limb 4's."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy quadrature round-off notes, identical on both sides
        ta, tb = error_table(limbs, "urdf"), error_table(other, "urdf")
    assert len(ta.pset) == len(tb.pset) == 171

    def rename(n: str) -> str:
        stem, comp = n.rsplit(".", 1)
        return f"{renamed.get(stem, stem)}.{comp}"

    assert [rename(n) for n in ta.pset.names] == tb.pset.names
    assert ta.classes == tb.classes
    assert tb.classes.count("uncompensatable") == 18
    assert {tb.pset.parameters[i].limb for i, c in enumerate(tb.classes) if c == "uncompensatable"} == {3}
    assert ta.worst_index == tb.worst_index
    assert rel(ta.sensitivity, tb.sensitivity) < RTOL
    assert rel(ta.sensitivity_uncompensated, tb.sensitivity_uncompensated) < RTOL


def assert_same_allocation(limbs: Mechanism, other: Mechanism) -> None:
    """The allocations agree: classes, toleranced errors, worst pose, tolerances (also the traditional
    method's) and the linear verification samples, to :data:`RTOL`."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ra, rb = allocate(limbs, SMALL), allocate(other, SMALL)
    assert ra.classes == rb.classes
    np.testing.assert_array_equal(ra.uncompensatable, rb.uncompensatable)
    assert ra.worst_index == rb.worst_index
    unc = ra.uncompensatable
    assert rel(ra.tolerances[unc], rb.tolerances[unc]) < RTOL
    assert rel(ra.traditional.tolerance, rb.traditional.tolerance) < RTOL
    for dist in ra.verification:
        va, vb = ra.verification[dist], rb.verification[dist]
        assert rel(va.dlam_linear_m, vb.dlam_linear_m) < RTOL
