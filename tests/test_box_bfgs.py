"""The compiled projected BFGS (jaxbal/_src/box_bfgs.py) against closed forms and SciPy's
L-BFGS-B, and the reduced co-design that runs it (jaxbal/_src/design_compiled.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize as scipy_minimize

from jaxbal._src.box_bfgs import _solve, box_bfgs


def _quadratic(x, context=None):
    """``½ xᵀ A x − bᵀ x`` with ``A = diag(1..n)``: minimiser ``b_i / i``."""
    a = jnp.arange(1.0, x.size + 1.0)
    b = jnp.full(x.size, 30.0)
    value = 0.5 * jnp.sum(a * x**2) - jnp.dot(b, x)
    return value, a * x - b, jnp.stack([value, 2.0 * value])


def _rosenbrock(x, context=None):
    def f(y):
        return jnp.sum(100.0 * (y[1:] - y[:-1] ** 2) ** 2 + (1.0 - y[:-1]) ** 2)

    value, grad = jax.value_and_grad(f)(x)
    return value, grad, value


def _run(fun, x0, lower, upper, aux, **kwargs):
    return jax.jit(
        lambda x0, lower, upper: box_bfgs(
            fun, x0, lower, upper, max_steps=300, gtol=1e-10, aux=aux, **kwargs
        )
    )(
        jnp.asarray(x0, dtype=float),
        jnp.asarray(lower, dtype=float),
        jnp.asarray(upper, dtype=float),
    )


def test_bounded_quadratic_reaches_the_clipped_minimiser():
    """A separable quadratic in a box: the minimiser is the unconstrained one clipped
    (closed form), with six variables held at their upper bound."""
    n = 20
    result = _run(_quadratic, np.ones(n), np.zeros(n), np.full(n, 5.0), jnp.zeros(2))
    expected = np.clip(30.0 / np.arange(1.0, n + 1.0), 0.0, 5.0)
    assert bool(result.converged)
    np.testing.assert_allclose(result.x, expected, rtol=1e-7)
    np.testing.assert_allclose(result.aux, [result.value, 2 * result.value])
    history = np.asarray(result.history)
    steps = int(result.steps)
    assert np.all(np.isfinite(history[:steps])) and np.all(np.isnan(history[steps:]))
    assert np.all(np.diff(history[:steps]) < 0)  # every accepted step lowers the loss


@pytest.mark.parametrize("lower, upper", [(-2.0, 0.5), (1.2, 3.0), (-np.inf, np.inf)])
def test_rosenbrock_in_a_box_matches_scipy(lower, upper):
    n = 10
    x0 = np.clip(np.full(n, -1.0), lower, upper)
    result = _run(_rosenbrock, x0, np.full(n, lower), np.full(n, upper), jnp.zeros(()))

    def fun(x):
        value, grad, _ = _rosenbrock(jnp.asarray(x))
        return float(value), np.asarray(grad)

    reference = scipy_minimize(
        fun, x0, jac=True, method="L-BFGS-B", bounds=[(lower, upper)] * n,
        options={"ftol": 1e-16, "gtol": 1e-12, "maxiter": 2000},
    )  # fmt: skip
    assert bool(result.converged)
    np.testing.assert_allclose(float(result.value), reference.fun, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(result.x, reference.x, rtol=1e-5, atol=1e-6)


def test_a_non_finite_start_stops_at_once():
    def fun(x, context=None):
        value = jnp.sum(jnp.log(x))  # log of a negative start: NaN
        return value, 1.0 / x, value

    result = _run(fun, -np.ones(3), np.full(3, -2.0), np.ones(3), jnp.zeros(()))
    assert not bool(result.converged)
    assert int(result.steps) == 0 and int(result.evaluations) == 1


def test_a_non_finite_trial_is_backtracked():
    """A pseudo-Huber loss (nearly linear far from its minimiser at 0.9) that is NaN
    beyond x = 1, inside the box: the quasi-Newton steps from far away overshoot into
    the NaN region, the search backtracks, and the run converges to 0.9."""

    def loss(x):
        return jnp.sum(jnp.sqrt(1.0 + (x - 0.9) ** 2) + jnp.where(x > 1.0, jnp.nan, 0.0))

    def fun(x, context=None):
        value, grad = jax.value_and_grad(loss)(x)
        return value, jnp.where(jnp.isfinite(grad), grad, jnp.nan), value

    result = _run(fun, np.full(2, -40.0), np.full(2, -50.0), np.full(2, 50.0), jnp.zeros(()))
    assert bool(result.converged)
    np.testing.assert_allclose(result.x, [0.9, 0.9], rtol=1e-8)
    assert int(result.evaluations) > int(result.steps) + 1  # some trial was rejected


def test_prelude_sets_the_context():
    """The prelude's evaluation (at another point) sets the context the run uses: here
    the loss's scale, so the optimum is unchanged and the final value is divided by it."""

    def fun(x, scale):
        value, grad, _ = _quadratic(x)
        return value / scale, grad / scale, value

    n = 5
    prelude = (jnp.full(n, 2.0), lambda aux: jnp.abs(aux))
    result = _run(
        fun, np.ones(n), np.zeros(n), np.full(n, 50.0), jnp.zeros(()),
        context=jnp.asarray(1.0), prelude=prelude,
    )  # fmt: skip
    scale = abs(float(_quadratic(jnp.full(n, 2.0))[0]))
    np.testing.assert_allclose(float(result.context), scale)
    np.testing.assert_allclose(result.x, 30.0 / np.arange(1.0, n + 1.0), rtol=1e-7)
    np.testing.assert_allclose(float(result.value) * scale, float(result.aux), rtol=1e-12)


def test_vmap_over_starts_equals_a_loop():
    n = 6
    starts = np.random.default_rng(1).uniform(-1.5, 0.4, size=(4, n))
    lower, upper = np.full(n, -2.0), np.full(n, 0.5)

    def run(x0):
        return box_bfgs(_rosenbrock, x0, lower, upper, max_steps=200, gtol=1e-10, aux=jnp.zeros(()))

    batched = jax.jit(jax.vmap(run))(jnp.asarray(starts))
    for k, x0 in enumerate(starts):
        single = jax.jit(run)(jnp.asarray(x0))
        np.testing.assert_allclose(batched.x[k], single.x, rtol=1e-12, atol=1e-14)
        assert int(batched.steps[k]) == int(single.steps)


def test_solve_equals_numpy():
    generator = np.random.default_rng(0)
    factor = generator.standard_normal((12, 12))
    matrix = factor @ factor.T + 0.1 * np.eye(12)
    rhs = generator.standard_normal(12)
    np.testing.assert_allclose(
        _solve(jnp.asarray(matrix), jnp.asarray(rhs)), np.linalg.solve(matrix, rhs), rtol=1e-9
    )
