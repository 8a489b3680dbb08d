"""The batch of a checked_jit check reduced in one pass (jaxbal/_src/first_failure.py):
the reduction against a Python loop, nested vmaps, the message of the first failing
sample, and no sort of the batch in the compiled program of a vmapped wrench."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.first_failure import first_failure
from jaxbal.profiles import Quintic


def _batch():
    x = jnp.arange(24.0).reshape(6, 2, 2)
    return x.at[3, 1, 0].set(jnp.nan).at[5, 0, 1].set(jnp.inf)


def test_one_sample_is_returned_unchanged():
    x = _batch()[3]
    invalid, offending = first_failure(~jnp.isfinite(x), (x, 2 * x))
    np.testing.assert_array_equal(invalid, ~np.isfinite(np.asarray(x)))
    np.testing.assert_array_equal(offending[1], 2 * x)


def test_vmap_gives_any_over_the_batch_and_the_first_failing_sample_as_a_loop():
    x = _batch()
    invalid, (a, b) = jax.vmap(lambda s: first_failure(~jnp.isfinite(s), (s, -s)), out_axes=None)(x)
    bad = ~np.isfinite(np.asarray(x))
    first = next(i for i in range(x.shape[0]) if bad[i].any())  # the loop
    assert first == 3
    np.testing.assert_array_equal(invalid, bad.any(axis=0))  # out_axes=None: unbatched
    np.testing.assert_array_equal(a, x[first])
    np.testing.assert_array_equal(b, -x[first])


def test_nothing_failing_gives_false_and_sample_zero_and_unbatched_offending_is_kept():
    x = jnp.arange(12.0).reshape(3, 4)
    const = jnp.array([7.0, 8.0])
    invalid, (a, c) = jax.vmap(lambda s: first_failure(s < 0, (s, const)), out_axes=None)(x)
    assert invalid.shape == (4,) and not invalid.any()
    np.testing.assert_array_equal(a, x[0])
    np.testing.assert_array_equal(c, const)


def test_nested_vmaps_reduce_every_batch_axis():
    x = _batch().reshape(2, 3, 2, 2)  # sample 3 is (1, 0); sample 5 is (1, 2)
    inner = jax.vmap(lambda s: first_failure(~jnp.isfinite(s), s), out_axes=None)
    invalid, off = jax.vmap(inner, out_axes=None)(x)
    assert invalid.shape == (2, 2) and off.shape == (2, 2)
    np.testing.assert_array_equal(off, x[1, 0])
    np.testing.assert_array_equal(invalid, (~np.isfinite(np.asarray(x))).any(axis=(0, 1)))


def _wrench_batch(robot):
    return jax.vmap(lambda q, qd, qdd: jaxbal.shaking_wrench(robot, q, qd, qdd))


def _states(name, n=64):
    """``n`` states along a straight end-effector line of the robot ``name``."""
    robot = getattr(jaxbal.robots, name)()
    start, end = {
        "planar_2r": ([0.4, 0.3], [0.6, 0.5]),
        "dual_v": ([0.0, -0.05, 0.0], [0.05, 0.05, 0.0]),
    }[name]
    line = jaxbal.StraightLine(jnp.array(start), jnp.array(end), Quintic(), 0.2)
    motion = jaxbal.design.motion_samples(
        robot, jaxbal.planning.EndEffectorLine(robot, line), jnp.linspace(0.0, 0.2, n)
    )
    return robot, tuple(motion)


@pytest.mark.parametrize("name", ["planar_2r", "dual_v"])
def test_checked_jit_of_a_vmapped_wrench_sorts_nothing_and_names_the_first_bad_state(name):
    """checkify reduced each batched check with an argsort of the whole batch: the
    checked wrench ran 5-9x slower than with callbacks (module doc of first_failure)."""
    robot, (q, qd, qdd) = _states(name)
    fn = _wrench_batch(robot)
    checked = jaxbal.checked_jit(lambda q, qd, qdd: fn(q, qd, qdd))
    expected = jax.jit(fn)(q, qd, qdd)
    for got, want in zip(checked(q, qd, qdd), expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-12)
    assert "stablehlo.sort" not in checked.programs["functional"].lower(q, qd, qdd).as_text()
    marked = 4242.0
    bad_qd = qd.at[9, 0].set(jnp.nan).at[30, 0].set(jnp.nan).at[9, -1].set(marked)
    with pytest.raises(ValueError, match=r"non-finite state \(q, qd, qdd\): \[") as info:
        checked(q, bad_qd, qdd)
    assert "4.242" in str(info.value) and "nan" in str(info.value)  # sample 9, the first


def test_checked_jit_of_a_gradient_over_a_batch_still_checks_the_state():
    robot, (q, qd, qdd) = _states("planar_2r", 8)

    def loss(masses, qd):
        force, _ = _wrench_batch(eqx.tree_at(lambda r: r.masses, robot, masses))(q, qd, qdd)
        return jnp.sum(force**2)

    grad = jaxbal.checked_jit(jax.grad(loss))
    g = grad(robot.masses, qd)
    assert np.all(np.isfinite(np.asarray(g)))
    np.testing.assert_allclose(g, jax.jit(jax.grad(loss))(robot.masses, qd), rtol=1e-13)
    with pytest.raises(ValueError, match="non-finite state"):
        grad(robot.masses, qd.at[5, 1].set(jnp.nan))
