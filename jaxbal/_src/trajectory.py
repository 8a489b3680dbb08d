"""Trajectories ``t ↦ q(t)`` and their exact time derivatives.

A trajectory is any callable from time [s] to coordinates; the concrete ones are
:class:`equinox.Module` pytrees (so their parameters -- endpoints, profile
coefficients, duration, the robot itself -- are differentiable). Velocities,
accelerations and jerks are obtained by nested forward-mode differentiation in time,
never by finite differences.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.callables import as_pytree
from jaxbal._src.profiles import Profile, checked_duration, normalised_time
from jaxbal._src.types import Array, Float, ScalarLike
from jaxbal._src.validation import checked_call


def time_derivatives(path: Callable, t: ScalarLike, order: int = 2) -> tuple:
    """``(x(t), ẋ(t), …, x⁽ᵒʳᵈᵉʳ⁾(t))`` of any differentiable ``path`` by nested ``jvp``.

    The path is traced once: each ``jvp`` level differentiates the tuple of the lower
    derivatives and keeps the tangent of the last one (tracing ``x``, ``ẋ`` and ``ẍ``
    separately traced the path ``order + 1`` times, with its checks: ~2× the program).
    """
    t = jnp.asarray(t, dtype=float)

    def upto(k):
        if k == 0:
            return lambda s: (path(s),)
        lower = upto(k - 1)

        def derivatives(s):
            values, rates = jax.jvp(lower, (s,), (jnp.ones_like(s),))
            return (*values, rates[-1])

        return derivatives

    return upto(order)(t)


def sample(path: Callable, times: Float[Array, " t"], order: int = 2) -> tuple:
    """:func:`time_derivatives` at every time of ``times`` (vectorised with ``vmap``).

    Called eagerly it runs as one compiled program (:func:`~jaxbal.checked_jit`: a
    check inside the path, e.g. a non-positive duration, raises ``ValueError``), compiled
    once per path structure: a lambda or closure path is taken as a pytree, so an
    equivalent new one reuses the program (op by op, a third-order sample of a profile
    took seconds). Under a trace it is inlined."""
    times = jnp.asarray(times, dtype=float)
    return checked_call(_sampled, as_pytree(path), times, order, once=True)


def _sampled(path: Callable, times, order: int) -> tuple:
    if times.ndim != 1 or times.shape[0] == 0:  # zero instants: a ZeroDivisionError
        raise ValueError(f"times must have shape (t,) with t >= 1 [s], got {times.shape}")
    resolve = getattr(path, "resolved", None)  # what does not depend on t, done once
    resolved = resolve() if callable(resolve) else path
    samples = tuple(jax.vmap(lambda t: time_derivatives(resolved, t, order))(times))
    check = getattr(path, "checked_samples", None)  # e.g. a COM plan's joins
    return samples if check is None else (check(times, samples[0]), *samples[1:])


def sample_times(duration: ScalarLike, count: int = 1001) -> Float[Array, " t"]:
    """``count ≥ 2`` equally spaced instants on ``[0, duration]`` [s], both ends
    included; ``duration`` finite and ``> 0`` (eagerly a ``ValueError``, under ``jit`` a
    runtime error: ``sample_times(0.0)`` gave instants all zero, a peak force of 0 N)."""
    if isinstance(count, bool) or not isinstance(count, int | np.integer) or count < 2:
        raise ValueError(f"count must be an integer >= 2 (both ends of the move), got {count!r}")
    return jnp.linspace(0.0, 1.0, count) * checked_duration(duration, "sample_times:")


class StraightLine(eqx.Module):
    """A straight-line move ``x(t) = x0 + s(t/T)·(x1 − x0)`` with a motion profile.

    Attributes:
        start, end: ``(k,)`` endpoints (any units: m for points, rad for angles).
        profile: a :class:`~jaxbal.profiles.Profile`.
        duration: ``T`` [s].

    References:
        Briot et al. (2012), eqs (2a)-(3).
    """

    start: Float[Array, " k"]
    end: Float[Array, " k"]
    profile: Profile
    duration: Float[Array, ""]

    def __init__(self, start, end, profile: Profile, duration: ScalarLike):
        self.start = jnp.atleast_1d(jnp.asarray(start, dtype=float))
        self.end = jnp.atleast_1d(jnp.asarray(end, dtype=float))
        self.profile = profile
        self.duration = jnp.asarray(duration, dtype=float)
        if self.start.shape != self.end.shape:
            raise ValueError(f"start {self.start.shape} and end {self.end.shape} differ in shape")

    def __call__(self, t: ScalarLike) -> Float[Array, " k"]:
        u = normalised_time(t, self.duration, "StraightLine")
        return self.start + self.profile(u) * (self.end - self.start)
