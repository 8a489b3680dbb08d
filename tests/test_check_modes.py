"""The runtime-check mode (on/off, functional) is part of JAX's trace keys, and
``checked_jit`` survives what ``checkify`` refuses.

Two defects found in session 19: (1) a nested compiled function (the Newton solve's
``jax.jit``, an ``eqx.filter_jit`` called under another trace) first traced with the
checks off (inside an optimiser) was reused, unchecked, by a later checked program: an
invalid value went through silently; (2) ``checkify`` refuses a ``vmap`` of a
``while_loop`` (Newton inverse kinematics along a batch of samples), so ``wrench_along``
of an Orthoglide COM plan could not be a ``checked_jit`` program.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src import validation
from jaxbal._src.robots.orthoglide import motion_cases
from jaxbal.planning import wrench_along


def test_a_nested_program_traced_with_checks_off_is_not_reused_with_checks_on():
    @jax.jit
    def inner(x):
        return 2.0 * validation.guard(x, x < 0, "x must be >= 0", x)

    with jaxbal.runtime_checks(False):  # e.g. inside an optimiser
        assert float(jax.jit(lambda x: inner(x) + 1.0)(jnp.asarray(-1.0))) == -1.0
    with pytest.raises(Exception, match="x must be >= 0"):
        jax.block_until_ready(jax.jit(lambda x: inner(x) + 2.0)(jnp.asarray(-1.0)))
    # and a program traced functionally (checkify) is not reused by a plain jit
    checked = validation.checked_jit(lambda x: inner(x) + 3.0)
    assert float(checked(jnp.asarray(1.0))) == 5.0
    with pytest.raises(Exception, match="x must be >= 0"):
        jax.block_until_ready(jax.jit(lambda x: inner(x) + 4.0)(jnp.asarray(-1.0)))


@pytest.fixture(scope="module")
def orthoglide_plan():
    robot = jaxbal.robots.orthoglide()
    plan = motion_cases(robot, jnp.zeros(3), jnp.array([0.05, 0.05, 0.0]), 0.2)["case3"]
    return robot, plan, jnp.linspace(0.0, 0.2, 9)


def test_wrench_along_a_newton_solved_plan_falls_back_from_checkify(orthoglide_plan):
    robot, plan, times = orthoglide_plan
    force, moment = wrench_along(robot, plan, times)
    reference = jax.jit(lambda r: wrench_along(r, plan, times))(robot)  # traced: plain
    np.testing.assert_allclose(np.asarray(force), np.asarray(reference[0]), atol=1e-9)
    np.testing.assert_allclose(np.asarray(moment), np.asarray(reference[1]), atol=1e-9)
    assert np.all(np.isfinite(np.asarray(force))) and np.max(np.abs(np.asarray(force))) > 1.0
    # the refusal is remembered for this structure (the functional trace is not retried)
    program = validation._LIBRARY[
        next(f for f in validation._LIBRARY if f.__name__ == "_wrench_along")
    ]
    assert len(program.refused) == 1
    # a check that fails in the fallback program is still a ValueError naming it
    bad = eqx.tree_at(lambda p: p.line.end, plan, jnp.array([2.0, 2.0, 2.0]))
    with pytest.raises(ValueError, match="COM target not reachable"):
        wrench_along(robot, bad, times)
