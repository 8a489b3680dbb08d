"""Test configuration: float64 on (jaxbal does it on import), strict dtype promotion off.

The persistent compilation cache is off in the tests (``JAXBAL_CACHE_DIR=off``, set
before jaxbal is imported): the tests that count compilations must see every one, not
a disk hit left by an earlier run. tests/test_config.py checks the cache in a
subprocess with its default settings.
"""

import os

os.environ["JAXBAL_CACHE_DIR"] = "off"

import jax  # noqa: E402
import pytest  # noqa: E402

import jaxbal  # noqa: E402, F401  (enables float64)

jax.config.update("jax_enable_x64", True)


def slow_for(values, *slow):
    """``values`` for ``pytest.mark.parametrize``, those in ``slow`` marked for
    ``make test-all`` (long compiles whose check another case already makes in
    ``make test``)."""
    return [pytest.param(v, marks=pytest.mark.slow) if v in slow else v for v in values]
