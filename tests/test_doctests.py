"""The worked numbers in the docstrings are right (every module's doctests run)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import pkmtol

MODULES = sorted(m.name for m in pkgutil.iter_modules(pkmtol.__path__, "pkmtol."))


@pytest.mark.parametrize("name", MODULES)
def test_module_doctests(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
