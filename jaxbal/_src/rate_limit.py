"""Trapezoidal-acceleration planning under actuator torque-rate limits.

Solves problem (5)-(6) of Briot et al. (2012): choose the switch times ``(u1, u2)`` of
a :class:`~jaxbal.profiles.TrapezoidalAcceleration` profile to minimise its peak
acceleration subject to ``max_t |dτ_i/dt| ≤ τ̇_max`` for every actuator.

The paper used Matlab's ``fgoalattain``. jaxbal solves the two-parameter problem by a
vectorised grid search refined around the best feasible point (``vmap`` over
candidates), which is global on the grid, deterministic, and needs no gradient of a
maximum. Torque rates are sampled on a uniform grid *plus* dense samples inside each
jerk phase (the torque rate is continuous inside a phase and jumps at its ends), so
short ramps are never missed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.planning import torque_rate_along
from jaxbal._src.profiles import TrapezoidalAcceleration
from jaxbal._src.robot import Robot


class RateLimitedPlan(NamedTuple):
    """Result of :func:`plan_rate_limited`.

    Attributes:
        profile: the optimal :class:`TrapezoidalAcceleration`.
        peak_rate: ``max_t max_i |dτ_i/dt|`` along it [N·m/s].
        peak_acceleration: its normalised peak ``|s''|`` (4 for bang-bang).
    """

    profile: TrapezoidalAcceleration
    peak_rate: jax.Array
    peak_acceleration: jax.Array


def _sample_times(profile: TrapezoidalAcceleration, duration, uniform: int, per_phase: int):
    phases, widths = profile.jerk_phases()
    inner = jnp.linspace(0.0, 1.0 - 1e-9, per_phase)
    dense = (phases[:, None] + widths[:, None] * inner[None, :]).reshape(-1)
    grid = jnp.linspace(0.0, 1.0, uniform)
    return jnp.concatenate([grid, dense]) * duration


def peak_torque_rate(
    robot: Robot,
    make_path: Callable,
    data,
    profile: TrapezoidalAcceleration,
    duration,
    uniform: int = 201,
    per_phase: int = 16,
):
    """``max_t max_i |dτ_i/dt|`` [N·m/s] of the path ``make_path(profile, data)``."""
    times = _sample_times(profile, duration, uniform, per_phase)
    rates = torque_rate_along(robot, make_path(profile, data), times)
    return jnp.max(jnp.abs(rates))


@eqx.filter_jit
def _candidate_rates(robot, make_path, data, duration, u1, u2):
    def one(a, b):
        return peak_torque_rate(robot, make_path, data, TrapezoidalAcceleration(a, b), duration)

    return jax.vmap(one)(u1, u2)


@jax.jit
def _candidate_accelerations(u1, u2):
    return jax.vmap(lambda a, b: TrapezoidalAcceleration(a, b).peak_acceleration)(u1, u2)


def plan_rate_limited(
    robot: Robot,
    make_path: Callable,
    data,
    duration: float,
    rate_limit: float,
    grid: int = 12,
    refinements: int = 3,
) -> RateLimitedPlan:
    """Optimal trapezoidal profile under a torque-rate limit (Briot et al. 2012, eqs 5-6).

    Args:
        robot: any robot (closed chains included: the rates of its actuators'
            torques, :func:`~jaxbal.planning.torque_rate_along`).
        make_path: ``(profile, data) ↦ trajectory`` (e.g. a COM line with that
            profile). Define it once at module level: compiled code is reused across
            calls with the same ``make_path`` and new ``data``.
        data: pytree of arrays passed to ``make_path`` (endpoints, free-angle law...).
        duration: motion time T [s] of the paths ``make_path`` builds: the torque rates
            are checked at times in ``[0, T]``.
        rate_limit: ``τ̇_max`` [N·m/s], the same for every actuator.
        grid: candidates per axis at each level.
        refinements: number of zoom-in levels around the best feasible candidate.

    Raises:
        ValueError: a ``duration`` that is not finite and ``> 0``, a ``rate_limit`` that
            is not finite and ``> 0``, a ``grid`` < 2 or ``refinements`` < 0, or no
            candidate satisfying the limit (the move is too fast).
    """
    # eagerly, before any compilation: T <= 0 sampled the rates at t <= 0 only and
    # reported a plan "within" the limit whose move broke it 267-fold
    for name, value in (("duration", duration), ("rate_limit", rate_limit)):
        number = np.asarray(value, dtype=float)
        if number.shape != () or not (np.isfinite(number) and number >= np.finfo(float).tiny):
            raise ValueError(f"plan_rate_limited: {name} must be finite and > 0, got {value!r}")
    for name, value, least in (("grid", grid, 2), ("refinements", refinements, 0)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < least:
            raise ValueError(f"plan_rate_limited: {name} must be an int >= {least}, got {value!r}")
    duration = jnp.asarray(duration, dtype=float)

    # Search in (u1, g) with u2 = 1/2 − g/2, i.e. g = 1 − 2 u2 the length of the middle ramp.
    lo = jnp.array([1e-4, 1e-4])
    hi = jnp.array([0.45, 0.9])
    best = None
    for _ in range(refinements + 1):
        a = jnp.linspace(lo[0], hi[0], grid)
        g = jnp.linspace(lo[1], hi[1], grid)
        aa, gg = (x.reshape(-1) for x in jnp.meshgrid(a, g, indexing="ij"))
        u1, u2 = aa, 0.5 - 0.5 * gg
        ok = u1 <= u2
        peak = jnp.where(
            ok, _candidate_rates(robot, make_path, data, duration, u1, jnp.maximum(u2, u1)), jnp.inf
        )
        acc = _candidate_accelerations(jnp.minimum(u1, u2), u2)
        feasible = ok & (peak <= rate_limit)
        if not bool(jnp.any(feasible)):
            if best is None:
                raise ValueError(
                    f"no trapezoidal profile meets the torque-rate limit {rate_limit} N·m/s "
                    f"(smallest peak rate found {float(jnp.min(peak)):.4g} N·m/s)"
                )
            break
        index = int(jnp.argmin(jnp.where(feasible, acc, jnp.inf)))
        best = (float(aa[index]), float(gg[index]), float(peak[index]), float(acc[index]))
        step = (hi - lo) / (grid - 1)
        centre = jnp.array(best[:2])
        lo = jnp.maximum(centre - step, 1e-5)
        hi = jnp.minimum(centre + step, jnp.array([0.5, 1.0]))
    u1, g, peak, acc = best
    profile = TrapezoidalAcceleration(u1, 0.5 - 0.5 * g)
    return RateLimitedPlan(profile, jnp.asarray(peak), jnp.asarray(acc))
