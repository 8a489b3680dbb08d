"""The result of a co-design (:func:`jaxbal.design.codesign`) and its assembly on the
host from an optimiser's final point."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxbal._src.design_loss import _combine_numpy, _everything, _to_design_numpy, _unflatten
from jaxbal._src.lbfgsb import projected_gradient
from jaxbal._src.metrics import metric_name
from jaxbal._src.robot import Robot
from jaxbal._src.types import Array, Scalar

__all__ = ["FEASIBILITY_RTOL", "DesignSolution"]

#: a constraint ``c ≤ b`` is reported satisfied when ``c ≤ b + FEASIBILITY_RTOL·σ``.
FEASIBILITY_RTOL = 1e-3


class DesignSolution(NamedTuple):
    """Result of :func:`codesign`.

    Attributes:
        design: every design variable of the optimised robot (name -> array, SI).
        robot: the optimised robot.
        value: final loss (dimensionless, see the module doc).
        initial_value: loss of the starting design.
        metrics: name -> ``(before, after)`` value of each objective and constraint
            metric [SI units].
        constraints: name -> ``(value, bound)`` after optimisation [SI units].
        feasible: every constraint satisfied (within :data:`FEASIBILITY_RTOL`).
        converged: the projected gradient reached ``gtol``, or the loss could not be
            lowered further (rounding); with ``optimizer=``, the gradient norm
            reached ``gtol``.
        steps: L-BFGS(-B) iterations done.
        grad_norm: final norm of the projected gradient in the design variables
            (with ``optimizer=``: of the gradient in the bound parameters ``r``).
        history: ``(max_steps,)`` loss at every iteration (NaN after stopping).
    """

    design: dict[str, Array]
    robot: Robot
    value: Scalar
    initial_value: Scalar
    metrics: dict[str, tuple[Scalar, Scalar]]
    constraints: dict[str, tuple[Scalar, Scalar]]
    feasible: Array
    converged: Array
    steps: Array
    grad_norm: Scalar
    history: Array


def _solution(robot, result, after, before, problem, layout, lower, upper) -> DesignSolution:
    """The :class:`DesignSolution` of an optimiser's ``result`` (the final point ``x``,
    loss, gradient, steps, convergence and history) with the metric values ``after``
    at that point and ``before`` at the start, on the host."""
    # on the host: compiling `_designed` cost more than the whole L-BFGS run after the
    # first evaluation (DUAL-V 0.14 s, 10-link arm 0.06 s; eagerly 0.08 s and 1 ms)
    optimised = robot.with_design(_to_design_numpy(_unflatten(result.x, layout), problem))
    everything = _everything(problem)
    labels = [metric_name(m) for m in everything]
    n = len(problem.terms)
    where = np.asarray([everything.index(m) for m in problem.constrained], dtype=int)
    after = np.asarray(after)
    bounds, bound_scales = np.asarray(problem.bounds), np.asarray(problem.bound_scales)
    excess = after[where] - bounds
    return DesignSolution(
        design=optimised.design(),
        robot=optimised,
        value=np.asarray(result.value),
        initial_value=np.asarray(_combine_numpy(before[:n], before[where], problem)),
        metrics={name: (before[i], after[i]) for i, name in enumerate(labels)},
        constraints={
            metric_name(m): (after[i], bounds[k])
            for k, (m, i) in enumerate(zip(problem.constrained, where, strict=True))
        },
        feasible=np.all(excess <= FEASIBILITY_RTOL * bound_scales),
        converged=np.asarray(result.converged),
        steps=np.asarray(result.steps),
        grad_norm=np.asarray(
            np.linalg.norm(projected_gradient(result.x, result.grad, lower, upper))
        ),
        history=result.history,
    )
