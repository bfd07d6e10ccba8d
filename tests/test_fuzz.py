"""2,000 seeded mutants of the bundled robots' files: every failure is a pkmtol error, none hangs."""

from __future__ import annotations

import warnings

from fuzzing import HANG_S, fuzz

CASES = 2_000


def test_fuzzed_robot_folders_raise_only_pkmtol_errors(tmp_path):
    warnings.simplefilter("ignore", RuntimeWarning)
    report = fuzz(CASES, seed=2026, workdir=tmp_path)
    assert report.cases == CASES
    assert report.outcomes["BUG"] == 0, "\n\n".join(tb for _, tb in report.bugs[:3])
    assert report.hangs == [] and report.slowest_s < HANG_S
    # the mutants reach every stage: refused at TOML, at URDF, at the D–H check, and accepted ones
    # run through home closure and the error model
    for outcome in ("MechanismFormatError", "UnknownKeyError", "URDFError", "DHMismatchError", "ok"):
        assert report.outcomes[outcome] >= 20, dict(report.outcomes)
