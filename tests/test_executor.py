"""The executor: chunk order kept, per-chunk seeds, bad settings refused with a PkmtolError, and the
same numbers, bit for bit, in this process, on 2 local processes and on a 2-worker Dask cluster."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from pkmtol.design.exact import claimed_vs_true
from pkmtol.design.verification import verify_all
from pkmtol.error_model.parameters import parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import ExecutorError, PkmtolError, SingularPoseError
from pkmtol.executor import Executor, chunk_seeds, imap_chunks, map_chunks
from pkmtol.model.loader import load_mechanism

SEED = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


def draw(seed: np.random.SeedSequence) -> np.ndarray:
    """A chunk of work that uses its own seed (module level: picklable)."""
    return np.random.default_rng(seed).standard_normal(4)


def fail_on_two(x: int) -> int:
    if x == 2:
        raise SingularPoseError("the test matrix", 1e9, np.array([0.1, 0.2, 0.3]))
    return x


def test_serial_map_keeps_order_and_is_lazy_as_an_iterator():
    assert map_chunks(abs, [-3, 1, -2]) == [3, 1, 2]
    assert map_chunks(abs, []) == []
    it = imap_chunks(abs, [-1, -2])
    assert next(it) == 1 and list(it) == [2]


def test_chunk_seeds_do_not_depend_on_who_runs_them():
    seeds = chunk_seeds(7, 3)
    again = chunk_seeds(7, 5)[:3]  # more chunks: the first ones unchanged
    for a, b in zip(seeds, again, strict=True):
        np.testing.assert_array_equal(draw(a), draw(b))
    assert not np.array_equal(draw(seeds[0]), draw(seeds[1]))
    serial = map_chunks(draw, seeds)
    parallel = map_chunks(draw, seeds, Executor(workers=2))
    for a, b in zip(serial, parallel, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("workers", [0, -1, 1.5, True, "2"])
def test_bad_worker_counts_are_refused(workers):
    with pytest.raises(ExecutorError) as info:
        Executor(workers=workers)
    assert isinstance(info.value, PkmtolError)
    assert info.value.culprit == "workers"
    assert "give an integer ≥ 1" in str(info.value)


def test_bad_dask_settings_are_refused():
    with pytest.raises(ExecutorError) as info:
        Executor(dask="  ")
    assert info.value.culprit == "dask"
    with pytest.raises(ExecutorError):
        chunk_seeds(0, -1)
    assert Executor().describe() == "serial" and Executor(workers=3).describe() == "3 local processes"


def test_errors_come_back_from_workers_with_their_data():
    err = SingularPoseError("the W", 1e9, np.array([0.1, 0.2, 0.3]))
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is SingularPoseError and str(back) == str(err) and back.condition == 1e9
    with pytest.raises(SingularPoseError) as info:
        map_chunks(fail_on_two, [1, 2, 3], Executor(workers=2))
    np.testing.assert_array_equal(info.value.target_m, [0.1, 0.2, 0.3])


@pytest.fixture(scope="module")
def job():
    """The verification and claimed-vs-true inputs of the seed robot (small counts)."""
    mech = load_mechanism(SEED)
    pset = parameter_set(mech, "dh")
    grid = sweep(mech, pset, mech.task_space.grid())
    unc = np.array([i for i, c in enumerate(grid.classify()) if c == "uncompensatable"])
    points = mech.task_space.sample(np.random.default_rng(1), 60)
    rnd = sweep(mech, pset, points, guesses=np.tile(grid.poses[0].q_all, (60, 1)))
    sigma = np.full(unc.size, 2e-5)
    return mech, pset, grid, rnd, unc, sigma


def run_job(job, executor):
    mech, pset, grid, rnd, unc, sigma = job
    rng = np.random.default_rng(5)
    ver = verify_all(mech, pset, rnd, unc, sigma, 5e-5, 1500, 1100, rng, executor=executor)
    claims = claimed_vs_true(
        grid.J[0][:, unc],
        rnd.J[:, :, unc],
        np.outer(sigma, [1.0, 0.5]),
        (1.0, 2.0),
        5e-5,
        500,
        rng,
        executor=executor,
    )
    return ver, claims


def assert_same(a, b):
    (va, ca), (vb, cb) = a, b
    for dist in va:
        np.testing.assert_array_equal(va[dist].dlam_exact_m, vb[dist].dlam_exact_m)
        np.testing.assert_array_equal(va[dist].dlam_linear_m, vb[dist].dlam_linear_m)
        assert va[dist].exact == vb[dist].exact
    assert ca == cb


def test_verification_is_bit_identical_on_every_executor(job):
    serial = run_job(job, None)
    ver = serial[0]
    assert all(v.exact is not None and v.exact.samples == 1100 for v in ver.values())  # 3 chunks each
    assert max(v.max_relative_difference for v in ver.values()) < 0.01  # exact agrees with linear
    assert_same(serial, run_job(job, Executor(workers=2)))
    pytest.importorskip("dask.distributed")
    assert_same(serial, run_job(job, Executor(workers=2, dask="local")))


def test_an_unreachable_scheduler_is_named():
    pytest.importorskip("dask.distributed")
    import pkmtol.executor as ex

    old = ex.DASK_TIMEOUT_S
    ex.DASK_TIMEOUT_S = 1.0
    try:
        with pytest.raises(ExecutorError) as info:
            map_chunks(abs, [1], Executor(dask="tcp://127.0.0.1:9"))
    finally:
        ex.DASK_TIMEOUT_S = old
    assert info.value.culprit == "dask"
    assert "tcp://127.0.0.1:9" in str(info.value) and "dask scheduler" in str(info.value)
