"""Cross-check with FIGAROH (issue 12, item 10): one limb of the seed robot as a serial robot.

pkmtol (urdf parameter set, ``raw_columns_local``, ``identifiability``, Gauss–Newton on
``perturbed_limb_models``) and FIGAROH (``BaseCalibration`` from a YAML config and a CSV) each
find the base parameters and identify them from the same simulated measurements of P; the truth
is plain Pinocchio with errors on every joint placement and on P. scripts/crosscheck_figaroh.py
does the work; docs/figaroh-crosscheck.md gives the method and the tolerances. Skipped when
figaroh is not installed (``pip install -e '.[figaroh]'``).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

pytest.importorskip("figaroh")

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "crosscheck_figaroh.py"
POSES, HOLDOUT, NOISE_M = 60, 200, 1e-5  # the script's defaults: the numbers of the doc page


def _load():
    spec = importlib.util.spec_from_file_location("crosscheck_figaroh", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


cc = _load()


@pytest.fixture(scope="module")
def noise_free():
    return cc.compare(POSES, HOLDOUT, 0.0, seed=1)


@pytest.fixture(scope="module")
def noisy():
    return cc.compare(POSES, HOLDOUT, NOISE_M, seed=1)


@pytest.fixture(scope="module")
def small_errors():
    return cc.compare(POSES, HOLDOUT, 0.0, seed=1, error_scale=0.1)


def test_parameter_counts_and_rank_agree(noise_free):
    c = noise_free
    assert len(c.pk.names) == 48  # 7 origins × 6 + 6 zero offsets
    assert c.fg.candidates == 39  # 6 joints × 6 full_params + 3 tip coordinates
    assert c.pk.ident.rank == len(c.fg.names) == 25
    assert len(c.fg.structural) - len(c.fg.absorbed) + len(cc.TIP) == 25
    r = c.pk.ident.rank
    assert c.pk.ident.pivots[r - 1] > 1e-2 and c.pk.ident.pivots[r] < 1e-12  # a clean gap


def test_base_column_spaces_coincide(noise_free):
    assert noise_free.joint_rank == 25
    assert noise_free.max_angle_rad < 1e-6  # FIGAROH's Jacobian is central differences


def test_parameter_mapping_is_exact(noise_free, noisy):
    # FIGAROH's estimate written as pkmtol's urdf parameters predicts what FIGAROH predicts
    assert noise_free.mapped_fg_m < 1e-13
    assert noisy.mapped_fg_m < 1e-13


def test_noise_free_both_recover_the_truth(noise_free):
    c = noise_free
    assert c.pk.rms_m < 1e-13 and c.fg.rms_m < 1e-13
    assert c.hold_pk_truth_m < 1e-12 and c.hold_fg_truth_m < 1e-12
    assert c.hold_pk_fg_m < 1e-12


def test_noisy_estimates_predict_the_same_positions(noisy):
    c = noisy
    assert 5e-6 < c.fg.rms_m < 1.5e-5
    assert abs(c.pk.rms_m - c.fg.rms_m) < 1e-6 * c.fg.rms_m
    # the same least-squares minimum
    assert c.hold_exact_fg_m < 1e-9  # 1e-4 of the noise: FIGAROH's LM stopping rule (scipy defaults)
    # pkmtol's frozen-Jacobian fixed point: within 1 % of the noise σ
    assert c.hold_pk_fg_m < 1e-2 * NOISE_M


def test_base_combinations_agree_to_first_order(noise_free, small_errors):
    big, small = noise_free.beta_diff_scale, small_errors.beta_diff_scale
    assert big < 1e-2
    # second order: errors ÷ 10 divide the difference by 100
    assert 50 < big / small < 200
