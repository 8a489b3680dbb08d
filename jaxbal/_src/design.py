"""Counter-mass co-design of any robot: optimise its design variables for a fixed motion.

:func:`codesign` minimises a weighted sum of metrics (:mod:`jaxbal._src.metrics`) over
the robot's named design variables (:meth:`jaxbal.Robot.design`) with a bound-constrained
quasi-Newton method (by default :mod:`jaxbal._src.host_bfgs`, L-BFGS-B's iteration with
a dense BFGS matrix, up to 64 variables, and SciPy's L-BFGS-B, :mod:`jaxbal._src.lbfgsb`,
above), or an optax optimiser in :func:`jaxbal.minimize`. The joint motion is *held
fixed* (sequential design, as in the papers: counter-masses do not change the inverse
kinematics).

**Loss.** With metric values ``v_i``, weights ``w_i`` and scales ``s_i``::

    loss = Σ_i w_i (v_i / s_i)²  +  P Σ_j max(0, (c_j − b_j) / σ_j)²

``s_i`` is the value of metric ``i`` for the starting robot, floored (an added mass or
inertia that starts at zero is scaled by the bare robot's total mass or base inertia;
any other metric by ``1e-12`` SI units), so every term is dimensionless. The terms are
*squared* so that a metric that can reach zero (the RMS force of a robot that can be
fully force-balanced) is smooth there; with one term the loss has the same minimiser
as the metric itself. The optional constraints ``c_j ≤ b_j`` are a quadratic penalty
of weight ``P = penalty`` (default :data:`CONSTRAINT_PENALTY`), scaled by ``σ_j`` =
``|b_j|`` floored as above; a penalty is inexact, so a constraint counts as satisfied
within the relative tolerance :data:`FEASIBILITY_RTOL`.

**Bounds.** The default optimisers hold them themselves (projected steps) and optimise the
design variables directly, so a loss quadratic in them (RMS force, added mass and
inertia of counter-masses) stays quadratic (2–4× fewer evaluations than the bound map
below, measured in ``benchmarks/codesign_bench.py``). An optax optimiser is
unconstrained, so with ``optimizer=`` the bounds are a smooth reparametrisation:
``x = lower + r²`` below only and ``x = lower + (upper − lower) sin² r`` with both.
Either way the start is moved :data:`START_OFFSET` inside the lower bound (SI units,
i.e. 0.1 g or 0.1 mm) and, for two-sided bounds, that fraction of the range inside both
ends: ``r = 0`` is a stationary point of ``r²`` (and of ``sin² r``), and a design whose
counter-masses and distances all start at zero is a saddle of the force (the products
``m·d`` have a zero gradient there). The optimiser may still reach a bound exactly. A
start a rounding error outside a bound (a solution's design read back from its robot)
is clipped onto it.

**Compilation.** The loss is a module-level function of ``(params, robot, motion,
problem)``; names, metric choices and bound kinds are static fields of ``problem``, all
numbers are array leaves. By default the only compiled program is the loss's value and
gradient (with the metric values, the scale floors and a validity mask of the given
robot and motion): the host-driven optimiser (:mod:`jaxbal._src.host_bfgs`) calls it
once per evaluation, so the first co-design of a process compiles one copy of the dynamics, and
the program, free of runtime-error callbacks, is kept by the persistent compilation
cache for the next process. Along a reduced motion (``reduce=``: the metrics from the
wrench regressor, :mod:`jaxbal._src.reduced_motion`) with at most
:data:`~jaxbal._src.design_compiled.COMPILED_MAX_VARIABLES` scalar variables, each
evaluation costs microseconds, so the host round trips would dominate: there the whole
co-design (scales, a projected BFGS loop, :mod:`jaxbal._src.box_bfgs`, and the final
metric values) is one compiled program, dispatched once
(:mod:`jaxbal._src.design_compiled`). An invalid robot or motion (e.g. a negative mass set with
``eqx.tree_at``) is raised eagerly, with the names of the offending values. With
``optimizer=`` an optax transformation, the whole loop is compiled
(:func:`jaxbal.minimize`). Either way a second call on a robot of the same structure,
with a motion of the same length and the same metric objects, reuses the compiled code
(different payloads, masses, weights, bounds or motions do not retrace). A metric given
as a callable is part of the compiled structure: define it once, at module level.

References:
    Arakelian & Briot (2008), eqs (1)-(3) (the force-balanced SCARA this recovers);
    Briot, Arakelian & Le Baron (2012), §3.3 (counterweights of the 2R and 3R);
    Liu & Nocedal (1989), L-BFGS.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.design_compiled import COMPILED_MAX_VARIABLES, compiled_function
from jaxbal._src.design_inputs import check_constraints, check_penalty, starts_inside
from jaxbal._src.design_loss import (
    SCALE_FLOOR,
    START_OFFSET,
    _bounds,
    _combine_numpy,
    _designed,
    _evaluate,
    _everything,
    _objective_terms,
    _Problem,
    _raise_invalid_start,
    _to_params,
    design_loss,
    loss_grad_function,
)
from jaxbal._src.design_solution import (
    AT_BOUND_RTOL,
    FEASIBILITY_RTOL,
    DesignSolution,
    _contacts,
    _solution,
)
from jaxbal._src.host_bfgs import HOST_MAX_VARIABLES, host_bfgs
from jaxbal._src.lbfgsb import lbfgsb
from jaxbal._src.loop_checks import check_samples_eagerly
from jaxbal._src.metrics import (
    Metric,
    as_motion,
    check_design_names,
    finite_array,
    metric_name,
)
from jaxbal._src.motion_samples import ReducedMotion, check_motion_shape
from jaxbal._src.optimize import minimize
from jaxbal._src.reduced_motion import REDUCE_MIN_VARIABLES, reduce_motion, reduces
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_robot
from jaxbal._src.validation import check_stopping, runtime_checks

__all__ = [
    "AT_BOUND_RTOL",
    "CONSTRAINT_PENALTY",
    "FEASIBILITY_RTOL",
    "REDUCE_MIN_VARIABLES",
    "START_OFFSET",
    "DesignSolution",
    "codesign",
]

#: default weight ``P`` of the quadratic constraint penalty (dimensionless).
CONSTRAINT_PENALTY = 1e4


def _codesign_compact(robot, motion, x0, problem: _Problem, max_steps, gtol, reduce):
    """:func:`codesign` with the default optimiser: the host-driven BFGS of
    :mod:`jaxbal._src.host_bfgs` (above :data:`~jaxbal._src.host_bfgs.HOST_MAX_VARIABLES`
    variables SciPy's L-BFGS-B) around one compiled program (:func:`_loss_grad`), in the
    design variables themselves (``problem.mapped`` False); along a reduced motion with
    few variables, the compiled BFGS loop of :mod:`jaxbal._src.design_compiled`."""
    params = _to_params(x0, problem)
    layout = tuple((name, tuple(np.shape(params[name]))) for name in problem.free)
    x_start = np.concatenate([np.ravel(np.asarray(params[n], dtype=float)) for n in problem.free])
    everything = _everything(problem)
    labels = [metric_name(m) for m in everything]
    # the starting design as given: its metric values set the scales (module doc)
    check_robot(robot)  # an invalid robot is refused before the program compiles
    if reduces(reduce, x_start.size, motion):
        motion = reduce_motion(robot, motion, problem.free, everything) or motion
    lower = np.concatenate([np.ravel(np.asarray(lo, dtype=float)) for lo in problem.lower])
    upper = np.concatenate(
        [
            np.ravel(np.asarray(hi, dtype=float)) if two else np.full(np.size(hi), np.inf)
            for hi, two in zip(problem.upper, problem.two_sided, strict=True)
        ]
    )
    if isinstance(motion, ReducedMotion) and x_start.size <= COMPILED_MAX_VARIABLES:
        run = compiled_function(robot, motion, problem, layout, max_steps)
        given = np.concatenate(
            [np.ravel(np.asarray(x0[name], dtype=float)) for name in problem.free]
        )
        result = jax.tree_util.tree_map(np.asarray, run(x_start, given, lower, upper, gtol))
        before, scales, bound_scales = result.context
        if not np.all(np.isfinite(before)):
            _raise_invalid_start(motion, labels, before)
        problem = eqx.tree_at(lambda p: (p.scales, p.bound_scales), problem, (scales, bound_scales))
        return _solution(robot, result, result.aux, before, problem, layout, lower, upper)
    n = len(problem.terms)
    where = np.asarray([everything.index(m) for m in problem.constrained], dtype=int)
    loss_grad = loss_grad_function(robot, motion, problem, layout)
    _, _, before, floors = loss_grad(x_start, np.asarray(True))
    before, floors = np.asarray(before), np.asarray(floors)
    finite_motion = all(np.all(np.isfinite(np.asarray(part))) for part in motion)
    if not finite_motion or not np.all(np.isfinite(before)):
        _raise_invalid_start(motion, labels, before)
    scales = np.maximum(np.abs(before[:n]), floors[:n])
    bound_scales = np.maximum(np.abs(np.asarray(problem.bounds)), floors[where])
    problem = eqx.tree_at(
        lambda p: (p.scales, p.bound_scales),
        problem,
        (jnp.asarray(scales), jnp.asarray(bound_scales)),
    )
    loss_grad = loss_grad_function(robot, motion, problem, layout)
    at_start = np.asarray(False)

    def evaluate(x):
        loss, grad, values, _ = loss_grad(x, at_start)
        return float(loss), np.asarray(grad), values

    # a dense BFGS in NumPy for a few variables (no SciPy import: host_bfgs's doc)
    optimise = host_bfgs if x_start.size <= HOST_MAX_VARIABLES else lbfgsb
    result = optimise(evaluate, x_start, lower, upper, max_steps=max_steps, gtol=gtol)
    return _solution(robot, result, result.aux, before, problem, layout, lower, upper)


def codesign(
    robot: Robot,
    motions,
    objective: Metric | Mapping[Metric, float] = "rms_force",
    *,
    free=None,
    lower: Mapping[str, Any] | None = None,
    upper: Mapping[str, Any] | None = None,
    start: Mapping[str, Any] | None = None,
    max_steps: int = 200,
    gtol: float = 1e-10,
    optimizer=None,
    constraints: Mapping[Metric, float] | None = None,
    penalty: float = CONSTRAINT_PENALTY,
    reduce: bool | None = None,
) -> DesignSolution:
    """Optimal design variables of ``robot`` for a fixed motion (see the module doc).

    Args:
        robot: any :class:`~jaxbal.Robot`.
        motions: a :class:`~jaxbal.design.Motion` (e.g. from
            :func:`~jaxbal.design.motion_samples`), a ``(q, q̇, q̈)`` tuple, or a list
            of them (several trajectories, concatenated in time).
        objective: a metric name (:data:`~jaxbal.design.METRICS`), a callable
            ``(robot, motion) -> scalar``, or a dict ``{metric: weight}`` (a weight of
            0 only reports the metric in ``metrics``). Peaks are maxima over time, not
            smooth: L-BFGS lowers them but may stop unconverged; RMS metrics are smooth.
        free: names of the design variables to optimise; default all but ``payload``.
        lower: lower bounds by name (scalar or the variable's shape), overriding
            :meth:`~jaxbal.Robot.design_lower_bounds` (masses and distances: 0).
        upper: optional upper bounds by name (the others are unbounded above).
        start: starting values by name (default: the robot's); any design variable
            may be given, the non-free ones are simply set.
        max_steps: quasi-Newton iteration cap.
        gtol: stop when the projected gradient of the loss (largest component; with
            ``optimizer=``, the gradient norm) falls below this.
        optimizer: ``None`` (default): a bound-constrained BFGS (L-BFGS-B above 64
            variables) driven from the host around one compiled value-and-gradient
            (fast first call, see the module doc), or along a reduced motion a
            projected BFGS compiled as one program with the whole co-design; or an
            optax transformation (e.g. ``optax.lbfgs()``, ``optax.adam(1e-2)``) run as
            one compiled loop by :func:`jaxbal.minimize`; pass the same object on every
            call to reuse the compiled loop.
        constraints: optional ``{metric: upper bound [SI]}``, e.g. an added-mass budget
            ``{"added_mass": 2.0}``, enforced by the quadratic penalty.
        penalty: weight ``P`` of the constraint penalty.
        reduce: evaluate the RMS force and moment from the wrench regressor computed
            once along the motion (:mod:`~jaxbal._src.reduced_motion`; verified, else
            the metrics are evaluated directly): ``True``, ``False``, or ``None``
            (default) for problems of at least :data:`REDUCE_MIN_VARIABLES` variables.
            Default optimiser only.

    Returns:
        A :class:`DesignSolution`.

    Raises:
        ValueError: an unknown metric or design-variable name (the message lists the
            valid ones), an empty ``free``, a non-finite start or bound, a start
            outside the bounds, a negative budget of a named metric, a negative or
            non-finite ``penalty``, ``max_steps < 1``, a NaN or negative ``gtol``, a
            motion of the wrong shape, or an invalid robot or motion (negative or
            non-finite masses, inertias or parameters, a non-finite state, non-finite
            starting metrics).
    """
    motion = as_motion(motions)
    check_motion_shape(robot, motion)
    # a closed chain's motion off its loops (held while a length changed): its compiled,
    # callback-free programs did not see it and optimised the wrong mechanism
    check_samples_eagerly(robot, motion.q, motion.qd, motion.qdd)
    terms, weights = _objective_terms(objective)
    constrained, bounds = check_constraints(constraints)
    check_penalty(penalty)
    check_stopping(max_steps, gtol)

    design = robot.design()
    if free is None:
        free = tuple(name for name in design if name != "payload")
    free = tuple(dict.fromkeys(check_design_names(robot, free)))
    if not free:
        raise ValueError(
            f"free names no design variable to optimise; {type(robot).__name__} has "
            f"{sorted(design)}"
        )
    start = dict(start or {})
    check_design_names(robot, start)
    for name, value in start.items():
        finite_array(f"start[{name!r}]", value)
    robot = robot.with_design(start)
    x0 = {name: finite_array(f"start value of {name!r}", robot.design()[name]) for name in free}
    lows, highs, two_sided = _bounds(robot, free, lower, upper)
    x0 = starts_inside(x0, lows, highs, two_sided)

    everything = terms + tuple(m for m in constrained if m not in terms)
    where = np.asarray([everything.index(m) for m in constrained], dtype=int)
    if optimizer is None:  # scales set from the starting design in _codesign_compact
        scales, floors = np.ones(len(terms)), np.full(len(everything), SCALE_FLOOR)
    else:
        # bookkeeping in NumPy: eager jnp operations each compiled a tiny XLA program
        before, floors = (np.asarray(x) for x in _evaluate(robot, motion, everything))
        scales = np.maximum(np.abs(before[: len(terms)]), floors[: len(terms)])
    bound_scales = np.maximum(np.abs(bounds), floors[where])
    problem = _Problem(
        free=free,
        two_sided=two_sided,
        terms=terms,
        constrained=constrained,
        lower=lows,
        upper=highs,
        weights=np.asarray(weights, dtype=float),
        scales=np.asarray(scales, dtype=float),
        bounds=np.asarray(bounds, dtype=float),
        bound_scales=np.asarray(bound_scales, dtype=float),
        penalty=np.asarray(penalty, dtype=float),
        mapped=optimizer is not None,
    )
    if optimizer is None:
        return _codesign_compact(robot, motion, x0, problem, max_steps, gtol, reduce)
    with runtime_checks(False):  # line-search trials may be non-finite (see validation)
        solution = minimize(
            design_loss,
            _to_params(x0, problem),
            optimizer=optimizer,
            max_steps=max_steps,
            gtol=gtol,
            args=(robot, motion, problem),
        )
    optimised, optimised_design = _designed(robot, solution.params, problem)
    after = np.asarray(_evaluate(optimised, motion, everything)[0])
    n = len(terms)
    initial_value = _combine_numpy(before[:n], before[where], problem)
    names = [metric_name(m) for m in everything]
    constraint_values = {
        metric_name(m): (after[i], bounds[k])
        for k, (m, i) in enumerate(zip(constrained, where, strict=True))
    }
    excess = after[where] - bounds
    return DesignSolution(
        design=optimised_design,
        robot=optimised,
        value=solution.value,
        initial_value=initial_value,
        metrics={name: (before[i], after[i]) for i, name in enumerate(names)},
        constraints=constraint_values,
        feasible=np.all(excess <= FEASIBILITY_RTOL * bound_scales),
        converged=solution.converged,
        steps=solution.steps,
        grad_norm=solution.grad_norm,
        history=solution.history,
        at_bound=_contacts(optimised, problem),
    )
