"""Test-run settings shared by every test module: the xdist group of the slow exact-kinematics tests.

`.ci/run` runs the suite on two workers (``pytest -n 2 --dist loadgroup``). Tests that build
machines and solve them on exact kinematics (the contract tests of ``tests/test_contract.py``)
are heavy and share cached studies, so they run together in one xdist group, ``"contract"``,
on one worker, while the other worker takes the rest. A test elsewhere joins the group with
``@pytest.mark.xdist_group("contract")``; every test of the modules in :data:`CONTRACT_MODULES`
is put in it here. Without xdist (a plain ``pytest``) the marker does nothing.

pytest-xdist 3.8 names a group by appending ``@<group>`` to ``item._nodeid``, which pytest ≥ 9
no longer reads (the id lives in ``item._id``): every group was then spread over the workers.
:func:`pytest_collection_finish` below appends the suffix where pytest reads it, before the
worker sends the ids to the scheduler.
"""

from __future__ import annotations

import pytest

import pkmtol  # noqa: F401  (first, so that its one-BLAS-thread default is set before numpy loads)

#: Test modules whose every test runs in the "contract" xdist group.
CONTRACT_MODULES = ("test_contract.py",)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.name in CONTRACT_MODULES and not item.get_closest_marker("xdist_group"):
            item.add_marker(pytest.mark.xdist_group("contract"))


@pytest.hookimpl(tryfirst=True)  # before the xdist worker sends the test ids to the scheduler
def pytest_collection_finish(session: pytest.Session) -> None:
    if not getattr(session.config.option, "loadgroup", False):  # xdist workers, --dist loadgroup
        return
    for item in session.items:
        groups = sorted(
            {
                str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                for m in item.iter_markers("xdist_group")
            }
        )
        if groups and "@" not in item.nodeid and hasattr(item, "_id"):
            from _pytest.nodes import coerce_node_id  # pytest ≥ 9

            item._id = coerce_node_id(f"{item.nodeid}@{'_'.join(groups)}")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "xdist_group(name): run with the other tests of the group on one xdist worker"
    )
