"""Motion profiles: boundary conditions, closed-form peaks, gradients.

References: Briot et al. (2012) eqs (3)-(4) and Fig 1; the closed forms of the
bang-bang (4S/T²) and quintic (10S/(√3T²)) peak accelerations.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.profiles import BangBang, BoundaryPolynomial, Quintic, TrapezoidalAcceleration

U = jnp.linspace(0.0, 1.0, 20001)


@eqx.filter_jit  # one program (eagerly, the nested derivatives ran op by op)
def derivatives(profile, u):
    return jax.vmap(lambda v: jaxbal.time_derivatives(profile, v, order=3))(u)


@pytest.mark.parametrize(
    "profile",
    [Quintic(), BangBang(), TrapezoidalAcceleration(0.1, 0.3), BoundaryPolynomial([1.0, -2, 3])],
    ids=["quintic", "bangbang", "trapezoid", "poly8"],
)
def test_boundary_conditions(profile):
    s, sd, _, _ = derivatives(profile, jnp.array([0.0, 1.0]))
    np.testing.assert_allclose(s, [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(sd, [0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("profile", [Quintic(), TrapezoidalAcceleration(0.1, 0.3)])
def test_zero_end_accelerations(profile):
    _, _, sdd, _ = derivatives(profile, jnp.array([0.0, 1.0 - 1e-12]))
    np.testing.assert_allclose(sdd, 0.0, atol=1e-6)


def test_peak_accelerations_closed_form():
    """Bang-bang 4S/T², quintic 10S/(√3 T²), for S = 0.3 m, T = 0.5 s (rel 1e-6)."""
    distance, duration = 0.3, 0.5
    times = jnp.linspace(0.0, duration, 20001)
    for profile, expected in [(BangBang(), 4.0), (Quintic(), 10.0 / np.sqrt(3.0))]:
        line = jaxbal.StraightLine([0.0], [distance], profile, duration)
        _, _, acc = jaxbal.sample(line, times)
        peak = float(jnp.max(jnp.abs(acc)))
        np.testing.assert_allclose(peak, expected * distance / duration**2, rtol=1e-6)


def test_bang_bang_is_right_continuous():
    _, _, sdd, _ = derivatives(BangBang(), jnp.array([0.0, 0.25, 0.5, 0.75]))
    np.testing.assert_allclose(sdd, [4.0, 4.0, -4.0, -4.0], atol=1e-12)


def test_trapezoid_tends_to_bang_bang():
    """u1 → 0, u2 → 1/2: trapezoid peak acceleration → 4 (error O(u1 + gap))."""
    profile = TrapezoidalAcceleration(1e-4, 0.5 - 1e-4)
    assert abs(float(profile.peak_acceleration) - 4.0) < 4.0 * 1e-3
    _, _, sdd, _ = derivatives(profile, U)
    np.testing.assert_allclose(float(jnp.max(jnp.abs(sdd))), float(profile.peak_acceleration))


def test_trapezoid_plateau_value_closed_form():
    """Symmetric trapezoid: ∫∫ s'' = 1 gives a = 1 / (area-weighted first moment)."""
    u1, u2 = 0.1, 0.3
    profile = TrapezoidalAcceleration(u1, u2)
    # velocity at u=1/2 equals the area of the positive half; s(1)=2·s(1/2) by symmetry.
    _, sd, _, _ = derivatives(profile, jnp.array([0.5]))
    area = float(profile.peak_acceleration) * (0.5 * u1 + (u2 - u1) + 0.5 * (0.5 - u2))
    np.testing.assert_allclose(float(sd[0]), area, rtol=1e-12)


@pytest.mark.slow
def test_profile_gradients_finite_differences():
    def position(params, u):
        return TrapezoidalAcceleration(params[0], params[1])(u)

    check_grads(
        lambda p: position(p, 0.37), (jnp.array([0.12, 0.31]),), order=2, modes=["fwd", "rev"]
    )
    check_grads(lambda c: BoundaryPolynomial(c)(0.63), (jnp.array([0.5, -1.0, 2.0]),), order=2)
    grad = jax.grad(lambda c: jnp.sum(derivatives(BoundaryPolynomial(c), U[::100])[2]))(
        jnp.zeros(3)
    )
    assert jnp.all(jnp.isfinite(grad))


def test_polynomial_degree():
    assert BoundaryPolynomial(jnp.zeros(3)).degree == 8
    coefficients = jnp.array([0.3, -0.2, 0.7])
    values = jax.vmap(BoundaryPolynomial(coefficients))(U[::50])
    fit = np.polynomial.polynomial.polyfit(np.asarray(U[::50]), np.asarray(values), 10)
    np.testing.assert_allclose(fit[9:], 0.0, atol=1e-8)
    with pytest.raises(ValueError, match="degree"):
        jaxbal.profiles.polynomial_of_degree(4)
