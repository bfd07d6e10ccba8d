"""The truth test on the hybrid machines (DESIGN.md, "The truth test"; docs/hybrid.md).

For each bundled hybrid, the linear maps of the whole machine (the module's and the tool chain's
parameters) against exact perturbed solves: (1) the TCP error twist ``A η`` with the commands at
nominal, (2) the task error after the correction, ``S C η``; both second order (the mismatch shrinks
tenfold with the perturbation). (3) Classes by exact single-parameter compensation: a parameter
classed compensatable leaves ≤ 1e-3 of its task error after the exact best compensation, an
uncompensatable one leaves what ``S C`` predicts.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hybrid_checks import error_twist, exact_compensation, exact_tcp, relative, task_error

from pkmtol import load_mechanism
from pkmtol.error_model.tool_chain import hybrid_parameter_set, task_targets
from pkmtol.error_model.tool_sweep import hybrid_sweep, tool_task_grid

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
HYBRIDS = ["r2rps_ups_wrist", "tricept_wrist"]


def _locked(mech):
    """The machine with its wrist locked at C = 90°, A = 45° (3-axis work: the task is the TCP position)."""
    tool = mech.tool.with_locked({"wrist_c": np.pi / 2, "wrist_a": np.pi / 4})
    return dataclasses.replace(mech, tool=tool, tool_directions=None)


def _sweep(mech, kind, scope, picks):
    ps = hybrid_parameter_set(mech, kind)
    tcp, axes = tool_task_grid(mech)
    idx = np.asarray(picks) % len(tcp)
    sw = hybrid_sweep(mech, ps, tcp[idx], None if axes is None else axes[idx], scope=scope)
    return ps, sw


CASES = [
    (name, kind, scope, locked)
    for name in HYBRIDS
    for kind, scope, locked in (
        ("urdf", "machine", False),
        ("dh", "module", False),
        ("urdf", "machine", True),
    )
]


@pytest.mark.parametrize(("name", "kind", "scope", "locked"), CASES)
def test_linear_maps_match_exact_kinematics_to_second_order(name, kind, scope, locked) -> None:
    mech = load_mechanism(ROBOTS / name)
    if locked:
        mech = _locked(mech)
    ps, sw = _sweep(mech, kind, scope, [0, 200, 524])
    rng = np.random.default_rng(27)
    for sep in sw.separations:
        direction = rng.normal(size=len(ps))
        mism = {}
        for size in (1e-5, 1e-6):
            eta = size * direction
            twist = error_twist(sep.pose.oMp, exact_tcp(mech, ps, sep, eta))
            corrected = task_error(sep, exact_tcp(mech, ps, sep, eta, sep.correction @ eta))
            left = sep.Y_c @ eta
            if np.linalg.norm(left) > 1e-3 * size:  # step 2: the residual the linear model predicts
                mism[size] = (relative(twist, sep.twist_map @ eta), relative(corrected, left))
            else:  # everything compensated: what is left, relative to the uncorrected task error
                raw = task_error(sep, exact_tcp(mech, ps, sep, eta))
                mism[size] = (
                    relative(twist, sep.twist_map @ eta),
                    float(np.linalg.norm(corrected) / np.linalg.norm(raw)),
                )
        for step in (0, 1):
            assert mism[1e-6][step] <= 1e-3, (name, step, mism)
            # second order: a tenth of the perturbation leaves about a tenth of the mismatch
            assert mism[1e-5][step] / max(mism[1e-6][step], 1e-300) >= 5.0 or mism[1e-5][step] < 1e-6, mism


@pytest.mark.parametrize(("name", "kind", "scope", "locked"), CASES)
def test_classes_follow_exact_single_parameter_compensation(name, kind, scope, locked) -> None:
    mech = load_mechanism(ROBOTS / name)
    if locked:
        mech = _locked(mech)
    ps, sw = _sweep(mech, kind, scope, [100])
    classes = sw.classify()
    sep = sw.separations[0]
    targets = task_targets(mech)
    seen = set()
    for i, cls in enumerate(classes):
        if cls == "absorbed":
            continue
        eta = np.zeros(len(ps))
        eta[i] = 1e-5
        raw = task_error(sep, exact_tcp(mech, ps, sep, eta))
        if scope == "machine":
            left = exact_compensation(mech, ps, sep, eta, targets)
        else:  # the module's Eq. 25, the wrist's commands unchanged: the correction itself
            left = task_error(sep, exact_tcp(mech, ps, sep, eta, sep.correction @ eta))
        predicted = sep.Y_c[:, i] * 1e-5
        if cls == "compensatable":
            # second-order floor 10 η²: a nearly absorbed error's raw task error is itself tiny
            assert np.linalg.norm(left) <= 1e-3 * np.linalg.norm(raw) + 1e-9, (ps.names[i], left, raw)
        else:
            assert np.linalg.norm(predicted) > 1e-3 * np.linalg.norm(raw)
            assert relative(left, predicted) <= 2e-3, (ps.names[i], left, predicted)
        seen.add(cls)
    if locked or scope == "module":
        assert seen == {"compensatable", "uncompensatable"}
    else:  # two wrist actuators span the 5-row task: every error that reaches it is compensated
        assert seen == {"compensatable"}
