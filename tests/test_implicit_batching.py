"""Batched Newton solves (implicit._newton_stack): ``vmap`` at any depth equals a
Python loop, a problem that does not converge leaves the others' roots alone and is
flagged, and ``checkify`` accepts the batched program (a plain ``vmap`` of a
``while_loop`` has a batched predicate, which checkify refuses)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental import checkify

from jaxbal import newton_solve


def _residual(x, p):
    # roots: x_i = sqrt(c_i d), one problem per (c, d); no real root when c d < 0
    return x**2 - p["c"] * p["d"]


X0 = jnp.array([1.0, 1.0])
CS = jnp.array([[1.0, 2.0], [3.0, 0.5], [4.0, 9.0]])
DS = jnp.array([0.5, 2.0])


def _solve(c, d, x0=X0):
    sol = newton_solve(_residual, x0, {"c": c, "d": d}, throw=False)
    return sol.value, sol.converged


def test_nested_vmap_equals_a_python_loop_and_the_closed_form():
    values, converged = jax.jit(jax.vmap(lambda d: jax.vmap(lambda c: _solve(c, d))(CS)))(DS)
    assert values.shape == (2, 3, 2) and bool(jnp.all(converged))
    loop = np.stack([np.stack([np.asarray(_solve(c, d)[0]) for c in CS]) for d in DS])
    np.testing.assert_allclose(np.asarray(values), loop, rtol=1e-13)
    np.testing.assert_allclose(np.asarray(values), np.sqrt(CS[None] * DS[:, None, None]))
    # batched initial guesses with shared parameters (the other merge of the stack)
    guesses = jnp.stack([X0, 3.0 * X0])
    both = jax.vmap(lambda d: jax.vmap(lambda x: _solve(CS[0], d, x)[0])(guesses))(DS)
    expected = np.broadcast_to(np.sqrt(CS[0] * DS[:, None, None]), (2, 2, 2))
    np.testing.assert_allclose(np.asarray(both), expected, rtol=1e-13)


def test_an_unsolvable_problem_is_flagged_and_leaves_the_others_alone():
    cs = CS.at[1, 0].set(-3.0)  # x^2 = -1.5: no real root
    values, converged = jax.jit(jax.vmap(lambda c: _solve(c, 0.5)))(cs)
    np.testing.assert_array_equal(np.asarray(converged), [True, False, True])
    for i in (0, 2):
        np.testing.assert_allclose(np.asarray(values[i]), np.sqrt(cs[i] * 0.5), rtol=1e-13)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_checkify_accepts_the_batched_solve_and_gradients_are_implicit():
    def total(d):
        return jnp.sum(jax.vmap(lambda c: _solve(c, d)[0])(CS))

    error, value = checkify.checkify(jax.jit(total), errors=checkify.user_checks)(DS[1])
    assert error.get() is None
    np.testing.assert_allclose(float(value), float(np.sum(np.sqrt(CS * DS[1]))), rtol=1e-13)
    gradient = jax.grad(total)(DS[1])  # d/dd sum sqrt(c d) = sum sqrt(c) / (2 sqrt(d))
    expected = np.sum(np.sqrt(CS) / (2.0 * np.sqrt(DS[1])))
    assert np.isfinite(float(gradient))
    np.testing.assert_allclose(float(gradient), expected, rtol=1e-12)
    per_d = jax.vmap(jax.grad(total))(DS)  # vmap of grad: the tangent solve batched too
    np.testing.assert_allclose(
        np.asarray(per_d), np.sum(np.sqrt(CS)) / (2.0 * np.sqrt(np.asarray(DS))), rtol=1e-12
    )


def _two_link_tip(q, target):
    """Tip of a planar two-link arm (0.2 m, 0.2 m) minus ``target``."""
    x = 0.2 * jnp.cos(q[0]) + 0.2 * jnp.cos(q[0] + q[1])
    y = 0.2 * jnp.sin(q[0]) + 0.2 * jnp.sin(q[0] + q[1])
    return jnp.stack([x, y]) - target


def test_a_singular_start_takes_a_damped_step_and_converges():
    """From the arm drawn straight (q = 0, singular Jacobian: Newton's step is not
    finite), one Levenberg-Marquardt step leaves the singularity and Newton converges to
    an exact inverse kinematics; batched, a problem with a regular start is solved as
    before (the same bits as alone) next to one with a singular start."""
    target = jnp.array([0.3, 0.2])
    straight = jnp.zeros(2)
    assert not bool(jnp.all(jnp.isfinite(jnp.linalg.solve(
        jax.jacfwd(_two_link_tip)(straight, target), _two_link_tip(straight, target)
    ))))  # fmt: skip
    solution = newton_solve(_two_link_tip, straight, target)
    assert bool(solution.converged)
    np.testing.assert_allclose(np.asarray(_two_link_tip(solution.value, target)), 0.0, atol=1e-12)
    bent = jnp.array([0.2, 1.2])
    alone = newton_solve(_two_link_tip, bent, target).value
    starts = jnp.stack([bent, straight])
    both = jax.jit(jax.vmap(lambda x: newton_solve(_two_link_tip, x, target, throw=False)))(starts)
    assert bool(jnp.all(both.converged))
    np.testing.assert_array_equal(np.asarray(both.value[0]), np.asarray(alone))
    # a Jacobian that vanishes (x² = 2 from x = 0) gives no direction: still refused
    solve = newton_solve(lambda x, p: x**2 - p, jnp.zeros(1), jnp.array([2.0]), throw=False)
    assert not bool(solve.converged)


def _arctan(x, p):
    return jnp.arctan(x - p)


def _plain_newton(x, p, steps):
    # the undamped iteration x <- x - (1 + (x - p)²) atan(x - p), in numpy
    for _ in range(steps):
        x = x - (1.0 + (x - p) ** 2) * np.arctan(x - p)
    return x


def test_a_far_start_is_globalised_by_step_halving():
    """atan(x - p) = 0 from 1.5 away: plain Newton overshoots further at every step and
    diverges (|x| > 1e6 after 6 steps, checked here in numpy); with step halving the
    solve converges to the root p, alone and batched next to a near start."""
    p = jnp.asarray(0.25)
    assert abs(_plain_newton(1.75, 0.25, 6)) > 1e6
    far = newton_solve(_arctan, jnp.array([1.75]), p)
    assert bool(far.converged)
    np.testing.assert_allclose(np.asarray(far.value), [0.25], atol=1e-12)
    starts = jnp.array([[1.75], [0.3]])
    both = jax.vmap(lambda x: newton_solve(_arctan, x, p, throw=False))(starts)
    assert bool(jnp.all(both.converged))
    np.testing.assert_allclose(np.asarray(both.value), 0.25, atol=1e-12)
    # the derivative is still the implicit one: dx/dp = 1
    np.testing.assert_allclose(
        float(jax.grad(lambda p: newton_solve(_arctan, jnp.array([1.75]), p).value[0])(p)), 1.0
    )
