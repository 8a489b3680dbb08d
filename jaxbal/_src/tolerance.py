"""How tightly a design pins its metric down: machining tolerances and flat directions.

Before a counter-mass is machined, a user needs to know two things about an optimised
design that its gradient alone does not tell:

* **Tolerance.** By how much may each design variable alone be off (a counter-mass
  machined 20 g heavy, a distance 1 mm short) before the metric (e.g. the RMS shaking
  force) rises by ``rise`` (default 1 %)? Found on the metric itself, not on a model:
  along each variable, in both directions, steps double from the quadratic estimate
  until the metric exceeds ``threshold = value + rise·|value|`` (or ``value +
  allowed``), then bisection to ``xtol`` (:mod:`~jaxbal._src.tolerance_search`). A
  variable's own bound (a mass at 0 kg), the search reach or an invalid design (an
  unreachable pose) can end the search first: ``ends`` says which.
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

from jaxbal._src.design_inputs import check_positive_number
from jaxbal._src.metrics import Metric, Motion, check_design_names, resolve_metric
from jaxbal._src.robot import Robot
from jaxbal._src.sensitivity import _metric_at, _value_and_grad
from jaxbal._src.tolerance_search import ENDS, lower_bounds, search
from jaxbal._src.validation import checked_call

__all__ = ["FLAT_RTOL", "STATIONARY_SHARE", "ZERO_METRIC", "Tolerance", "tolerance"]

#: a curvature of ``D^-½ H D^-½`` below this (relative to its largest) counts as flat:
#: the couplings of the entries along it are ``inf``.
FLAT_RTOL = 1e-9
#: a design is stationary when, for every entry off its lower bound, the gradient's
#: first-order change over the tolerance interval is at most this share of the rise.
STATIONARY_SHARE = 0.1
#: a metric at most this [its SI unit: N, N·m, …] is zero up to rounding (a balanced
#: 2R's RMS force is ~1e-11 N): a relative rise of it means nothing, give ``allowed=``.
ZERO_METRIC = 1e-9


class Tolerance(NamedTuple):
    """Result of :func:`tolerance` (offsets and tolerances in the variables' SI units).

    Attributes:
        value: the metric at the design [its SI unit].
        threshold: the metric each interval end reaches, ``value + rise·|value|`` or
            ``value + allowed``.
        interval: name -> ``(below, above)``, arrays of the variable's shape: the entry
            alone may move by ``−below … +above`` with the metric at most ``threshold``
            (at the ``1 + SCAN`` points of each side checked; a rise narrower than their
            spacing can still hide between them).
        ends: name -> ``(below, above)`` arrays of :data:`ENDS` strings: why each side
            ended.
        open: name -> ``(below, above)`` booleans, ``ends != "rise"``: the tolerance
            is at least the interval (bound, reach) or limited by validity.
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
    ends: dict[str, tuple[np.ndarray, np.ndarray]]
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
        """A plain-text table: entry, −tolerance, +tolerance, coupling; an open side is
        marked ``≥`` and a letter: ``b`` bound, ``r`` reach, ``x`` invalid beyond."""
        rows = [f"{'variable':<24}{'-tol':>13}{'+tol':>13}{'coupling':>10}"]
        mark = {"rise": "", "bound": " b", "reach": " r", "invalid": " x"}
        k = 0
        for name, (below, above) in self.interval.items():
            ends = self.ends[name]
            for i in np.ndindex(np.shape(below)):
                cells = [
                    ("" if ends[side][i] == "rise" else "≥")
                    + f"{bound[i]:.4g}"
                    + mark[ends[side][i]]
                    for side, bound in enumerate((below, above))
                ]
                coupled = float(np.asarray(self.coupling[name])[i])
                rows.append(f"{self.labels[k]:<24}{cells[0]:>13}{cells[1]:>13}{coupled:>10.3g}")
                k += 1
        if abs(self.value) <= ZERO_METRIC:
            rows.append("coupling: n/a, the metric vanishes here (not smooth at its zero)")
        elif not self.convex:
            rows.append(
                "coupling: n/a, the Hessian is not convex here (a negative curvature, or a "
                "cross term of an entry it hardly sees): no minimum"
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
    rise: float | None = None,
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
        rise: allowed rise of the metric relative to ``|value|`` (> 0; default 0.01).
        allowed: instead, the allowed absolute rise [the metric's unit] (> 0; needed
            where the metric is zero up to rounding, :data:`ZERO_METRIC`, e.g. a
            force-balanced robot's force).
        xtol: bisection tolerance, relative to ``max(|x|, 1)`` of each entry.
        reach: farthest search, in units of ``max(|x|, 1)`` of each entry.

    Raises:
        ValueError: an unknown metric or variable name, a ``rise``/``allowed``/
            ``xtol``/``reach`` that is not a finite number > 0, both ``rise`` and
            ``allowed``, a metric that is not finite at the design or zero up to
            rounding without ``allowed``, or a non-finite gradient or Hessian.
    """
    resolve_metric(metric)
    if rise is not None and allowed is not None:
        raise ValueError(
            f"give rise= (relative) or allowed= (absolute), not both: {rise}, {allowed}"
        )
    numbers = {"rise": rise, "allowed": allowed, "xtol": xtol, "reach": reach}
    for name, number in numbers.items():
        if number is not None:
            check_positive_number(name, number)
    rise = 0.01 if rise is None and allowed is None else rise
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
    if allowed is None and abs(value) <= ZERO_METRIC:
        raise ValueError(
            f"{metric!r} is {value!r} at the design, zero up to rounding: a relative rise "
            "of it means nothing; give allowed= (an absolute rise in the metric's unit)"
        )
    threshold = value + allowed if allowed is not None else value + rise * abs(value)
    x0, unravel = ravel_pytree(chosen)
    x0 = np.asarray(x0)
    g = np.asarray(ravel_pytree(gradient)[0])
    h = np.asarray(checked_call(_hessian, x0, chosen, robot, motion, metric))
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
        raise ValueError(f"gradient or Hessian of {metric!r} is not finite: {g!r}, {h!r}")
    h = 0.5 * (h + h.T)
    labels = _labels(chosen)
    low, ends = search(
        robot, motion, metric, chosen, x0, g, h, value, threshold, xtol, reach, unravel
    )
    n = x0.size
    below, above = low[:n], low[n:]
    coupling, flattest, curvature, convex = _coupling(h, x0)
    if abs(value) <= ZERO_METRIC:  # a norm at its zero: no Hessian describes it
        coupling = np.full(n, np.nan)
    lower = np.asarray(ravel_pytree(lower_bounds(robot, chosen))[0])
    at_lower = x0 - lower <= xtol * np.maximum(np.abs(x0), 1.0)
    first_order = np.abs(g) * np.maximum(below, above)
    pushed = at_lower & (g >= 0)
    stationary = np.all(pushed | (first_order <= STATIONARY_SHARE * (threshold - value)))

    def split(flat):  # (n,) -> name -> array of the variable's shape
        return {k: np.asarray(v) for k, v in unravel(flat).items()}

    lows, highs = split(below), split(above)
    codes = np.asarray([ENDS.index(e) for e in ends], dtype=float)
    low_codes, high_codes = split(codes[:n]), split(codes[n:])

    def named(code):
        return np.asarray(ENDS, dtype=object)[np.asarray(code, dtype=int)]

    end_names = {k: (named(low_codes[k]), named(high_codes[k])) for k in lows}
    return Tolerance(
        value=value,
        threshold=float(threshold),
        interval={k: (lows[k], highs[k]) for k in lows},
        ends=end_names,
        open={k: (v[0] != "rise", v[1] != "rise") for k, v in end_names.items()},
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
