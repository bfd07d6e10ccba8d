"""The main job as a pipeline of stages, shared with `pkmtol sweep` (issues 24.6 and 29.1).

`sweep` and `allocate` run the same allocation: the tolerances a sweep prints for a variant are
the design-β tolerances `allocate` finds on that variant's mechanism with the same options.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from pkmtol.design.job import DesignOptions, StageClock, allocate
from pkmtol.design.synthesis import parse_vary, synthesize, variant_mechanism
from pkmtol.model.loader import load_mechanism

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
KEY = "reference_point.position_m[2]"
#: The cheapest options of `allocate` (only its tolerances are compared).
CHEAP = {"samples": 2, "exact_samples": 0, "verification_poses": 1, "claim_poses": 1}


def _variant(values: dict[str, float]):
    doc = tomllib.loads((SEED / "mechanism.toml").read_text(encoding="utf-8"))
    texts = {lb.name: lb.urdf_path.read_text(encoding="utf-8") for lb in load_mechanism(SEED).limbs}
    return variant_mechanism(SEED, doc, texts, values)


@pytest.mark.parametrize("method", ["fosm", "exact"])
def test_sweep_and_allocate_give_the_same_tolerances_on_a_variant(method):
    """At l = 0.1 m the old sweep left six parameters free; allocate tolerances all of them (29.1)."""
    sweep = synthesize(SEED, [parse_vary(f"{KEY}=0.1:0.1:1")], method=method)
    var = sweep.variants[0]
    assert var.reachable, var.reason
    result = allocate(_variant(var.values), DesignOptions(method=method, **CHEAP))
    unc = result.uncompensatable
    assert var.names == tuple(result.pset.names[i] for i in unc)
    expected = (
        result.method_design.sigma
        if result.method_design is not None
        else result.tolerances[unc, result.design_column]
    )
    np.testing.assert_allclose(var.tolerances, expected, rtol=1e-12, atol=0)
    assert np.all(np.isfinite(var.tolerances)), "no parameter is left free"
    assert result.worst_point_m == pytest.approx(var.worst_point_m, abs=1e-12)


def test_stage_clock_times_each_named_stage_and_returns_its_result():
    clock = StageClock()
    assert clock("double", lambda x: 2 * x, 21) == 42
    assert clock(None, lambda: "untimed") == "untimed"
    assert list(clock.timings_s) == ["double"] and clock.timings_s["double"] >= 0.0
