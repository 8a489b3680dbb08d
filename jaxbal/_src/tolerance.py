"""How tightly a design pins its metric down: machining tolerances and flat directions.

Before a counter-mass is machined, a user needs to know two things about an optimised
design that its gradient alone does not tell:

* **Tolerance.** By how much may each design variable alone be off (a counter-mass
  machined 20 g heavy, a distance 1 mm short) before the metric (e.g. the RMS shaking
  force) rises by ``rise`` (default 1 %)? Found on the metric itself, not on a model:
  along each variable, in both directions, steps double from the quadratic estimate
  until the metric exceeds ``threshold = (1 + rise)·value`` (or ``value + allowed``),
  then bisection to ``xtol``. A variable's own bound (a mass at 0 kg) or the search
  reach ends the search first where the metric stays below: ``open`` says so.
* **Coupling.** Does the optimum fix each variable, or can the others make up for it?
  From the Hessian ``H`` of the metric in the variables (SI units) at the design, the
  coupling of entry ``i`` is ``√(H_ii (H⁻¹)_ii) ≥ 1``, unit-free: the tolerance of
  the variable when the others are re-adjusted, divided by its tolerance alone (second
  order). Near 1 the variable is pinned; ≫ 1 the others compensate it (the DUAL-V's
  counter-masses trade against each other: SciPy's and jaxbal's optima differ by
  0.4 kg each at the same loss); ``inf`` on a flat direction (e.g. a counter-mass and
  its distance, whose product alone the force sees). ``flattest`` is that direction
  (offsets in SI units) and ``flattest_curvature`` its curvature relative to the
  diagonal (0 flat, 1 uncoupled): the eigenpair of ``D^-½ H D^-½``, ``D = diag H``.

The coupling is second-order information: it describes the design where the metric
is smooth and convex there (``convex``: no negative curvature; else the couplings are
NaN, e.g. a product ``m·d`` away from its optimum), and it is the tolerance ratio of
the module doc at a minimum (``minimum``: also ``stationary``, the gradient's share of
every interval's rise below :data:`STATIONARY_SHARE`, or the entry on its lower bound
with the gradient pushing it there). A peak metric's Hessian is that of its peak sample
alone. The tolerances hold for any metric and any design.

References:
    Nocedal & Wright (2006), *Numerical Optimization*, §2.1 (second-order conditions);
    Belsley, Kuh & Welsch (1980), *Regression Diagnostics*, ch. 3 (variance inflation:
    the coupling is its square root for a quadratic loss).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import numpy as np
from jax.flatten_util import ravel_pytree

from jaxbal._src.metrics import Metric, Motion, check_design_names, resolve_metric
from jaxbal._src.robot import Robot
from jaxbal._src.sensitivity import _metric_at, _value_and_grad, _values_at
from jaxbal._src.validation import checked_call, runtime_checks

__all__ = ["FLAT_RTOL", "STATIONARY_SHARE", "Tolerance", "tolerance"]

#: a curvature of ``D^-½ H D^-½`` below this (relative to its largest) counts as flat:
#: the couplings of the entries along it are ``inf``.
FLAT_RTOL = 1e-9
#: a design is stationary when, for every entry off its lower bound, the gradient's
#: first-order change over the tolerance interval is at most this share of the rise.
STATIONARY_SHARE = 0.1


class Tolerance(NamedTuple):
    """Result of :func:`tolerance` (offsets and tolerances in the variables' SI units).

    Attributes:
        value: the metric at the design [its SI unit].
        threshold: the metric each interval end reaches, ``(1 + rise)·value`` or
            ``value + allowed``.
        interval: name -> ``(below, above)``, arrays of the variable's shape: the entry
            alone may move by ``−below … +above`` with the metric at most ``threshold``.
        open: name -> ``(below, above)`` booleans: the search ended at the variable's
            bound or reach with the metric still below ``threshold`` (the tolerance is
            at least that).
        gradient: name -> ``∂metric/∂variable``.
        hessian: ``(n, n)`` second derivatives in the order of ``labels``.
        labels: ``(n,)`` entry names, e.g. ``"counter_masses[1]"``.
        coupling: name -> ``√(H_ii (H⁻¹)_ii)`` (module doc; ``inf`` on a flat
            direction, ``nan`` for an entry the metric does not depend on).
        flattest: name -> the offsets of the flattest direction (largest entry 1 in
            units of ``max(|x|, 1)``).
        flattest_curvature: its curvature relative to the diagonal (0 flat, 1
            uncoupled; negative: the Hessian is not convex).
        convex: no curvature below ``−FLAT_RTOL`` of the largest (couplings given).
        stationary: the gradient is negligible at the interval scale (module doc).
        minimum: ``convex and stationary``: the couplings are tolerance ratios.
    """

    value: float
    threshold: float
    interval: dict[str, tuple[np.ndarray, np.ndarray]]
    open: dict[str, tuple[np.ndarray, np.ndarray]]
    gradient: dict[str, np.ndarray]
    hessian: np.ndarray
    labels: tuple[str, ...]
    coupling: dict[str, np.ndarray]
    flattest: dict[str, np.ndarray]
    flattest_curvature: float
    convex: bool
    stationary: bool

    @property
    def minimum(self) -> bool:
        return self.convex and self.stationary

    def table(self) -> str:
        """A plain-text table: entry, −tolerance, +tolerance, coupling (``≥`` where
        the search ended open)."""
        rows = [f"{'variable':<24}{'-tol':>12}{'+tol':>12}{'coupling':>10}"]
        k = 0
        for name, (below, above) in self.interval.items():
            opened = self.open[name]
            for i in np.ndindex(np.shape(below)):
                cells = [
                    ("≥" if opened[side][i] else "") + f"{bound[i]:.4g}"
                    for side, bound in enumerate((below, above))
                ]
                coupled = float(np.asarray(self.coupling[name])[i])
                rows.append(f"{self.labels[k]:<24}{cells[0]:>12}{cells[1]:>12}{coupled:>10.3g}")
                k += 1
        if not self.convex:
            rows.append(
                f"coupling: n/a, the metric is not convex here (curvature "
                f"{self.flattest_curvature:.3g} along `flattest`): no minimum"
            )
        elif not self.stationary:
            rows.append("coupling: curvature only, no minimum (the gradient dominates)")
        return "\n".join(rows)


def _flat_metric(x, template, robot, motion, metric):
    return _metric_at(ravel_pytree(template)[1](x), robot, motion, metric)


_hessian = jax.hessian(_flat_metric)


def tolerance(
    robot: Robot,
    motion: Motion | Callable[[Robot], Motion],
    metric: Metric = "rms_force",
    *,
    wrt=None,
    rise: float = 0.01,
    allowed: float | None = None,
    xtol: float = 1e-9,
    reach: float = 10.0,
) -> Tolerance:
    """Machining tolerances and couplings of a design (module doc).

    Args:
        robot: the design, e.g. ``codesign(...).robot``.
        motion: a :class:`~jaxbal.design.Motion`, or a callable ``robot -> Motion``
            re-planned with the design (as :func:`~jaxbal.sensitivity.sensitivity`).
        metric: a metric name (:data:`~jaxbal.design.METRICS`) or a callable
            ``(robot, motion) -> scalar``.
        wrt: design variable names (default: all of the robot's).
        rise: allowed relative rise of the metric (> 0).
        allowed: instead, the allowed absolute rise [the metric's unit] (> 0; needed
            where the metric is 0, e.g. a force-balanced robot's peak force).
        xtol: bisection tolerance, relative to ``max(|x|, 1)`` of each entry.
        reach: farthest search, in units of ``max(|x|, 1)`` of each entry.

    Raises:
        ValueError: an unknown metric or variable name, a non-positive or non-finite
            ``rise``/``allowed``/``xtol``/``reach``, a metric that is not finite at the
            design or 0 without ``allowed``, or a non-finite gradient or Hessian.
    """
    resolve_metric(metric)
    for name, number in (("rise", rise), ("xtol", xtol), ("reach", reach)):
        if not (np.isfinite(number) and number > 0):
            raise ValueError(f"{name} must be finite and > 0, got {number!r}")
    if allowed is not None and not (np.isfinite(allowed) and allowed > 0):
        raise ValueError(f"allowed must be finite and > 0 [metric unit], got {allowed!r}")
    design = robot.design()
    names = tuple(design) if wrt is None else check_design_names(robot, wrt)
    if not names:
        kind = type(robot).__name__
        raise ValueError(f"wrt names no design variable; {kind} has {sorted(design)}")
    # sorted: the order in which JAX flattens a dict (labels, Hessian rows and columns)
    chosen = {name: np.asarray(design[name], dtype=float) for name in sorted(names)}
    value, gradient = checked_call(_value_and_grad, chosen, robot, motion, metric)
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{metric!r} is not finite at the design: {value!r}")
    if allowed is None and value == 0.0:
        raise ValueError(f"{metric!r} is 0 at the design: give allowed= (an absolute rise)")
    threshold = value + allowed if allowed is not None else value * (1.0 + rise)
    x0, unravel = ravel_pytree(chosen)
    x0 = np.asarray(x0)
    g = np.asarray(ravel_pytree(gradient)[0])
    h = np.asarray(checked_call(_hessian, x0, chosen, robot, motion, metric))
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
        raise ValueError(f"gradient or Hessian of {metric!r} is not finite: {g!r}, {h!r}")
    h = 0.5 * (h + h.T)
    labels = _labels(chosen)
    below, above, open_below, open_above = _search(
        robot, motion, metric, chosen, x0, g, h, value, threshold, xtol, reach, unravel
    )
    coupling, flattest, curvature, convex = _coupling(h, x0)
    lower = np.asarray(ravel_pytree(_lower_bounds(robot, chosen))[0])
    at_lower = x0 - lower <= xtol * np.maximum(np.abs(x0), 1.0)
    first_order = np.abs(g) * np.maximum(below, above)
    pushed = at_lower & (g >= 0)
    stationary = np.all(pushed | (first_order <= STATIONARY_SHARE * (threshold - value)))

    def split(flat):  # (n,) -> name -> array of the variable's shape
        return {k: np.asarray(v) for k, v in unravel(flat).items()}

    flags = (open_below.astype(float), open_above.astype(float))
    lows, highs, opened_low, opened_high = (split(a) for a in (below, above, *flags))
    return Tolerance(
        value=value,
        threshold=float(threshold),
        interval={k: (lows[k], highs[k]) for k in lows},
        open={k: (opened_low[k] > 0.5, opened_high[k] > 0.5) for k in lows},
        gradient={k: np.asarray(v) for k, v in gradient.items()},
        hessian=h,
        labels=labels,
        coupling=split(coupling),
        flattest=split(flattest),
        flattest_curvature=curvature,
        convex=bool(convex),
        stationary=bool(stationary),
    )


def _labels(chosen) -> tuple[str, ...]:
    labels = []
    for name, x in chosen.items():
        if np.ndim(x) == 0:
            labels.append(name)
        else:
            labels += [f"{name}[{', '.join(map(str, i))}]" for i in np.ndindex(np.shape(x))]
    return tuple(labels)


def _search(robot, motion, metric, chosen, x0, g, h, value, threshold, xtol, reach, unravel):
    """Distances ``(n,)`` below and above each entry to the threshold (module doc)."""
    n = x0.size
    scale = np.maximum(np.abs(x0), 1.0)
    lower = ravel_pytree(_lower_bounds(robot, chosen))[0]
    limit = np.concatenate([np.minimum(x0 - np.asarray(lower), reach * scale), reach * scale])
    limit = np.maximum(limit, 0.0)
    sign = np.concatenate([-np.ones(n), np.ones(n)])
    slope, curve = np.concatenate([-g, g]), np.concatenate([np.diag(h), np.diag(h)])
    guess = _quadratic_step(slope, curve, threshold - value)
    usable = np.isfinite(guess) & (guess > 0)
    step = np.minimum(np.where(usable, guess, 1e-3 * np.tile(scale, 2)), limit)

    def within(steps):
        points = np.tile(x0, (2 * n, 1))
        points[np.arange(2 * n), np.tile(np.arange(n), 2)] += sign * steps
        batch = jax.vmap(unravel)(points)
        with runtime_checks(False):  # an invalid state is NaN: outside the interval
            values = np.asarray(_values_at(batch, robot, motion, metric))
        return values <= threshold  # NaN: False

    low, high = np.zeros(2 * n), np.full(2 * n, np.nan)
    for _ in range(200):  # expand: 2**200 covers any reach from any first step
        todo = np.isnan(high) & (low < limit)
        if not np.any(todo):
            break
        ok = within(np.where(todo, step, 0.0))
        low = np.where(todo & ok, step, low)
        high = np.where(todo & ~ok, step, high)
        step = np.where(todo & ok, np.minimum(2.0 * step, limit), step)
    opened = np.isnan(high)
    tol = xtol * np.tile(scale, 2)
    for _ in range(200):
        todo = ~opened & (high - low > tol)
        if not np.any(todo):
            break
        middle = 0.5 * (low + high)
        ok = within(np.where(todo, middle, 0.0))
        low = np.where(todo & ok, middle, low)
        high = np.where(todo & ~ok, middle, high)
    return low[:n], low[n:], opened[:n], opened[n:]


def _quadratic_step(slope, curve, rise):
    """Positive root of ``slope·δ + curve·δ²/2 = rise`` (NaN where there is none)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        quadratic = (-slope + np.sqrt(slope**2 + 2.0 * curve * rise)) / curve
        linear = rise / slope
    return np.where(np.abs(curve) > 0, quadratic, np.where(slope > 0, linear, np.nan))


def _lower_bounds(robot: Robot, chosen) -> dict[str, np.ndarray]:
    """The robot's own lower bounds of the chosen variables (``-inf`` where none)."""
    bounds = robot.design_lower_bounds()
    return {
        name: np.broadcast_to(np.asarray(bounds.get(name, -np.inf), dtype=float), np.shape(x))
        for name, x in chosen.items()
    }


def _coupling(h, x0):
    """Couplings ``(n,)``, the flattest direction ``(n,)``, its relative curvature and
    whether the Hessian is convex (module doc)."""
    diagonal = np.diag(h)
    top = np.max(np.abs(diagonal))
    live = diagonal > FLAT_RTOL * top  # the others: entries the metric hardly sees
    coupling = np.full(x0.size, np.nan)
    flattest = np.zeros(x0.size)
    if not np.any(live):
        return coupling, flattest, float("nan"), False
    # not convex: a negative diagonal, or a cross term of a dead entry that no PSD
    # matrix of these diagonals has (|H_ij|² ≤ H_ii H_jj)
    cross = np.abs(h[np.ix_(~live, live)]) ** 2 > FLAT_RTOL * top * diagonal[live][None, :]
    d = 1.0 / np.sqrt(diagonal[live])
    scaled = d[:, None] * h[np.ix_(live, live)] * d[None, :]
    curvatures, vectors = np.linalg.eigh(scaled)
    convex = curvatures[0] >= -FLAT_RTOL * curvatures[-1]
    convex &= not (np.any(diagonal < -FLAT_RTOL * top) or np.any(cross))
    flat = curvatures <= FLAT_RTOL * curvatures[-1]
    with np.errstate(divide="ignore"):
        inverse = np.sum(vectors[:, ~flat] ** 2 / curvatures[~flat], axis=1)
    touched = np.any(np.abs(vectors[:, flat]) > np.sqrt(FLAT_RTOL), axis=1)
    coupling[live] = np.where(touched, np.inf, np.sqrt(inverse)) if convex else np.nan
    direction = d * vectors[:, 0]
    scale = np.maximum(np.abs(x0[live]), 1.0)
    direction = direction / np.max(np.abs(direction) / scale)
    flattest[live] = direction * np.sign(direction[np.argmax(np.abs(direction))])
    return coupling, flattest, float(curvatures[0]), convex
