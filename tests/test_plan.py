"""Capabilities are declared, and the declarations agree with the adapters' options."""

from __future__ import annotations

import pytest

from solvers import SOLVERS


@pytest.mark.parametrize("name", list(SOLVERS))
def test_declared_capabilities_agree_with_the_adapters_options(name):
    """The harness reads declarations only; here, once, they are checked against the options that
    carry them: a seed to train from, rtol and atol, threads, save and load."""
    cls = SOLVERS[name]
    if cls is None:
        pytest.skip(f"{name} is not installed")
    options = set(cls.OPTIONS)
    assert cls.trains == ("seed" in options)
    assert cls.has_tolerance == ({"rtol", "atol"} <= options)
    assert cls.takes_threads == ("threads" in options)
    assert cls.can_save == (callable(getattr(cls, "save", None)) and callable(getattr(cls, "load", None)))
    assert cls.QUERY_OPTIONS <= options
