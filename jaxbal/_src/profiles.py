"""Motion profiles ``s(u)`` on normalised time ``u = t/T ∈ [0, 1]``, with s(0)=0, s(1)=1.

Profiles are :class:`equinox.Module` pytrees whose parameters (switch times,
polynomial coefficients) are differentiable leaves. Derivatives with respect to
``u`` come from autodiff; each profile is written so that its derivatives are exact
and *right-continuous* at switching instants (the acceleration of a bang-bang profile
at ``u = 1/2`` is the decelerating value).

Peak accelerations for a displacement ``S`` in time ``T`` (closed forms, tested):

* quintic ``10u³ − 15u⁴ + 6u⁵``: ``10 S / (√3 T²)``;
* bang-bang: ``4 S / T²`` (time-optimal for a bounded acceleration).

References:
    Briot, Arakelian & Le Baron (2012), eqs (2)-(6) and Fig 1; Khalil & Dombre (2002).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from jaxbal._src.types import Array, Float, Scalar, ScalarLike
from jaxbal._src.validation import guard


def _ramp_power(x, power: int):
    """``max(x, 0)**power / power!`` written with ``where`` so all its u-derivatives are
    exact and right-continuous at ``x = 0``."""
    factorial = {0: 1.0, 1: 1.0, 2: 2.0, 3: 6.0}[power]
    positive = x >= 0
    safe = jnp.where(positive, x, 0.0)
    return jnp.where(positive, safe**power / factorial, 0.0)


def _cube_difference(u, start, end):
    """``(r(u − start)³ − r(u − end)³) / (6 (end − start))`` with ``r = max(·, 0)``, for
    ``start ≤ end``: the position of a unit jerk switched on at ``start`` and off at
    ``end``, scaled by ``1/(end − start)``. Written without the cancellation of the
    difference (``a² + ab + b²`` once both ramps are on), so a phase of width 1e-71
    gives the bang-bang limit, not round-off times 1e71; u-derivatives exact and
    right-continuous at both ends."""
    a, b = u - start, u - end
    a_on = jnp.where(a >= 0, a, 0.0)
    b_on = jnp.where(b >= 0, b, 0.0)
    ramping = a_on**3 / (6.0 * jnp.maximum(end - start, 1e-300))
    both_on = (a_on**2 + a_on * b_on + b_on**2) / 6.0
    return jnp.where(b >= 0, both_on, ramping)


def held(u):
    """``u`` inside ``[0, 1]``; outside it the constant end (0 or 1), so that a move
    evaluated before its start or after its duration rests at its start or end pose
    (``s`` = 0 or 1, its derivatives 0: every built-in profile starts and ends at
    rest) instead of extrapolating its polynomial (sampling a 0.5 s move on ``[0, 1]``
    s gave 50× its peak force). Written with ``where``, not ``clip``: at ``u = 0`` and
    ``1`` the derivatives are the move's (``clip`` halves them there)."""
    return jnp.where(u > 1.0, 1.0, jnp.where(u < 0.0, 0.0, u))


def checked_duration(duration, what: str):
    """``duration`` [s] as a float array, guarded by being finite and ``> 0`` (eagerly a
    ``ValueError`` naming it, under ``jit`` a runtime error)."""
    duration = jnp.asarray(duration, dtype=float)
    invalid = ~(jnp.isfinite(duration) & (duration > 0))
    return guard(duration, invalid, f"{what} duration must be finite and > 0 [s]", duration)


def normalised_time(t, duration, what: str):
    """``u = t / T`` of a move of ``duration`` ``T`` [s], ``T`` checked where it is used
    (:func:`checked_duration`), so that a duration changed by ``eqx.tree_at`` or an
    optimiser is checked too (``T = 0`` gave ``u = ±inf``, the end pose at every time)."""
    return jnp.asarray(t, dtype=float) / checked_duration(duration, what)


def _checked_time(profile, u, value):
    """``value = s(u)``, guarded by a finite ``u`` and a finite ``s(u)``: a NaN time gave a
    silent NaN. Eagerly a ``ValueError`` naming ``u``; under ``jit`` a runtime error."""
    invalid = ~(jnp.isfinite(u) & jnp.isfinite(value))
    message = f"{type(profile).__name__} profile: u must be finite (the normalised time t/T)"
    return guard(value, invalid, message, u)


class Profile(eqx.Module):
    """Base class: ``profile(u)`` returns ``s(u)``, dimensionless. The built-in profiles
    rest outside ``[0, 1]`` (:func:`held`); a profile of your own should too."""

    def __call__(self, u: ScalarLike) -> Scalar:
        raise NotImplementedError


class Quintic(Profile):
    """Fifth-order polynomial ``10u³ − 15u⁴ + 6u⁵`` (zero velocity and acceleration at
    both ends). Briot et al. (2012), case 1."""

    def __call__(self, u):
        u = jnp.asarray(u, dtype=float)
        v = held(u)
        return _checked_time(self, u, v**3 * (10.0 - 15.0 * v + 6.0 * v**2))


class BangBang(Profile):
    """Bang-bang acceleration: ``s'' = +4`` for ``u < 1/2``, ``−4`` after.

    References: Briot et al. (2012), eqs (3)-(4), Fig 1a.
    """

    def __call__(self, u):
        u = jnp.asarray(u, dtype=float)
        v = held(u)
        return _checked_time(self, u, 4.0 * (_ramp_power(v, 2) - 2.0 * _ramp_power(v - 0.5, 2)))


class TrapezoidalAcceleration(Profile):
    """Trapezoidal acceleration (Fig 1b of Briot et al. 2012), symmetric about ``u = 1/2``.

    The acceleration rises linearly from 0 to ``+a`` on ``[0, u1]``, stays at ``+a`` on
    ``[u1, u2]``, goes linearly to ``−a`` on ``[u2, 1 − u2]``, stays at ``−a`` on
    ``[1 − u2, 1 − u1]`` and returns to 0 at ``u = 1``. ``a`` is fixed by ``s(1) = 1``.
    Bang-bang is the limit ``u1 → 0, u2 → 1/2``.

    Attributes:
        u1: first switch time as a fraction of the duration, ``0 < u1 ≤ u2`` (a
            subnormal ``u1 < 2.2e-308`` counts as 0: XLA flushes it).
        u2: second switch time as a fraction of the duration, ``u2 < 1/2``.

    The jerk is piecewise constant, so actuator torque *rates* stay bounded, which is
    what eq (6) of the paper needs.
    """

    u1: Float[Array, ""]
    u2: Float[Array, ""]

    def __init__(self, u1: ScalarLike, u2: ScalarLike):
        self.u1 = jnp.asarray(u1, dtype=float)
        self.u2 = jnp.asarray(u2, dtype=float)

    def _shape(self, u):
        """Position for a unit plateau acceleration: jerk ``+1/u1`` on ``[0, u1]``,
        ``−2/(1 − 2u2)`` on ``[u2, 1 − u2]``, ``+1/u1`` from ``1 − u1`` on."""
        u1, u2 = self.u1, self.u2
        last = _ramp_power(u - (1.0 - u1), 3) / jnp.maximum(u1, 1e-300)
        return (
            _cube_difference(u, jnp.zeros_like(u1), u1)
            - 2.0 * _cube_difference(u, u2, 1.0 - u2)
            + last
        )

    def __call__(self, u):
        u = jnp.asarray(u, dtype=float)
        value = self._checked(self._shape(held(u)) / self._shape(jnp.asarray(1.0)))
        return _checked_time(self, u, value)

    def jerk_phases(self) -> tuple[Float[Array, "3"], Float[Array, "3"]]:
        """Starts and widths ``(3,)`` each (fractions of the duration) of the three
        phases of non-zero jerk, ``[0, u1]``, ``[u2, 1 − u2]``, ``[1 − u1, 1]``: the
        actuator torque rate jumps at their ends, so sample inside them to see it."""
        u1, u2 = self.u1, self.u2
        starts = jnp.stack([jnp.zeros_like(u1), u2, 1.0 - u1])
        return starts, jnp.stack([u1, 1.0 - 2.0 * u2, u1])

    def _checked(self, value):
        """``value``, guarded by ``0 < u1 ≤ u2 < 1/2`` (finite) where the profile is used."""
        switches = jnp.stack([self.u1, self.u2])
        ordered = (self.u1 > 0) & (self.u1 <= self.u2) & (self.u2 < 0.5)
        bad = ~(jnp.all(jnp.isfinite(switches)) & ordered)
        message = "TrapezoidalAcceleration switch times must satisfy 0 < u1 <= u2 < 1/2"
        return guard(value, bad, message, switches)

    @property
    def peak_acceleration(self) -> Scalar:
        """Peak ``|s''|`` (the plateau value ``a``) for unit displacement and duration
        (switch times checked as where the profile is used)."""
        return self._checked(1.0 / self._shape(jnp.asarray(1.0)))


class BoundaryPolynomial(Profile):
    """Polynomial with ``s(0)=0, s(1)=1`` and zero velocity and acceleration at both ends.

    ``s(u) = 10u³ − 15u⁴ + 6u⁵ + u³(1 − u)³ Σ_k c_k u^k``; with ``K ≥ 1`` free
    coefficients its degree is ``5 + K``. Every choice of
    ``c`` satisfies the six boundary conditions, so the coefficients can be optimised
    freely. Degree 8 (``K = 3``) is the free-angle law of Briot et al. (2012), eqs (19)-(20).
    """

    coefficients: Float[Array, " k"]

    def __init__(self, coefficients):
        self.coefficients = jnp.atleast_1d(jnp.asarray(coefficients, dtype=float))

    @property
    def degree(self) -> int:
        return 5 + max(self.coefficients.shape[0], 1)

    def __call__(self, u):
        u = jnp.asarray(u, dtype=float)
        v = held(u)
        # Horner's scheme: no u**0 whose derivative at u = 0 would be 0·∞ = NaN.
        bump = (v * (1.0 - v)) ** 3 * jnp.polyval(self.coefficients[::-1], v)
        value = guard(
            Quintic()(v) + bump,
            ~jnp.all(jnp.isfinite(self.coefficients)),
            "BoundaryPolynomial coefficients must be finite",
            self.coefficients,
        )
        return _checked_time(self, u, value)


def polynomial_of_degree(degree: int) -> BoundaryPolynomial:
    """A :class:`BoundaryPolynomial` of the given degree (≥ 6), initialised to the quintic."""
    if degree < 6:
        raise ValueError(f"degree must be >= 6 for free coefficients, got {degree}")
    return BoundaryPolynomial(jnp.zeros(degree - 5))
