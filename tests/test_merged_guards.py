"""The checks of one physics output traced as one runtime check
(jaxbal/_src/merged_guards.py): one callback per output, the same messages, the first
failing check in program order reported (as the chained checks did)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental import checkify

import jaxbal
from jaxbal._src.merged_guards import merged_guards
from jaxbal._src.validation import _FUNCTIONAL, guard
from jaxbal.design import base_inertia


def _callbacks(fn, *args) -> int:
    return jax.jit(fn).lower(*args).as_text().count("callback")


def test_each_physics_output_has_one_runtime_check():
    robot = jaxbal.robots.planar_2r()
    q = jnp.array([0.3, -0.5])
    one = _callbacks(lambda x: eqx.error_if(x, x < 0, "negative"), jnp.ones(()))
    assert one >= 1
    outputs = {
        "wrench": lambda r, a: jaxbal.shaking_wrench(r, a, a, a),
        "torques": lambda r, a: jaxbal.inverse_dynamics(r, a, a, a),
        "centre of mass": jaxbal.center_of_mass,
        "base inertia": base_inertia,
    }
    for name, fn in outputs.items():
        assert _callbacks(fn, robot, q) == one, name


def _three_checks(x):
    def checks(x):
        y = guard(x, x[0] < 0, "first", x)
        y = guard(y, x[1] < 0, "second", x)
        return guard(y, x[2] < 0, "third", x)

    return merged_guards(checks, x)


@pytest.mark.parametrize(
    "values,message",
    [([1.0, -1.0, -1.0], "second"), ([-1.0, 1.0, -1.0], "first"), ([1.0, 1.0, -1.0], "third")],
)
def test_the_first_failing_check_is_reported(values, message):
    compiled = jax.jit(_three_checks)
    with pytest.raises(Exception, match=message):
        jax.block_until_ready(compiled(jnp.asarray(values)))
    with pytest.raises(ValueError, match=message):  # eagerly: raised at the check
        _three_checks(jnp.asarray(values))
    np.testing.assert_array_equal(compiled(jnp.ones(3)), jnp.ones(3))


def test_over_a_batch_the_first_check_failing_anywhere_wins():
    """Sample 0 fails the third check only, sample 1 the second: "second" (the order of
    the checks, not of the samples), as the chained checks raised."""
    batch = jnp.asarray([[1.0, 1.0, -1.0], [1.0, -1.0, 1.0]])
    with pytest.raises(Exception, match="second"):
        jax.block_until_ready(jax.jit(jax.vmap(_three_checks))(batch))
    np.testing.assert_array_equal(jax.jit(jax.vmap(_three_checks))(jnp.ones((2, 3))), 1.0)


def test_a_bad_parameter_is_named_before_the_non_finite_wrench_it_causes():
    robot = jaxbal.robots.planar_2r()
    state = jnp.array([[0.1, 0.2], [0.3, 0.4]])
    wrench = jax.jit(jax.vmap(lambda r, a: jaxbal.shaking_wrench(r, a, a, a), (None, 0)))
    bad = eqx.tree_at(lambda r: r.lengths, robot, jnp.array([jnp.nan, 0.3]))
    with pytest.raises(Exception, match="robot parameters must be finite"):
        jax.block_until_ready(wrench(bad, state))
    negative = eqx.tree_at(lambda r: r.payload, robot, jnp.asarray(-1.0))
    with pytest.raises(Exception, match="non-finite state"):  # the state's check first
        jax.block_until_ready(wrench(negative, state.at[1, 0].set(jnp.nan)))
    with pytest.raises(Exception, match="body masses"):
        jax.block_until_ready(wrench(negative, state))
    assert np.all(np.isfinite(wrench(robot, state)[0]))


def _multiplies(robot, state, checks: bool, functional: bool = False) -> int:
    wrench = jax.vmap(jaxbal.shaking_wrench, in_axes=(None, 0, 0, 0))
    with jaxbal.runtime_checks(checks), _FUNCTIONAL(functional):
        if functional:  # the program of jaxbal.checked_jit
            wrench = checkify.checkify(wrench, errors=checkify.user_checks)
        text = jax.jit(wrench).lower(robot, state, state, state).compile().as_text()
    return text.count(" multiply(")


def test_the_checked_wrench_is_computed_once():
    """A check reads the wrench (is it finite?) and the program returns it: without the
    value written to memory first, XLA:CPU compiled the Orthoglide's whole wrench into
    both (2.1x the multiplies of the unchecked program, 3.4x slower), with the checks
    as callbacks (merged) and as checked_jit's functional checks alike."""
    robot = jaxbal.robots.orthoglide()
    state = jnp.tile(jnp.array([0.01, 0.02, 0.03, 0.1, 0.2, 0.3]), (8, 1))
    unchecked = _multiplies(robot, state, False)
    assert unchecked > 50
    for functional in (False, True):
        checked = _multiplies(robot, state, True, functional)
        assert checked <= 1.3 * unchecked, (functional, checked, unchecked)
