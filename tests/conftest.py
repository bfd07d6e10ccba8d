"""Test-run settings shared by every test module: the xdist groups of the slow exact-kinematics tests.

`.ci/run` runs the suite on two workers (``pytest -n 2 --dist loadgroup``). Tests that build
machines and solve them on exact kinematics (the contract tests of ``tests/test_contract.py``)
are heavy and share cached studies, so they run together in one xdist group, ``"contract"``,
on one worker, while the other worker takes the rest. A test elsewhere joins the group with
``@pytest.mark.xdist_group("contract")``; every test of the modules in :data:`CONTRACT_MODULES`
is put in it here. Without xdist (a plain ``pytest``) the marker does nothing.
"""

from __future__ import annotations

import pytest

#: Test modules whose every test runs in the "contract" xdist group.
CONTRACT_MODULES = ("test_contract.py",)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.name in CONTRACT_MODULES and not item.get_closest_marker("xdist_group"):
            item.add_marker(pytest.mark.xdist_group("contract"))


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "xdist_group(name): run with the other tests of the group on one xdist worker"
    )
