"""Joint counter-mass + trajectory co-design, robust over a payload distribution.

:func:`joint_codesign` extends :func:`jaxbal.design.codesign`: besides the robot's
design variables, named *trajectory* variables ``θ`` (profile switch times, a φ-law
polynomial, a planned COM path, …) are optimised, with two-sided bounds. The motion is
no longer fixed: a motion factory ``motion(robot, θ) -> Motion`` (a module-level
function or an ``eqx.Module``, so the compiled loop is reused) samples it for every
candidate. The metrics are evaluated at every payload of ``payloads`` (one ``vmap``)
and aggregated by their mean (``robust="mean"``, the expectation over a uniform grid),
their quadratic mean (``"rms"``, smooth where the mean has a kink: a payload balanced
exactly, see :mod:`jaxbal._src.payload_aggregate`) or by a smooth maximum
(``robust="max"``), the log-mean-exp of the ``n`` payloads::

    smax(v) = s/k · log (1/n) Σ_p exp(k v_p / s),    max v − s log(n)/k ≤ smax(v) ≤ max v

with ``s`` the metric's scale and ``k = sharpness``; it equals ``v`` exactly for a
metric that does not depend on the payload (the added mass), so a Pareto front's
added-mass end point is the added mass itself, not ``v + s log(n)/k``. Constraints (torque
limit, added-mass budget, …) hold at the *worst* payload (hard maximum). The loss, the
bound reparametrisation, the penalty are those of :mod:`jaxbal._src.design`; so is the
solver: by default the host-driven L-BFGS of :mod:`jaxbal._src.lbfgs` around one compiled
value-and-gradient with the metric values at every payload (half the compile time of
optax's loop); with ``optimizer=`` an optax transformation, optax's compiled loop.

References:
    Briot, Arakelian & Le Baron (2012), §2 (trajectory parameters of COM planning);
    Geng et al. (2021) (payload variation spoils the balance);
    van der Wijk et al. (2013) (counter-masses).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src import design_inputs as inputs
from jaxbal._src import payload_aggregate as agg
from jaxbal._src.base_vibration_metric import refuse_rescaled_times
from jaxbal._src.design import CONSTRAINT_PENALTY, FEASIBILITY_RTOL
from jaxbal._src.design_loss import (
    _bounds,
    _combine,
    _floor,
    _objective_terms,
    _Problem,
    _to_design,
    _to_design_numpy,
    _to_params,
    _values,
    given_or,
)
from jaxbal._src.design_solution import _contacts, bound_contacts
from jaxbal._src.lbfgs import lbfgs
from jaxbal._src.metrics import Motion, check_design_names, finite_array, metric_name
from jaxbal._src.momentum import replayed
from jaxbal._src.motion_factories import check_planned, check_start
from jaxbal._src.optimize import minimize
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_robot
from jaxbal._src.types import Array, Scalar
from jaxbal._src.validation import check_stopping, checked_call, runtime_checks

__all__ = ["CONSTRAINT_RTOL", "JointSolution", "joint_codesign", "payload_metrics"]

MotionFactory = Callable[[Robot, dict], Motion]

#: shifted-penalty rounds stop once ``c ≤ b + CONSTRAINT_RTOL·|b|`` at the worst payload
CONSTRAINT_RTOL = 1e-6


class JointSolution(NamedTuple):
    """Result of :func:`joint_codesign`.

    Attributes:
        design: every design variable of the optimised robot (name -> array, SI).
        trajectory: the optimised trajectory variables (name -> array).
        robot: the optimised robot (nominal payload).
        value: final loss (dimensionless); ``initial_value`` where the optimiser starts
            (a variable on a bound moved just inside it: ~1e-5 off the given design's).
        metrics: name -> ``(before, after)`` over the payloads [SI]: an objective's mean,
            quadratic mean or (``robust="max"``) worst payload, exactly (the loss takes a
            smooth maximum, up to ``s log(n)/k`` below it); a constraint-only metric's worst.
        constraints: name -> ``(worst value over payloads, bound)`` after [SI].
        feasible: every constraint satisfied within :data:`FEASIBILITY_RTOL`.
        converged, steps, grad_norm, history, at_bound: as
            :class:`jaxbal.design.DesignSolution` (``at_bound``: the design variables).
        trajectory_at_bound: ``at_bound`` of the trajectory variables (θ).
    """

    design: dict[str, Array]
    trajectory: dict[str, Array]
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
    trajectory_at_bound: dict[str, np.ndarray]


class _Joint(eqx.Module):
    design: _Problem
    trajectory: _Problem
    payloads: Array
    robust: str = eqx.field(static=True)
    sharpness: Array


def _per_payload(robot, motion, theta, payloads, metrics):
    """``(n_payloads, len(metrics))`` values, one ``vmap`` over the payloads."""

    def one(payload):
        loaded = robot.with_design({"payload": payload})
        return _values(loaded, motion(loaded, theta), metrics)

    return jax.vmap(one)(payloads)


def _loss_values(candidate: Robot, theta, motion: MotionFactory, joint: _Joint):
    """``(loss, (n_payloads, k) metric values)`` of a candidate robot and ``θ``: the
    objective terms, then the constraint metrics."""
    problem = joint.design
    metrics = problem.terms + problem.constrained
    values = _per_payload(candidate, motion, theta, joint.payloads, metrics)
    n = len(problem.terms)
    objective = agg.aggregate(values[:, :n], problem.scales, joint.robust, joint.sharpness)
    constrained = jnp.max(values[:, n:], axis=0) if problem.constrained else None
    return _combine(objective, constrained, problem), values


def joint_loss(params, robot: Robot, motion: MotionFactory, joint: _Joint):
    """Loss of :func:`joint_codesign` at the parameters (module level: cached loop)."""
    candidate = robot.with_design(_to_design(params["design"], joint.design))
    theta = _to_design(params["trajectory"], joint.trajectory)
    return _loss_values(candidate, theta, motion, joint)[0]


@eqx.filter_jit
def _loss_grad(params, robot: Robot, motion: MotionFactory, joint: _Joint, given, at_start):
    """Loss, gradient (a pytree like ``params``) and ``(n_payloads, k)`` metric values:
    the one program the default joint co-design compiles. With ``at_start`` (a traced
    bool) the values are those of the given robot and ``θ = given`` (the scales are
    then placeholders). Runtime checks are off while it is traced (line-search trials
    may be non-finite); the robot is checked before, the caller raises eagerly."""

    def loss(p):
        designed = robot.with_design(_to_design(p["design"], joint.design))
        theta = _to_design(p["trajectory"], joint.trajectory)
        theta = {k: jnp.where(at_start, given[k], theta[k]) for k in theta}
        return _loss_values(given_or(robot, designed, at_start), theta, motion, joint)

    # no straight-line replay: traced once, evaluated tens of times (momentum.replayed)
    with runtime_checks(False), replayed(False):
        (value, values), grad = jax.value_and_grad(loss, has_aux=True)(params)
    return value, grad, values


def payload_metrics(robot: Robot, motion: MotionFactory, trajectory, payloads, metrics: tuple):
    """``(n_payloads, len(metrics))`` metric values of ``robot`` moving with
    ``motion(robot, trajectory)`` at every payload [SI] (compiled once per structure;
    an invalid robot or motion raises ``ValueError``)."""
    trajectory = {k: jnp.asarray(v, float) for k, v in trajectory.items()}
    payloads = jnp.asarray(payloads, float).reshape(-1)
    check_robot(robot)  # before the (larger) program compiles
    # checked: a bad robot or motion raises ValueError with the values, not a runtime error
    return checked_call(_per_payload, robot, motion, trajectory, payloads, tuple(metrics))


@eqx.filter_jit
def _floors(robot, motion, theta, metrics):
    return jnp.stack([_floor(robot, motion(robot, theta), m) for m in metrics])


def _trajectory_problem(trajectory, lower, upper) -> _Problem:
    names = tuple(trajectory)
    if set(lower) != set(names) or set(upper) != set(names):
        raise ValueError(f"trajectory bounds must name exactly {sorted(names)}")
    lows, highs = [], []
    for name in names:
        x = finite_array(f"trajectory[{name!r}]", trajectory[name])
        lo = finite_array(f"trajectory_lower[{name!r}]", lower[name], x.shape)
        hi = finite_array(f"trajectory_upper[{name!r}]", upper[name], x.shape)
        if not np.all(hi > lo) or np.any(x < lo) or np.any(x > hi):
            raise ValueError(
                f"trajectory {name!r}: need lower < upper and the start inside, got "
                f"lower {lo.tolist()}, start {x.tolist()}, upper {hi.tolist()}"
            )
        lows.append(jnp.asarray(lo))
        highs.append(jnp.asarray(hi))
    return _Problem(names, (True,) * len(names), (), (), tuple(lows), tuple(highs),
                    *(jnp.zeros(0),) * 4, jnp.asarray(0.0))  # fmt: skip


def joint_codesign(
    robot: Robot,
    motion: MotionFactory,
    trajectory: Mapping[str, Any],
    objective="peak_force",
    *,
    trajectory_lower: Mapping[str, Any],
    trajectory_upper: Mapping[str, Any],
    free=None,
    lower: Mapping[str, Any] | None = None,
    upper: Mapping[str, Any] | None = None,
    start: Mapping[str, Any] | None = None,
    payloads=None,
    robust: str = "mean",
    sharpness: float = 200.0,
    constraints: Mapping[Any, float] | None = None,
    penalty: float = CONSTRAINT_PENALTY,
    scales: Mapping[str, float] | None = None,
    max_steps: int = 200,
    gtol: float = 1e-10,
    optimizer=None,
    rounds: int = 5,
) -> JointSolution:
    """Design variables and trajectory variables optimised together (module doc).

    Args:
        robot: any :class:`~jaxbal.Robot` (its ``payload`` is the nominal one).
        motion: ``motion(robot, θ) -> Motion`` (traceable; e.g.
            ``Motion(*jaxbal.sample(trajectory_of(robot, θ), times, order=2))``).
        trajectory: starting ``θ`` (name -> array).
        objective: metric, or ``{metric: weight}`` (as :func:`~jaxbal.design.codesign`).
        trajectory_lower, trajectory_upper: two-sided bounds of every ``θ`` entry.
        free, lower, upper, start: design variables, as in ``codesign`` (an empty
            ``free`` optimises the trajectory only).
        payloads: ``(n,)`` payloads [kg] the metrics are aggregated over (default: the
            robot's own).
        robust: ``"mean"`` (expected value over the payload grid), ``"rms"``
            (quadratic mean, smooth where a payload is balanced exactly) or ``"max"``.
            A mean that stops unconverged where an objective is zero at some payload
            (a kink: see :mod:`jaxbal._src.payload_aggregate`) warns, naming it.
        sharpness: ``k > 0`` of the smooth maximum.
        constraints: ``{metric: bound}`` held at the worst payload.
        penalty: weight of the quadratic constraint penalty.
        scales: optional fixed scale (finite, > 0) per objective metric name (default:
            its value at the start) — pass the same scales along a Pareto front.
        max_steps, gtol: L-BFGS iteration cap and gradient-norm tolerance.
        optimizer: ``None`` (host-driven L-BFGS) or an optax transformation
            (:func:`jaxbal.minimize`).
        rounds: at most this many solves with a shifted penalty bound (same
            compilation), so that the constraints hold at the worst payload up to the
            solver's accuracy; they stop early once every constraint holds to
            :data:`CONSTRAINT_RTOL` of its bound.
    """
    inputs.check_robust(robust, sharpness)
    check_stopping(max_steps, gtol)
    inputs.check_rounds(rounds)
    inputs.check_penalty(penalty)
    terms, weights = _objective_terms(objective)
    given = inputs.check_scales(scales, terms)
    constrained, bounds = inputs.check_constraints(constraints)
    bounds = jnp.asarray(bounds)
    design = robot.design()
    if free is None:
        free = tuple(name for name in design if name != "payload")
    free = tuple(dict.fromkeys(check_design_names(robot, free)))
    robot = robot.with_design(dict(start or {}))
    check_robot(robot)  # an invalid robot is refused before anything compiles
    if payloads is None:
        payloads = jnp.atleast_1d(design.get("payload", jnp.zeros(())))
    payloads = jnp.asarray(inputs.check_payloads(payloads))
    theta_problem = _trajectory_problem(trajectory, trajectory_lower, trajectory_upper)
    theta0 = {k: jnp.asarray(v, float) for k, v in trajectory.items()}
    lows, highs, two_sided = _bounds(robot, free, lower, upper)
    inputs.starts_inside({k: robot.design()[k] for k in free}, lows, highs, two_sided)
    check_start(robot, motion, theta0, trajectory_lower, trajectory_upper, payloads)
    everything = terms + tuple(m for m in constrained if m not in terms)
    refuse_rescaled_times(everything, theta0)
    columns = [(terms + constrained).index(m) for m in everything]
    n = len(terms)
    where = np.asarray([everything.index(m) for m in constrained], int)
    ones = jnp.ones(n)

    def make_problem(term_scales, bound_scales):
        return _Problem(
            free, two_sided, terms, constrained, lows, highs, jnp.asarray(weights),
            jnp.asarray(term_scales), bounds, jnp.asarray(bound_scales),
            jnp.asarray(penalty, dtype=float),
        )  # fmt: skip

    sharp = jnp.asarray(sharpness, float)
    joint = _Joint(
        make_problem(ones, jnp.ones_like(bounds)), theta_problem, payloads, robust, sharp
    )
    x0 = {name: robot.design()[name] for name in free}
    params0 = {
        "design": _to_params(x0, joint.design),
        "trajectory": _to_params(theta0, theta_problem),
    }
    leaves, treedef = jax.tree_util.tree_flatten(params0)
    shapes = [np.shape(leaf) for leaf in leaves]
    cuts = np.cumsum([0] + [int(np.prod(shape, dtype=int)) for shape in shapes])

    def unflat(x):
        parts = [
            x[a:b].reshape(shape) for a, b, shape in zip(cuts[:-1], cuts[1:], shapes, strict=True)
        ]
        return jax.tree_util.tree_unflatten(treedef, parts)

    def evaluate(x, joint, at_start=False):
        value, grad, values = _loss_grad(
            unflat(x), robot, motion, joint, theta0, np.asarray(at_start)
        )
        flat = np.concatenate([np.ravel(np.asarray(g)) for g in jax.tree_util.tree_leaves(grad)])
        return float(value), flat, np.asarray(values)[:, columns]

    x_start = np.concatenate([np.ravel(np.asarray(leaf, float)) for leaf in leaves])
    # the robot and θ as given: their metric values set the scales (as codesign's)
    _, _, before = evaluate(x_start, joint, at_start=True)
    if not np.all(np.isfinite(before)):
        _raise_invalid_start(robot, motion, theta0, payloads, everything, before)
    agg.check_aggregable(robust, before[:, :n])
    floors = np.asarray(_floors(robot, motion, theta0, everything))
    nominal = np.maximum(np.abs(np.mean(before, axis=0)), floors)
    # a given scale is used as given (it was raised to the floor: another objective)
    term_scales = [float(given.get(metric_name(m), nominal[i])) for i, m in enumerate(terms)]
    bound_scales = np.maximum(np.abs(np.asarray(bounds)), floors[where])
    joint = eqx.tree_at(lambda j: j.design, joint, make_problem(term_scales, bound_scales))
    problem = joint.design
    initial_value, _, at_first = evaluate(x_start, joint)
    x, shift = x_start, np.zeros(np.shape(bounds))
    for _ in range(rounds if constrained else 1):
        # Shifted quadratic penalty (Powell-Hestenes-Rockafellar): move the bound
        # seen by the penalty by the violation left, so the true bound is met.
        shifted = eqx.tree_at(lambda j: j.design.bounds, joint, bounds - shift)
        if optimizer is None:  # host-driven L-BFGS around the one compiled program
            result = lbfgs(partial(evaluate, joint=shifted), x, max_steps=max_steps, gtol=gtol)
            x, worst = result.x, np.max(result.aux, axis=0)
            status = (result.converged, result.steps, np.linalg.norm(result.grad), result.history)
        else:  # the optax optimiser's compiled loop
            args = (robot, motion, shifted)
            with runtime_checks(False):
                solution = minimize(joint_loss, unflat(x), optimizer, max_steps, gtol, args=args)
            x = np.concatenate([np.ravel(np.asarray(p)) for p in jax.tree.leaves(solution.params)])
            worst = np.max(evaluate(x, shifted)[2], axis=0)
            status = (solution.converged, solution.steps, solution.grad_norm, solution.history)
        if not constrained:
            break
        excess = worst[where] - np.asarray(bounds)
        if np.all(excess <= CONSTRAINT_RTOL * bound_scales):
            break  # every constraint met to CONSTRAINT_RTOL: no further round
        shift = np.maximum(shift + excess, 0.0)
    final_value, _, after = evaluate(x, joint)
    # Keep the start if the optimiser ended above it (non-smooth peaks).
    if not final_value <= initial_value:
        x, after = x_start, at_first
    params = unflat(x)
    optimised = robot.with_design(_to_design_numpy(params["design"], problem))
    theta = _to_design_numpy(params["trajectory"], theta_problem)
    theta = {k: jnp.asarray(v) for k, v in theta.items()}
    names = [metric_name(m) for m in everything]
    aggregated = [
        np.concatenate([agg.aggregate_numpy(v[:, :n], robust), np.max(v[:, n:], axis=0)])
        for v in (before, after)
    ]  # fmt: skip
    check_planned(optimised, motion, theta, payloads)  # a NaN motion was seen by no one
    worst, (converged, steps, grad_norm, history) = np.max(after, axis=0)[where], status
    if robust == "mean" and not converged:  # a kink of the mean? (warns, naming it)
        agg.warn_at_kink(after[:, :n], problem.scales, names[:n], payloads, grad_norm)
    excess = worst - np.asarray(bounds)
    return JointSolution(
        design=optimised.design(),
        trajectory=theta,
        robot=optimised,
        value=np.asarray(min(final_value, initial_value)),
        initial_value=np.asarray(initial_value),
        metrics={name: (aggregated[0][i], aggregated[1][i]) for i, name in enumerate(names)},
        constraints={metric_name(m): (worst[k], bounds[k]) for k, m in enumerate(constrained)},
        feasible=np.all(excess <= FEASIBILITY_RTOL * bound_scales),
        converged=np.asarray(converged),
        steps=np.asarray(steps),
        grad_norm=np.asarray(grad_norm),
        history=np.asarray(history),
        at_bound=_contacts(optimised, problem),
        trajectory_at_bound=bound_contacts(
            theta, *(getattr(theta_problem, k) for k in ("free", "lower", "upper", "two_sided"))
        ),  # fmt: skip
    )


def _raise_invalid_start(robot, motion, theta, payloads, metrics, before) -> None:
    """The named error of a start the compiled program flagged: the metrics evaluated
    again with the runtime checks on raise it; else the non-finite values are listed."""
    payload_metrics(robot, motion, theta, payloads, metrics)
    listed = {metric_name(m): np.asarray(before[:, i]) for i, m in enumerate(metrics)}
    raise ValueError(f"metrics of the starting design are not finite: {listed}")
