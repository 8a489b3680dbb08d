"""Pareto fronts of two metrics by warm-started weighted-sum continuation.

:func:`pareto_front` minimises ``(1 − w) a/s_a + w b/s_b`` (squared, as in
:mod:`jaxbal._src.design`) for a sequence of weights ``w``, each solve starting from the
previous optimum (continuation), with fixed scales ``s`` so that every point solves the
same problem family: the weights are array leaves, so the L-BFGS loop is compiled once.
The end points ``w = 0`` and ``w = 1`` are the single-objective optima; dominated
points (possible with a non-convex front) are flagged by :func:`nondominated`.

References:
    Miettinen (1999), Nonlinear Multiobjective Optimization, §3.1 (weighting method).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxbal._src.joint_codesign import joint_codesign
from jaxbal._src.metrics import metric_name
from jaxbal._src.types import Array

__all__ = ["ParetoFront", "nondominated", "pareto_front"]


class ParetoFront(NamedTuple):
    """Result of :func:`pareto_front`.

    Attributes:
        weights: ``(n,)`` weight ``w`` of the second metric.
        values: ``(n, 2)`` aggregated metric values [SI].
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
    point dominates (better or equal on all, better on one, beyond ``rtol``)."""
    values = np.asarray(values, dtype=float)
    slack = rtol * np.maximum(np.abs(values).max(axis=0), 1e-300)
    mask = np.ones(len(values), dtype=bool)
    for i, v in enumerate(values):
        no_worse = np.all(values <= v + slack, axis=1)
        better = np.any(values < v - slack, axis=1)
        mask[i] = not np.any(no_worse & better)
    return mask


def pareto_front(
    robot,
    motion,
    trajectory,
    metrics: tuple,
    weights,
    *,
    start=None,
    **options,
) -> ParetoFront:
    """Front between ``metrics = (a, b)`` of :func:`~jaxbal.design.joint_codesign`.

    Args:
        robot, motion, trajectory: as :func:`~jaxbal.design.joint_codesign`.
        metrics: the two metrics ``(a, b)``.
        weights: increasing weights ``w ∈ [0, 1]`` of ``b``.
        start: starting design of the first solve.
        **options: passed on (bounds, ``free``, ``payloads``, ``robust``, constraints…).

    Returns:
        A :class:`ParetoFront` (the solution at ``w`` starts from the one before).
    """
    a, b = metrics
    weights = np.asarray(weights, dtype=float)
    first = joint_codesign(robot, motion, trajectory, {a: 1.0, b: 0.0}, start=start, **options)
    scales = {metric_name(m): float(first.metrics[metric_name(m)][0]) for m in metrics}
    free = options.pop("free", None)
    names = free if free is not None else [n for n in robot.design() if n != "payload"]
    solutions, design, theta = [], start or {}, dict(trajectory)
    for w in weights:
        solution = joint_codesign(
            robot, motion, theta, {a: 1.0 - w, b: w}, start=design, free=free,
            scales=scales, **options,
        )  # fmt: skip
        solutions.append(solution)
        design = {n: solution.design[n] for n in names}
        theta = solution.trajectory
    values = jnp.asarray(
        [[s.metrics[metric_name(m)][1] for m in metrics] for s in solutions], dtype=float
    )
    return ParetoFront(
        weights=jnp.asarray(weights),
        values=values,
        solutions=solutions,
        efficient=jnp.asarray(nondominated(values)),
        feasible=jnp.asarray([bool(s.feasible) for s in solutions]),
    )
