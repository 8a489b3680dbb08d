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
from jaxbal.planning import EndEffectorLine, wrench_along
from jaxbal.profiles import Quintic


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


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_wrench_along_a_newton_solved_plan_is_a_functional_program(orthoglide_plan):
    """The Newton solves along samples are one loop with a scalar predicate
    (implicit._newton_stack), which checkify accepts: the persistently cacheable
    functional program is used, and a failed check names the offending values."""
    robot, plan, times = orthoglide_plan
    force, moment = wrench_along(robot, plan, times)
    reference = jax.jit(lambda r: wrench_along(r, plan, times))(robot)  # traced: plain
    np.testing.assert_allclose(np.asarray(force), np.asarray(reference[0]), atol=1e-9)
    np.testing.assert_allclose(np.asarray(moment), np.asarray(reference[1]), atol=1e-9)
    assert np.all(np.isfinite(np.asarray(force))) and np.max(np.abs(np.asarray(force))) > 1.0
    program = validation._LIBRARY[
        next(f for f in validation._LIBRARY if f.__name__ == "_wrench_along")
    ]
    assert not program.refused
    assert "functional" in program.programs and "callback" not in program.programs
    # a plan on a line of its own (com_line's plans recompute the line from the robot)
    line = eqx.tree_at(lambda p: p.end, plan.line, jnp.array([2.0, 2.0, 2.0]))
    bad = jaxbal.planning.ComLine(robot, line, poses=plan.poses)
    with pytest.raises(ValueError, match=r"COM target not reachable.*\d"):
        wrench_along(robot, bad, times)


def test_checked_jit_falls_back_where_checkify_refuses_a_batched_while_loop():
    """A user function with a ``vmap`` of a plain ``while_loop`` (batched predicate):
    checkify refuses it, checked_jit remembers the structure and runs the program with
    the checks as callbacks; a failed check there is still a ValueError naming it."""

    def count_up(xs):
        xs = validation.guard(xs, xs < 0, "start must be >= 0", xs)
        return jax.vmap(lambda x: jax.lax.while_loop(lambda v: v < 10.0, lambda v: v + 3.0, x))(xs)

    program = validation.checked_jit(count_up)
    out = program(jnp.array([0.0, 5.0, 9.5]))
    np.testing.assert_array_equal(np.asarray(out), [12.0, 11.0, 12.5])
    assert len(program.refused) == 1
    with pytest.raises(ValueError, match="start must be >= 0"):
        program(jnp.array([0.0, -1.0, 9.5]))
    assert len(program.refused) == 1  # remembered, not retried


def test_a_checked_program_called_with_concrete_arguments_inside_a_jit():
    """Found in session 20: ``jax.jit(lambda r: wrench_along(r, plan, times))`` with a
    concrete plan sampled the plan through checked_jit with concrete arguments, but
    inside the enclosing trace (jit stages every operation): the functional program's
    error was a tracer and reading it failed. Inside any trace the enclosing program
    now carries the checks."""
    robot = jaxbal.robots.planar_2r()
    plan = EndEffectorLine(
        robot, jaxbal.StraightLine(jnp.array([0.4, 0.3]), jnp.array([0.1, 0.5]), Quintic(), 0.2)
    )
    times = jnp.linspace(0.0, 0.2, 7)
    eager = wrench_along(robot, plan, times)
    traced = jax.jit(lambda r: wrench_along(r, plan, times))(robot)
    for a, b in zip(eager, traced, strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-12)
    bad = EndEffectorLine(
        robot, jaxbal.StraightLine(jnp.array([0.4, 0.3]), jnp.array([2.2, 0.5]), Quintic(), 0.2)
    )
    with pytest.raises(Exception, match="outside the workspace"):
        jax.block_until_ready(jax.jit(lambda r: wrench_along(r, bad, times))(robot))
