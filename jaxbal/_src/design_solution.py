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

__all__ = ["AT_BOUND_RTOL", "FEASIBILITY_RTOL", "DesignSolution", "bound_contacts"]

#: a constraint ``c ≤ b`` is reported satisfied when ``c ≤ b + FEASIBILITY_RTOL·σ``.
FEASIBILITY_RTOL = 1e-3

#: a variable is reported at a bound within this fraction of its range (two-sided
#: bounds) or of ``max(1, |bound|)`` SI units (a lower bound alone): e.g. 1 mg for a
#: mass bounded below by 0 kg, 10 µm for a position bounded below by −10 m.
AT_BOUND_RTOL = 1e-6


def bound_contacts(values, free, lower, upper, two_sided) -> dict[str, np.ndarray]:
    """Which entries of the optimised variables sit on a bound.

    Args:
        values: name -> optimised value (array, SI units).
        free, lower, upper, two_sided: the variables' names, their bounds (arrays of
            their shapes) and whether each has an upper bound (as in the co-design
            problem).

    Returns:
        name -> integer array of the variable's shape: ``-1`` on the lower bound,
        ``+1`` on the upper bound, ``0`` inside (within :data:`AT_BOUND_RTOL`).
    """
    contacts = {}
    for name, lo, hi, two in zip(free, lower, upper, two_sided, strict=True):
        x, lo, hi = (np.asarray(a, dtype=float) for a in (values[name], lo, hi))
        scale = (hi - lo) if two else np.maximum(1.0, np.abs(lo))
        tolerance = AT_BOUND_RTOL * scale
        side = np.where(x - lo <= tolerance, -1, 0)
        if two:
            side = np.where(hi - x <= tolerance, 1, side)
        contacts[name] = side.astype(np.int8)
    return contacts


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
        at_bound: free variable name -> ``int8`` array of its shape: ``-1`` where the
            optimum lies on the lower bound, ``+1`` on the upper bound, ``0`` inside
            (:func:`bound_contacts`). A counter-mass at 0 kg was removed; a position
            on its bound means the bound, not the physics, stopped the optimiser:
            widen it (``lower=``/``upper=``) or accept the compromise.
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
    at_bound: dict[str, np.ndarray]


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
        at_bound=_contacts(optimised, problem),
    )


def _contacts(optimised: Robot, problem) -> dict[str, np.ndarray]:
    """:func:`bound_contacts` of the free variables of ``optimised``."""
    design = optimised.design()
    return bound_contacts(design, problem.free, problem.lower, problem.upper, problem.two_sided)
