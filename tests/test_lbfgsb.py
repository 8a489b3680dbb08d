"""The default co-design's optimiser (jaxbal._src.lbfgsb, SciPy's L-BFGS-B driven from
the host): closed-form minimisers of bound-constrained quadratics and of Rosenbrock, a
start on a bound, non-finite trial points, stopping rules and the loss history;
checked against the exact solutions, not against itself."""

import numpy as np
import pytest

from jaxbal._src.lbfgsb import lbfgsb, projected_gradient


def _diagonal_quadratic(n=12, seed=0):
    """``½ Σ a_i x_i² − b_i x_i`` with box bounds: the minimiser is ``clip(b/a, lo, hi)``
    componentwise (separable), some components at a bound, some inside."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.5, 50.0, n)  # condition 100
    b = rng.normal(size=n) * a
    lower, upper = np.full(n, -0.5), np.full(n, 0.8)
    upper[::3] = np.inf  # one-sided bounds too
    return a, b, lower, upper, np.clip(b / a, lower, upper)


def test_bounded_quadratic_reaches_the_clipped_solution():
    """The box minimiser ``clip(b/a, lo, hi)`` to 1e-8 (the run stops when the loss no
    longer falls by more than FTOL = 1e-15 relative, i.e. x to ~√FTOL), bounds exact,
    a decreasing history (NaN after the last step), and the evaluation count at least
    the steps + 1."""
    a, b, lower, upper, exact = _diagonal_quadratic()
    assert np.any(exact == lower) and np.any(exact == upper) and np.any(np.abs(exact) < 0.5)

    def fun(x):
        return 0.5 * np.sum(a * x**2) - b @ x, a * x - b, None

    result = lbfgsb(fun, np.zeros(a.size), lower, upper, max_steps=200, gtol=1e-12)
    assert result.converged
    np.testing.assert_allclose(result.x, exact, rtol=0, atol=1e-8)
    at_bound = (exact == lower) | (exact == upper)
    np.testing.assert_array_equal(result.x[at_bound], exact[at_bound])
    assert np.max(np.abs(projected_gradient(result.x, result.grad, lower, upper))) <= 1e-6
    done = result.history[: result.steps]
    assert np.all(np.isfinite(done)) and np.all(np.diff(done) <= 1e-12 * np.abs(done[1:]))
    assert np.all(np.isnan(result.history[result.steps :]))
    assert result.evaluations >= result.steps + 1


def test_start_on_a_bound_leaves_it():
    """A start exactly on the lower bound, where the minimiser is inside: the bound
    does not hold the variable (no stationary point there, unlike ``x = lo + r²``)."""
    result = lbfgsb(
        lambda x: (float((x[0] - 2.0) ** 2), np.array([2.0 * (x[0] - 2.0)]), None),
        np.zeros(1),
        np.zeros(1),
        np.full(1, np.inf),
        max_steps=50,
        gtol=1e-12,
    )
    assert result.converged
    np.testing.assert_allclose(result.x, [2.0], atol=1e-10)


@pytest.mark.parametrize("n", [2, 10])
def test_rosenbrock(n):
    """Chained Rosenbrock, unbounded (infinite bounds): the minimiser (1, …, 1) to 1e-7;
    for n = 2 with a lower bound of 1.2 on x₁: the minimiser (1.2, 1.44) (x₂ = x₁²),
    the bound active with the gradient pointing out of the box."""

    def fun(x):
        f = np.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2)
        g = np.zeros_like(x)
        g[:-1] = -400.0 * x[:-1] * (x[1:] - x[:-1] ** 2) - 2.0 * (1.0 - x[:-1])
        g[1:] += 200.0 * (x[1:] - x[:-1] ** 2)
        return f, g, x.copy()

    x0 = np.array([-1.2, 1.0]) if n == 2 else np.zeros(n)
    free = np.full(n, np.inf)
    result = lbfgsb(fun, x0, -free, free, max_steps=1000, gtol=1e-10)
    assert result.converged
    np.testing.assert_allclose(result.x, np.ones(n), atol=1e-7)
    np.testing.assert_array_equal(result.aux, result.x)  # aux of the final point
    if n == 2:
        lower = np.array([1.2, -np.inf])
        bounded = lbfgsb(fun, np.array([1.5, 0.0]), lower, free, max_steps=1000, gtol=1e-10)
        assert bounded.converged and bounded.x[0] == 1.2
        np.testing.assert_allclose(bounded.x[1], 1.44, atol=1e-7)
        assert bounded.grad[0] > 0.0  # active: the loss would fall below the bound


def test_non_finite_trials_are_rejected():
    """A loss that is +inf (gradient NaN) beyond x = 0.5, the minimum at x = 2 of the
    finite branch out of reach: the run stays in the finite region, against the
    boundary, every accepted value finite, and does not report convergence."""

    def fun(x):
        if x[0] > 0.5:
            return np.inf, np.full(1, np.nan), None
        return (x[0] - 2.0) ** 2, np.array([2.0 * (x[0] - 2.0)]), None

    result = lbfgsb(fun, np.array([-3.0]), -np.inf, np.inf, max_steps=100, gtol=1e-12)
    assert np.isfinite(result.value) and result.x[0] <= 0.5
    assert result.x[0] > 0.4  # pushed towards the boundary
    assert not result.converged
    assert np.all(np.isfinite(result.history[: result.steps]))


def test_non_finite_start_and_step_cap():
    """A non-finite start stops at once (not converged, no step); a zero projected
    gradient at the start stops at once (converged); max_steps caps the iterations."""
    bad = lbfgsb(lambda x: (np.nan, x, None), np.ones(2), -np.inf, np.inf, max_steps=5, gtol=0.0)
    assert not bad.converged and bad.steps == 0 and bad.evaluations == 1
    # at its lower bound, pushed outward: a constrained stationary point
    done = lbfgsb(lambda x: (float(x[0]), np.ones(1), None), np.zeros(1), 0.0, 1.0, max_steps=5,
                  gtol=0.0)  # fmt: skip
    assert done.converged and done.steps == 0 and done.x[0] == 0.0
    a, b, lower, upper, _ = _diagonal_quadratic(50, seed=1)
    rotation = np.linalg.qr(np.random.default_rng(2).normal(size=(50, 50)))[0]
    hessian = rotation @ np.diag(a) @ rotation.T
    capped = lbfgsb(
        lambda x: (0.5 * x @ hessian @ x - b @ x, hessian @ x - b, None),
        np.zeros(50),
        lower,
        upper,
        max_steps=3,
        gtol=0.0,
    )
    assert capped.steps == 3 and not capped.converged


def test_a_loss_falling_to_zero_is_not_stopped_early():
    """A rotated quadratic whose minimum is 0 (a perfectly balanced design, loss 1 at the
    start): L-BFGS-B's stopping test on the loss decrease is relative to max(|f|, 1),
    i.e. absolute once the loss is small; the runs are rescaled, so the point still
    reaches the minimiser to 1e-9 and the projected gradient gtol = 1e-14."""
    rng = np.random.default_rng(3)
    rotation = np.linalg.qr(rng.normal(size=(12, 12)))[0]
    hessian = rotation @ np.diag(np.geomspace(1.0, 100.0, 12)) @ rotation.T
    exact = rng.uniform(1.0, 2.0, 12)
    x0 = np.zeros(12)
    norm = 0.5 * (x0 - exact) @ hessian @ (x0 - exact)

    def fun(x):
        e = x - exact
        return 0.5 * e @ hessian @ e / norm, hessian @ e / norm, None

    result = lbfgsb(fun, x0, np.zeros(12), np.full(12, np.inf), max_steps=500, gtol=1e-14)
    assert result.converged and result.value < 1e-20
    np.testing.assert_allclose(result.x, exact, rtol=0, atol=1e-9)
