"""Several value checks raised as one runtime error (jaxbal/_src/validation.py, Guards).

References: the eager ``ValueError`` of each check (the same message first), and the
lowered program of a single ``equinox.error_if`` (the wrench's five checks compile to
as many host callbacks as one).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.validation import Guards


def guarded(x):
    guards = Guards()
    guards.check(x < 0, "x must be >= 0", x)
    guards.check(x > 10, "x must be <= 10", x)
    guards.check(~jnp.isfinite(x), "x must be finite", x)
    return guards.apply(x * 2.0)


def test_eager_checks_raise_at_once_in_order():
    with pytest.raises(ValueError, match="x must be >= 0"):
        guarded(jnp.array([-1.0, 20.0]))
    with pytest.raises(ValueError, match="x must be <= 10"):
        guarded(jnp.array([1.0, 20.0]))
    assert np.array_equal(guarded(jnp.array([1.0, 2.0])), [2.0, 4.0])


def test_jit_raises_the_first_failed_check():
    fn = jax.jit(guarded)
    assert np.array_equal(fn(jnp.array([1.0, 2.0])), [2.0, 4.0])
    with pytest.raises(Exception, match="x must be >= 0"):
        fn(jnp.array([-1.0, 20.0]))
    with pytest.raises(Exception, match="x must be <= 10"):
        fn(jnp.array([1.0, 20.0]))
    with pytest.raises(Exception, match="x must be finite"):
        fn(jnp.array([1.0, jnp.nan]))


def test_vmap_raises_the_first_check_failed_anywhere_in_the_batch():
    fn = jax.jit(jax.vmap(guarded))
    # sample 0 fails the third check, sample 1 the first: the first one is reported
    with pytest.raises(Exception, match="x must be >= 0"):
        fn(jnp.array([jnp.nan, -1.0, 3.0]))
    assert np.array_equal(fn(jnp.array([0.0, 1.0])), [0.0, 2.0])


def test_the_wrench_checks_compile_to_one_callback():
    robot = jaxbal.robots.planar_2r()
    q = jnp.array([0.1, 0.2])

    def one(x):
        return eqx.error_if(x, jnp.any(x < 0), "one check")

    single = jax.jit(one).lower(q).as_text().count("callback")
    text = jax.jit(lambda a: jaxbal.shaking_wrench(robot, a, a, a)).lower(q).as_text()
    assert single > 0
    assert text.count("callback") == single


def test_the_wrench_reports_a_bad_mass_before_its_non_finite_result():
    robot = eqx.tree_at(lambda r: r.masses, jaxbal.robots.planar_2r(), jnp.array([jnp.nan, 1.0]))
    q = jnp.array([0.1, 0.2])
    fn = jax.jit(lambda r, a: jaxbal.shaking_wrench(r, a, a, a))
    with pytest.raises(Exception, match="body masses must be finite"):
        fn(robot, q)
    with pytest.raises(Exception, match="non-finite state"):
        fn(jaxbal.robots.planar_2r(), jnp.array([jnp.nan, 0.2]))
