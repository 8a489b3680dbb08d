"""The one-dimensional searches of :func:`jaxbal.sensitivity.tolerance`: along each
design-variable entry, in both directions, the distance at which the metric first
exceeds its threshold (see :mod:`jaxbal._src.tolerance`).

All ``2n`` directions advance together, one batched evaluation of the metric per step
(runtime checks off: an invalid state is NaN, outside the interval): steps double from
the quadratic estimate until the threshold, a bound or the reach; bisection to
``xtol``; then :data:`SCAN` points inside each interval are checked (a crossing the
steps jumped over is bisected in turn); last, each end is evaluated with the checks
on, since with them off the metric can be finite where a check fails.

References:
    Press et al. (2007), *Numerical Recipes*, §9.1 (bracketing and bisection).
"""

from __future__ import annotations

import jax
import numpy as np
from jax.flatten_util import ravel_pytree

from jaxbal._src.robot import Robot
from jaxbal._src.sensitivity import _metric_at, _values_at
from jaxbal._src.validation import checked_call, runtime_checks

__all__ = ["ENDS", "SCAN", "lower_bounds", "search"]

#: points checked inside each interval after the bisection (a crossing the doubling
#: steps jumped over, e.g. a narrow bump, is then found and bisected).
SCAN = 16
#: why a search ended: the metric reached the threshold (``"rise"``), the variable's
#: lower bound (``"bound"``) or the reach (``"reach"``) came first, or the design stopped
#: being valid (``"invalid"``: an unreachable pose, a failed check) before the threshold.
ENDS = ("rise", "bound", "reach", "invalid")


def search(robot, motion, metric, chosen, x0, g, h, value, threshold, xtol, reach, unravel):
    """Distances ``(2n,)`` below then above each entry to the threshold, and why each
    search ended (:data:`ENDS`; module doc)."""
    n = x0.size
    scale = np.tile(np.maximum(np.abs(x0), 1.0), 2)
    room = x0 - np.asarray(ravel_pytree(lower_bounds(robot, chosen))[0])
    bound = np.concatenate([room <= reach * scale[:n], np.zeros(n, bool)])
    limit = np.maximum(np.where(bound, np.concatenate([room, room]), reach * scale), 0.0)
    sign = np.concatenate([-np.ones(n), np.ones(n)])
    slope, curve = np.concatenate([-g, g]), np.concatenate([np.diag(h), np.diag(h)])
    guess = _quadratic_step(slope, curve, threshold - value)
    usable = np.isfinite(guess) & (guess > 0)
    step = np.minimum(np.where(usable, guess, 1e-3 * scale), limit)
    entry = np.tile(np.arange(n), 2)

    def values_at(steps):  # steps (2n, k): the metric at k points along each direction
        k = steps.shape[1]
        points = np.repeat(x0[None], 2 * n * k, axis=0)
        points[np.arange(2 * n * k), np.repeat(entry, k)] += np.repeat(sign, k) * steps.ravel()
        with runtime_checks(False):  # an invalid state is NaN: outside the interval
            out = np.asarray(_values_at(jax.vmap(unravel)(points), robot, motion, metric))
        return out.reshape(2 * n, k)

    low, high, bad = np.zeros(2 * n), np.full(2 * n, np.nan), np.zeros(2 * n, bool)
    for _ in range(200):  # expand: 2**200 covers any reach from any first step
        todo = np.isnan(high) & (low < limit)
        if not np.any(todo):
            break
        f = values_at(np.where(todo, step, 0.0)[:, None])[:, 0]
        ok = f <= threshold  # NaN: False
        low, high = np.where(todo & ok, step, low), np.where(todo & ~ok, step, high)
        bad = np.where(todo & ~ok, np.isnan(f), bad)
        step = np.where(todo & ok, np.minimum(2.0 * step, limit), step)
    for _ in range(8):  # bisect, then look inside for a crossing the steps jumped over
        for _ in range(200):
            todo = ~np.isnan(high) & (high - low > xtol * scale)
            if not np.any(todo):
                break
            middle = 0.5 * (low + high)
            f = values_at(np.where(todo, middle, 0.0)[:, None])[:, 0]
            ok = f <= threshold
            low, high = np.where(todo & ok, middle, low), np.where(todo & ~ok, middle, high)
            bad = np.where(todo & ~ok, np.isnan(f), bad)
        fractions = np.arange(1, SCAN + 1) / (SCAN + 1)
        inside = values_at(low[:, None] * fractions[None, :])
        above = ~(inside <= threshold)
        if not np.any(above):
            break
        first = np.argmax(above, axis=1)
        hit = np.any(above, axis=1)
        high = np.where(hit, low * fractions[first], high)
        bad = np.where(hit, np.isnan(inside[np.arange(2 * n), first]), bad)
        low = np.where(hit, np.where(first > 0, low * fractions[first - 1], 0.0), low)
    ends = np.where(np.isnan(high), np.where(bound, "bound", "reach"), "rise")
    ends = np.where(bad, "invalid", ends)
    return _valid_ends(low, ends, x0, sign, entry, xtol * scale, unravel, robot, motion, metric)


def _valid_ends(low, ends, x0, sign, entry, tol, unravel, robot, motion, metric):
    """``(low, ends)`` with each end checked with the runtime checks on: the metric can
    be finite where a check fails (an unreachable COM target, with the checks off); an
    end that fails is moved back to the last valid point (``"invalid"``)."""

    def valid(k, distance):
        point = x0.copy()
        point[entry[k]] += sign[k] * distance
        try:
            return bool(
                np.isfinite(checked_call(_metric_at, unravel(point), robot, motion, metric))
            )
        except ValueError:
            return False

    low, ends = low.copy(), ends.copy()
    for k in np.flatnonzero(low > 0):
        if valid(k, low[k]):
            continue
        a, b = 0.0, low[k]
        while b - a > tol[k]:
            middle = 0.5 * (a + b)
            a, b = (middle, b) if valid(k, middle) else (a, middle)
        low[k], ends[k] = a, "invalid"
    return low, ends


def _quadratic_step(slope, curve, rise):
    """Positive root of ``slope·δ + curve·δ²/2 = rise`` (NaN where there is none)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        quadratic = (-slope + np.sqrt(slope**2 + 2.0 * curve * rise)) / curve
        linear = rise / slope
    return np.where(np.abs(curve) > 0, quadratic, np.where(slope > 0, linear, np.nan))


def lower_bounds(robot: Robot, chosen) -> dict[str, np.ndarray]:
    """The robot's own lower bounds of the chosen variables (``-inf`` where none)."""
    bounds = robot.design_lower_bounds()
    return {
        name: np.broadcast_to(np.asarray(bounds.get(name, -np.inf), dtype=float), np.shape(x))
        for name, x in chosen.items()
    }
