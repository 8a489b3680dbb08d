"""Joint counter-mass + trajectory co-design, robust over a payload distribution.

:func:`joint_codesign` extends :func:`jaxbal.design.codesign`: besides the robot's
design variables, named *trajectory* variables ``θ`` (profile switch times, a φ-law
polynomial, a planned COM path, …) are optimised, with two-sided bounds. The motion is
no longer fixed: a motion factory ``motion(robot, θ) -> Motion`` (a module-level
function or an ``eqx.Module``, so the compiled loop is reused) samples it for every
candidate. The metrics are evaluated at every payload of ``payloads`` (one ``vmap``)
and aggregated by their mean (``robust="mean"``, the expectation over a uniform grid)
or by a smooth maximum (``robust="max"``), the log-mean-exp of the ``n`` payloads::

    smax(v) = s/k · log (1/n) Σ_p exp(k v_p / s),    max v − s log(n)/k ≤ smax(v) ≤ max v

with ``s`` the metric's scale and ``k = sharpness``; it equals ``v`` exactly for a
metric that does not depend on the payload (the added mass), so a Pareto front's
added-mass end point is the added mass itself, not ``v + s log(n)/k``. Constraints (torque limit,
added-mass budget, …) hold at the *worst* payload (hard maximum). The loss, the bound
reparametrisation and the penalty are those of :mod:`jaxbal._src.design`.

References:
    Briot, Arakelian & Le Baron (2012), §2 (trajectory parameters of COM planning);
    Geng et al. (2021) (payload variation spoils the balance);
    van der Wijk et al. (2013) (counter-masses).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.design import CONSTRAINT_PENALTY, FEASIBILITY_RTOL, _bounds, _objective_terms
from jaxbal._src.design_loss import _combine, _floor, _Problem, _to_design, _to_params, _values
from jaxbal._src.metrics import Motion, check_design_names, metric_name, resolve_metric
from jaxbal._src.optimize import minimize
from jaxbal._src.robot import Robot
from jaxbal._src.types import Array, Scalar
from jaxbal._src.validation import runtime_checks

__all__ = ["CONSTRAINT_RTOL", "JointSolution", "joint_codesign", "payload_metrics"]

MotionFactory = Callable[[Robot, dict], Motion]

#: the shifted-penalty rounds stop once every constraint holds to this fraction of its
#: scale (its bound): ``c ≤ b + CONSTRAINT_RTOL·|b|`` at the worst payload.
CONSTRAINT_RTOL = 1e-6


class JointSolution(NamedTuple):
    """Result of :func:`joint_codesign`.

    Attributes:
        design: every design variable of the optimised robot (name -> array, SI).
        trajectory: the optimised trajectory variables (name -> array).
        robot: the optimised robot (nominal payload).
        value: final loss (dimensionless); ``initial_value`` at the start.
        metrics: name -> ``(before, after)`` aggregated value over the payloads [SI].
        constraints: name -> ``(worst value over payloads, bound)`` after [SI].
        feasible: every constraint satisfied within :data:`FEASIBILITY_RTOL`.
        converged, steps, grad_norm, history: as :class:`jaxbal.design.DesignSolution`.
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


class _Joint(eqx.Module):
    design: _Problem
    trajectory: _Problem
    payloads: Array
    robust: str = eqx.field(static=True)
    sharpness: Array


def _aggregate(values: Array, scales: Array, robust: str, sharpness) -> Array:
    """``(n_payloads, k)`` metric values -> ``(k,)`` mean or smooth maximum."""
    if robust == "mean":
        return jnp.mean(values, axis=0)
    scaled = sharpness * values / scales
    log_mean = jax.scipy.special.logsumexp(scaled, axis=0) - np.log(values.shape[0])
    return scales / sharpness * log_mean


def _per_payload(robot, motion, theta, payloads, metrics):
    """``(n_payloads, len(metrics))`` values, one ``vmap`` over the payloads."""

    def one(payload):
        loaded = robot.with_design({"payload": payload})
        return _values(loaded, motion(loaded, theta), metrics)

    return jax.vmap(one)(payloads)


def joint_loss(params, robot: Robot, motion: MotionFactory, joint: _Joint):
    """Loss of :func:`joint_codesign` at the parameters (module level: cached loop)."""
    problem = joint.design
    candidate = robot.with_design(_to_design(params["design"], problem))
    theta = _to_design(params["trajectory"], joint.trajectory)
    metrics = problem.terms + problem.constrained
    values = _per_payload(candidate, motion, theta, joint.payloads, metrics)
    n = len(problem.terms)
    objective = _aggregate(values[:, :n], problem.scales, joint.robust, joint.sharpness)
    constrained = jnp.max(values[:, n:], axis=0) if problem.constrained else None
    return _combine(objective, constrained, problem)


def payload_metrics(robot: Robot, motion: MotionFactory, trajectory, payloads, metrics: tuple):
    """``(n_payloads, len(metrics))`` metric values of ``robot`` moving with
    ``motion(robot, trajectory)`` at every payload [SI] (jit-compiled, cached)."""
    trajectory = {k: jnp.asarray(v, float) for k, v in trajectory.items()}
    payloads = jnp.asarray(payloads, float).reshape(-1)
    return _payload_metrics(robot, motion, trajectory, payloads, tuple(metrics))


@eqx.filter_jit
def _payload_metrics(robot, motion, trajectory, payloads, metrics):
    return _per_payload(robot, motion, trajectory, payloads, metrics)


_loss = eqx.filter_jit(joint_loss)


@eqx.filter_jit
def _floors(robot, motion, theta, metrics):
    return jnp.stack([_floor(robot, motion(robot, theta), m) for m in metrics])


def _trajectory_problem(trajectory, lower, upper) -> _Problem:
    names = tuple(trajectory)
    if set(lower) != set(names) or set(upper) != set(names):
        raise ValueError(f"trajectory bounds must name exactly {sorted(names)}")
    lows, highs = [], []
    for name in names:
        x = np.asarray(trajectory[name], float)
        lo = np.broadcast_to(np.asarray(lower[name], float), x.shape)
        hi = np.broadcast_to(np.asarray(upper[name], float), x.shape)
        if not np.all(hi > lo) or np.any(x < lo) or np.any(x > hi):
            raise ValueError(f"trajectory {name!r}: need lower < upper and start inside")
        lows.append(jnp.asarray(lo))
        highs.append(jnp.asarray(hi))
    empty = jnp.zeros(0)
    return _Problem(names, (True,) * len(names), (), (), tuple(lows), tuple(highs),
                    empty, empty, empty, empty, jnp.asarray(0.0))  # fmt: skip


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
        robust: ``"mean"`` (expected value over the payload grid) or ``"max"``.
        sharpness: ``k`` of the smooth maximum.
        constraints: ``{metric: bound}`` held at the worst payload.
        penalty: weight of the quadratic constraint penalty.
        scales: optional fixed scale per objective metric name (default: its value at
            the start) — pass the same scales along a Pareto front.
        max_steps, gtol, optimizer: L-BFGS settings (:func:`jaxbal.minimize`).
        rounds: at most this many solves with a shifted penalty bound (same
            compilation), so that the constraints hold at the worst payload up to the
            solver's accuracy; they stop early once every constraint holds to
            :data:`CONSTRAINT_RTOL` of its bound.
    """
    if robust not in ("mean", "max"):
        raise ValueError(f"robust must be 'mean' or 'max', got {robust!r}")
    terms, weights = _objective_terms(objective)
    constraints = dict(constraints or {})
    constrained = tuple(constraints)
    for metric in constrained:
        resolve_metric(metric)
    bounds = jnp.asarray([float(b) for b in constraints.values()], dtype=float)
    design = robot.design()
    if free is None:
        free = tuple(name for name in design if name != "payload")
    free = tuple(dict.fromkeys(check_design_names(robot, free)))
    robot = robot.with_design(dict(start or {}))
    if payloads is None:
        payloads = jnp.atleast_1d(design.get("payload", jnp.zeros(())))
    payloads = jnp.asarray(payloads, dtype=float).reshape(-1)
    theta_problem = _trajectory_problem(trajectory, trajectory_lower, trajectory_upper)
    theta0 = {k: jnp.asarray(v, float) for k, v in trajectory.items()}
    lows, highs, two_sided = _bounds(robot, free, lower, upper)
    everything = terms + tuple(m for m in constrained if m not in terms)
    before = payload_metrics(robot, motion, theta0, payloads, everything)
    floors = _floors(robot, motion, theta0, everything)
    nominal = jnp.maximum(jnp.abs(jnp.mean(before, axis=0)), floors)
    given = dict(scales or {})
    term_scales = jnp.stack(
        [jnp.maximum(given.get(metric_name(m), nominal[i]), floors[i]) for i, m in enumerate(terms)]
    )
    where = jnp.asarray([everything.index(m) for m in constrained], int)
    problem = _Problem(
        free, two_sided, terms, constrained, lows, highs, jnp.asarray(weights),
        term_scales, bounds, jnp.maximum(jnp.abs(bounds), floors[where]),
        jnp.asarray(penalty, dtype=float),
    )  # fmt: skip
    joint = _Joint(problem, theta_problem, payloads, robust, jnp.asarray(sharpness, float))
    x0 = {name: robot.design()[name] for name in free}
    params0 = {"design": _to_params(x0, problem), "trajectory": _to_params(theta0, theta_problem)}
    with runtime_checks(False):
        initial_value = _loss(params0, robot, motion, joint)
        params, shift = params0, jnp.zeros_like(bounds)
        for _ in range(rounds if constrained else 1):
            # Shifted quadratic penalty (Powell-Hestenes-Rockafellar): move the bound
            # seen by the penalty by the violation left, so the true bound is met.
            shifted = eqx.tree_at(lambda j: j.design.bounds, joint, bounds - shift)
            solution = minimize(
                joint_loss, params, optimizer, max_steps, gtol, args=(robot, motion, shifted)
            )
            params = solution.params
            if not constrained:
                break
            candidate = robot.with_design(_to_design(params["design"], problem))
            theta = _to_design(params["trajectory"], theta_problem)
            worst = jnp.max(payload_metrics(candidate, motion, theta, payloads, everything), 0)
            excess = worst[where] - bounds
            if bool(jnp.all(excess <= CONSTRAINT_RTOL * problem.bound_scales)):
                break  # every constraint met to CONSTRAINT_RTOL: no further round
            shift = jnp.maximum(shift + excess, 0.0)
        final_value = _loss(params, robot, motion, joint)
    # Keep the start if the optimiser ended above it (non-smooth peaks).
    better = final_value <= initial_value
    params = jax.tree.map(lambda a, b: jnp.where(better, a, b), params, params0)
    optimised = robot.with_design(_to_design(params["design"], problem))
    theta = _to_design(params["trajectory"], theta_problem)
    after = payload_metrics(optimised, motion, theta, payloads, everything)
    n = len(terms)
    names = [metric_name(m) for m in everything]
    agg_before = jnp.concatenate(
        [_aggregate(before[:, :n], term_scales, robust, sharpness), jnp.max(before[:, n:], 0)]
    )
    agg_after = jnp.concatenate(
        [_aggregate(after[:, :n], term_scales, robust, sharpness), jnp.max(after[:, n:], 0)]
    )
    worst = jnp.max(after, axis=0)[where]
    excess = worst - bounds
    return JointSolution(
        design=optimised.design(),
        trajectory=theta,
        robot=optimised,
        value=jnp.minimum(final_value, initial_value),
        initial_value=initial_value,
        metrics={name: (agg_before[i], agg_after[i]) for i, name in enumerate(names)},
        constraints={metric_name(m): (worst[k], bounds[k]) for k, m in enumerate(constrained)},
        feasible=jnp.all(excess <= FEASIBILITY_RTOL * problem.bound_scales),
        converged=solution.converged,
        steps=solution.steps,
        grad_norm=solution.grad_norm,
        history=solution.history,
    )
