"""Pareto fronts of two metrics by warm-started weighted-sum continuation.

:func:`pareto_front` minimises ``(1 − w) a/s_a + w b/s_b`` (squared, as in
:mod:`jaxbal._src.design`) for a sequence of weights ``w``, each solve starting from the
previous optimum (continuation), with fixed scales ``s`` so that every point solves the
same problem family: the weights are array leaves, so the L-BFGS loop is compiled once.
The end points ``w = 0`` and ``w = 1`` are the single-objective optima.

A weighted-sum optimum cannot be dominated by another feasible design: the dominating
design has a lower loss at that weight. A dominated point therefore means that its solve
stopped in a worse local optimum (peaks are non-smooth); ``repair`` passes re-solve
every dominated point starting from the design that dominates it and keep the result
if its loss is lower. Points still dominated afterwards are flagged by
:func:`nondominated` (``ParetoFront.efficient``), never hidden. Repair is tried for
dominance beyond ``CONSTRAINT_RTOL`` (1e-6, relative), the accuracy the solves are
held to; a point is reported dominated beyond :data:`DOMINANCE_RTOL` (1e-5): solves
that land on the same bound-active design a few 1e-6 apart are a tie.

References:
    Miettinen (1999), Nonlinear Multiobjective Optimization, §3.1 (weighting method).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxbal._src.joint_codesign import CONSTRAINT_RTOL, _floors, joint_codesign, payload_metrics
from jaxbal._src.metrics import metric_name
from jaxbal._src.payload_aggregate import aggregate_numpy
from jaxbal._src.types import Array

#: a front point is reported dominated (``ParetoFront.efficient`` False) only beyond
#: this fraction of the two values compared (:func:`dominance`): ten times the accuracy
#: constraints are held to (``CONSTRAINT_RTOL``), so two solves landing on the same
#: bound-active design (4.9999936 and 5.0000002 kg for a 5 kg budget) are a tie. The
#: repair passes re-solve every point dominated beyond ``CONSTRAINT_RTOL`` already.
DOMINANCE_RTOL = 10 * CONSTRAINT_RTOL

__all__ = [
    "DOMINANCE_RTOL",
    "ParetoFront",
    "constraint_excess",
    "dominance",
    "nondominated",
    "pareto_front",
    "plot_front",
]


class ParetoFront(NamedTuple):
    """Result of :func:`pareto_front`.

    Attributes:
        weights: ``(n,)`` weight ``w`` of the second metric.
        values: ``(n, 2)`` aggregated metric values [SI] (``JointSolution.metrics``: for
            ``robust="max"`` the worst payload, not the loss's smooth maximum).
        solutions: the :class:`~jaxbal.design.JointSolution` of every weight.
        efficient: ``(n,)`` True where no other point of the front dominates it.
        feasible: ``(n,)`` every constraint satisfied.
    """

    weights: Array
    values: Array
    solutions: list
    efficient: Array
    feasible: Array


def nondominated(values, rtol: float = 1e-9) -> np.ndarray:
    """``(n,)`` mask of the points of ``values`` ``(n, k)`` (minimised) that no other
    point dominates (:func:`dominance`)."""
    return ~np.any(dominance(values, rtol), axis=0)


def dominance(values, rtol: float = 1e-9) -> np.ndarray:
    """``(n, n)`` matrix ``D[j, i]``: point ``j`` of ``values`` ``(n, k)`` (minimised)
    dominates point ``i``: no worse on every metric and better on one, each beyond
    ``rtol`` times the larger magnitude of the two values compared."""
    values = np.asarray(values, dtype=float)
    u, v = values[:, None, :], values[None, :, :]
    slack = rtol * np.maximum(np.maximum(np.abs(u), np.abs(v)), 1e-300)
    no_worse = np.all(u <= v + slack, axis=-1)
    better = np.any(u < v - slack, axis=-1)
    return no_worse & better


def _checked_front(metrics, weights) -> tuple[tuple, np.ndarray]:
    """``(a, b)`` and the weights ``(n,)``, or ``ValueError``: two different metrics
    (one metric twice was a single objective whose ``w = 0`` point was the start), and
    at least one weight, each in ``[0, 1]``, increasing."""
    metrics = tuple(metrics)
    if len(metrics) != 2 or metric_name(metrics[0]) == metric_name(metrics[1]):
        names = [metric_name(m) for m in metrics]
        raise ValueError(f"metrics must be two different metrics (a, b), got {names}")
    values = np.asarray(weights, dtype=float)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"weights must be a sequence of at least one w in [0, 1], got {weights!r}")
    if not (np.all(np.isfinite(values)) and np.all((values >= 0) & (values <= 1))):
        raise ValueError(f"every weight w of b must lie in [0, 1], got {values.tolist()}")
    if np.any(np.diff(values) <= 0):
        raise ValueError(f"weights must increase (each point starts from the one before), "
                         f"got {values.tolist()}")  # fmt: skip
    return metrics, values


def _scales(robot, motion, trajectory, metrics, options) -> dict[str, float]:
    """Fixed scale of each metric along the front: its worst (``robust="max"``), mean or
    quadratic mean value over the payloads at the start, floored as in :func:`joint_codesign`."""
    payloads = options.get("payloads")
    if payloads is None:
        payloads = jnp.atleast_1d(robot.design().get("payload", jnp.zeros(())))
    theta = {k: jnp.asarray(v, float) for k, v in trajectory.items()}
    values = np.asarray(payload_metrics(robot, motion, theta, payloads, tuple(metrics)))
    values = aggregate_numpy(values, options.get("robust", "mean"))
    floors = np.asarray(_floors(robot, motion, theta, tuple(metrics)))
    scales = np.maximum(np.abs(values), floors)
    return {metric_name(m): float(x) for m, x in zip(metrics, scales, strict=True)}


def pareto_front(
    robot,
    motion,
    trajectory,
    metrics: tuple,
    weights,
    *,
    start=None,
    repair: int = 2,
    **options,
) -> ParetoFront:
    """Front between ``metrics = (a, b)`` of :func:`~jaxbal.design.joint_codesign`.

    Args:
        robot, motion, trajectory: as :func:`~jaxbal.design.joint_codesign`.
        metrics: the two metrics ``(a, b)``.
        weights: increasing weights ``w ∈ [0, 1]`` of ``b`` (at least one).
        start: starting design of the first solve.
        repair: passes that re-solve each dominated point from a dominating one.
        **options: passed on (bounds, ``free``, ``payloads``, ``robust``, constraints…);
            ``scales`` (by metric name) replaces the scale taken at the start.

    Returns:
        A :class:`ParetoFront` (the solution at ``w`` starts from the one before).
    """
    metrics, weights = _checked_front(metrics, weights)
    a, b = metrics
    given = options.pop("scales", None)
    scales = _scales(robot.with_design(dict(start or {})), motion, trajectory, metrics, options)
    scales.update({metric_name(m): float(given[metric_name(m)])
                   for m in metrics if metric_name(m) in (given or {})})  # fmt: skip
    free = options.pop("free", None)
    names = free if free is not None else [n for n in robot.design() if n != "payload"]

    def solve(w, design, theta):
        return joint_codesign(
            robot, motion, theta, {a: 1.0 - w, b: w}, start=design, free=free,
            scales=scales, **options,
        )  # fmt: skip

    def start_of(solution):
        return {n: solution.design[n] for n in names}, solution.trajectory

    def front_values(solutions):
        return np.asarray(
            [[s.metrics[metric_name(m)][1] for m in metrics] for s in solutions], dtype=float
        )

    solutions, design, theta = [], start or {}, dict(trajectory)
    for w in weights:
        solutions.append(solve(w, design, theta))
        design, theta = start_of(solutions[-1])
    for _ in range(repair):
        values = front_values(solutions)
        matrix = dominance(values, CONSTRAINT_RTOL)
        dominated = np.flatnonzero(np.any(matrix, axis=0))
        if dominated.size == 0:
            break
        for i in dominated:
            # the dominating point with the lowest loss at weight i is the best start
            dominating = np.flatnonzero(matrix[:, i])
            w, scale = weights[i], np.asarray([scales[metric_name(m)] for m in metrics])
            losses = ((values[dominating] / scale) ** 2) @ np.asarray([1.0 - w, w])
            candidate = solve(w, *start_of(solutions[dominating[int(np.argmin(losses))]]))
            if float(candidate.value) < float(solutions[i].value):
                solutions[i] = candidate
    values = jnp.asarray(front_values(solutions))
    return ParetoFront(
        weights=jnp.asarray(weights),
        values=values,
        solutions=solutions,
        efficient=jnp.asarray(nondominated(values, DOMINANCE_RTOL)),
        feasible=jnp.asarray([bool(s.feasible) for s in solutions]),
    )


def constraint_excess(solution) -> float:
    """Largest constraint violation of a :class:`~jaxbal.design.JointSolution` at its
    worst payload, relative to the bound's magnitude (≤ 0: every constraint met)."""
    excess = [(value - bound) / abs(bound) for value, bound in solution.constraints.values()]
    return max((float(x) for x in excess), default=float("-inf"))


def plot_front(axis, front: ParetoFront, labels=("a", "b"), marks=None):
    """Draw ``front`` on a Matplotlib ``axis``: metric b across, metric a up; dominated
    points left out. ``marks``: ``{label: (b, a)}`` designs to mark (e.g. a paper's)."""
    values = np.asarray(front.values)[np.asarray(front.efficient)]
    axis.plot(values[:, 1], values[:, 0], "o-", color="k", ms=3, label="front")
    for (label, (x, y)), style in zip((marks or {}).items(), ("r*", "bs", "g^", "mD", "c>"),
                                      strict=False):  # fmt: skip
        axis.plot([x], [y], style, ms=8, label=label)
    axis.set(xlabel=labels[1], ylabel=labels[0])
    axis.legend(fontsize=6)
