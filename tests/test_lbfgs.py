"""The host-driven L-BFGS of the default co-design (jaxbal._src.lbfgs): closed-form
minimisers (a quadratic, Rosenbrock), non-finite trial points, stopping rules and the
loss history; checked against the exact solutions, not against itself."""

import numpy as np
import pytest

from jaxbal._src.lbfgs import lbfgs


def _quadratic(n=20, seed=0):
    rng = np.random.default_rng(seed)
    m = rng.normal(size=(n, n))
    a = m @ m.T + n * np.eye(n)  # SPD, condition ~ 4
    b = rng.normal(size=n)
    return a, b, np.linalg.solve(a, b)


def test_quadratic_reaches_the_linear_solve():
    """½xᵀAx − bᵀx (20 variables, SPD): the minimiser is A⁻¹b (1e-10 relative), the
    gradient norm reaches gtol, and the history decreases (Armijo)."""
    a, b, exact = _quadratic()

    def fun(x):
        return 0.5 * x @ a @ x - b @ x, a @ x - b, None

    result = lbfgs(fun, np.zeros(20), max_steps=200, gtol=1e-12)
    assert result.converged and np.linalg.norm(result.grad) <= 1e-12
    np.testing.assert_allclose(result.x, exact, rtol=1e-10)
    done = result.history[: result.steps]
    # Armijo, or the approximate Wolfe condition: rises only at rounding level
    assert np.all(np.diff(done) <= 1e-12 * np.abs(done[1:]))
    assert np.all(np.isnan(result.history[result.steps :]))
    assert result.evaluations >= result.steps + 1


@pytest.mark.parametrize("n", [2, 10])
def test_rosenbrock(n):
    """Chained Rosenbrock from (−1.2, 1) (n = 2) and from 0 (n = 10; from (−1.2, 1, …)
    it has a second local minimum near x₁ = −1): the minimiser (1, …, 1) to 1e-8."""

    def fun(x):
        f = np.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2)
        g = np.zeros_like(x)
        g[:-1] = -400.0 * x[:-1] * (x[1:] - x[:-1] ** 2) - 2.0 * (1.0 - x[:-1])
        g[1:] += 200.0 * (x[1:] - x[:-1] ** 2)
        return f, g, x.copy()

    x0 = np.array([-1.2, 1.0]) if n == 2 else np.zeros(n)
    result = lbfgs(fun, x0, max_steps=500, gtol=1e-10)
    assert result.converged
    np.testing.assert_allclose(result.x, np.ones(n), atol=1e-8)
    np.testing.assert_array_equal(result.aux, result.x)  # aux of the final point


def test_non_finite_trials_are_rejected():
    """A loss that is +inf (and its gradient NaN) beyond x = 0.5, minimum at x = 2 of
    the finite branch out of reach: the run stays in the finite region and stops at
    the boundary side, every accepted value finite."""

    def fun(x):
        if x[0] > 0.5:
            return np.inf, np.full(1, np.nan), None
        return (x[0] - 2.0) ** 2, np.array([2.0 * (x[0] - 2.0)]), None

    result = lbfgs(fun, np.array([-3.0]), max_steps=100, gtol=1e-12)
    assert np.isfinite(result.value) and result.x[0] <= 0.5
    assert result.x[0] > 0.49  # pushed against the boundary
    assert not result.converged
    assert np.all(np.isfinite(result.history[: result.steps]))


def test_start_at_the_minimum_and_step_cap():
    """A zero gradient at the start stops at once (converged, no step); max_steps caps
    the accepted iterations."""
    result = lbfgs(lambda x: (float(x @ x), 2.0 * x, None), np.zeros(3), max_steps=5, gtol=0.0)
    assert result.converged and result.steps == 0 and result.evaluations == 1
    a, b, _ = _quadratic(50, seed=1)
    capped = lbfgs(
        lambda x: (0.5 * x @ a @ x - b @ x, a @ x - b, None), np.zeros(50), max_steps=3, gtol=0.0
    )
    assert capped.steps == 3 and not capped.converged
