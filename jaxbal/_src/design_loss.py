"""The co-design loss and its one compiled program (see :mod:`jaxbal._src.design`).

The loss is a function of the unconstrained parameters ``r`` of the bounded design
variables, the robot, the motion and a :class:`_Problem` (names, metric choices and
bound kinds static; every number an array leaf), so that the compiled code is reused
for any robot of the same structure. :func:`_loss_grad_flat` is the program the default
co-design calls once per L-BFGS iteration.

References:
    Liu & Nocedal (1989), L-BFGS (the parametrisation keeps it unconstrained).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from functools import cache
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.config import compiler_options
from jaxbal._src.design_inputs import check_lower_bounds
from jaxbal._src.metrics import (
    ADDED_MASS_VARIABLES,
    Motion,
    base_inertia,
    check_design_names,
    check_hashable,
    finite_array,
    resolve_metric,
)
from jaxbal._src.momentum import replayed, total_mass
from jaxbal._src.robot import Robot
from jaxbal._src.types import Array, Scalar
from jaxbal._src.validation import runtime_checks

#: distance [SI units of the variable] that a variable starting at its lower bound is
#: moved inside, so that its square-root parameter is not at a stationary point.
START_OFFSET = 1e-4
#: floor of the scale of a metric other than the added mass and inertia [SI].
SCALE_FLOOR = 1e-12


class _Problem(eqx.Module):
    """Everything the loss needs besides the parameters, robot and motion: names and
    metric choices static (part of the compiled structure), numbers as array leaves."""

    free: tuple[str, ...] = eqx.field(static=True)
    two_sided: tuple[bool, ...] = eqx.field(static=True)
    terms: tuple[Any, ...] = eqx.field(static=True)
    constrained: tuple[Any, ...] = eqx.field(static=True)
    lower: tuple[Array, ...]
    upper: tuple[Array, ...]
    weights: Array
    scales: Array
    bounds: Array
    bound_scales: Array
    penalty: Array
    #: whether the parameters are those of the bound map (``x = lower + r²``, ``lower +
    #: (upper − lower) sin² r``: the optax loop and the joint co-design) or the design
    #: variables themselves (the default co-design's L-BFGS-B holds the bounds).
    mapped: bool = eqx.field(static=True, default=True)


def _to_design(params: dict[str, Array], problem: _Problem) -> dict[str, Array]:
    """The bounded design variables from the unconstrained parameters ``r`` (the
    parameters themselves when ``problem.mapped`` is False)."""
    if not problem.mapped:
        return dict(params)
    design = {}
    for name, two, lo, hi in zip(
        problem.free, problem.two_sided, problem.lower, problem.upper, strict=True
    ):
        r = params[name]
        design[name] = lo + (hi - lo) * jnp.sin(r) ** 2 if two else lo + r**2
    return design


def _to_design_numpy(params: Mapping[str, np.ndarray], problem: _Problem) -> dict:
    """:func:`_to_design` in NumPy (the optimiser's final point, on the host)."""
    if not problem.mapped:
        return {name: np.asarray(value, dtype=float) for name, value in params.items()}
    design = {}
    for name, two, lo, hi in zip(
        problem.free, problem.two_sided, problem.lower, problem.upper, strict=True
    ):
        r, lo, hi = (np.asarray(a, dtype=float) for a in (params[name], lo, hi))
        design[name] = lo + (hi - lo) * np.sin(r) ** 2 if two else lo + r**2
    return design


def _to_params(design: Mapping[str, np.ndarray], problem: _Problem) -> dict[str, Array]:
    """Parameters ``r`` of a design moved :data:`START_OFFSET` inside the bounds (the
    design variables themselves, so moved, when ``problem.mapped`` is False: a design
    whose counter-masses and distances all start at zero is a saddle of the force, whose
    products ``m·d`` have a zero gradient there)."""
    params = {}
    for name, two, lo, hi in zip(
        problem.free, problem.two_sided, problem.lower, problem.upper, strict=True
    ):
        lo, hi, x = np.asarray(lo), np.asarray(hi), np.asarray(design[name], dtype=float)
        if two:
            span = hi - lo
            inset = np.minimum(START_OFFSET / span, 0.25)
            fraction = np.clip((x - lo) / span, inset, 1.0 - inset)
            inside = lo + span * fraction
            params[name] = np.arcsin(np.sqrt(fraction)) if problem.mapped else inside
        else:
            inside = np.maximum(x, lo + START_OFFSET)
            params[name] = np.sqrt(inside - lo) if problem.mapped else inside
        params[name] = np.asarray(params[name], dtype=float)
    return params


def _values(robot: Robot, motion: Motion, metrics: tuple) -> Array:
    return jnp.stack([jnp.asarray(resolve_metric(m)(robot, motion)) for m in metrics])


def _combine(values: Array, constrained: Array, problem: _Problem) -> Scalar:
    """The loss from the metric values of the objective terms and of the constraints."""
    loss = jnp.sum(problem.weights * (values / problem.scales) ** 2)
    if problem.constrained:
        excess = jnp.maximum((constrained - problem.bounds) / problem.bound_scales, 0.0)
        loss = loss + problem.penalty * jnp.sum(excess**2)
    return loss


def _everything(problem: _Problem) -> tuple:
    """The objective terms, then the constraint metrics that are not also terms."""
    return problem.terms + tuple(m for m in problem.constrained if m not in problem.terms)


def _loss_of(candidate: Robot, motion: Motion, problem: _Problem):
    """``(loss, metric values (k,))`` of a robot: objective terms, then constraints."""
    everything = _everything(problem)
    values = _values(candidate, motion, everything)
    where = jnp.asarray([everything.index(m) for m in problem.constrained], dtype=int)
    constrained = values[where] if problem.constrained else None
    return _combine(values[: len(problem.terms)], constrained, problem), values


def _loss_and_values(params, robot: Robot, motion: Motion, problem: _Problem, at_start):
    """:func:`_loss_of` at the parameters ``r``; with ``at_start`` (a traced bool) of
    ``robot`` as given (the scales are then placeholders)."""
    designed = robot.with_design(_to_design(params, problem))
    return _loss_of(given_or(robot, designed, at_start), motion, problem)


def given_or(robot: Robot, designed: Robot, at_start) -> Robot:
    """``robot`` where ``at_start`` (a traced bool), else ``designed`` (same structure),
    leaf by leaf: one program evaluates both the given start and the candidates."""
    dynamic, static = eqx.partition(robot, eqx.is_array)
    chosen = jax.tree_util.tree_map(
        lambda given, new: jnp.where(at_start, given, new),
        dynamic,
        eqx.filter(designed, eqx.is_array),
    )
    return eqx.combine(chosen, static)


def _loss_grad(params, robot: Robot, motion: Motion, problem: _Problem, at_start):
    """Loss, gradient and metric values, and the metrics' scale floors. The caller
    checks the robot before (:func:`~jaxbal._src.robot_checks.check_robot`) and the motion
    and the values on the host: no runtime-error callbacks, so that the compiled program
    is stored in the persistent compilation cache. Runtime checks are off while it is
    traced (line-search trials may be non-finite)."""
    # no straight-line replay: this program runs a few hundred times at most, and the
    # replay's trace and compile time outweigh its faster evaluations (momentum.replayed)
    with runtime_checks(False), replayed(False):
        (loss, values), grad = jax.value_and_grad(_loss_and_values, has_aux=True)(
            params, robot, motion, problem, at_start
        )
    floors = jnp.stack([_floor(robot, motion, m) for m in _everything(problem)])
    return loss, grad, values, floors


def _unflatten(x, layout) -> dict[str, Array]:
    """The parameter dict of the flat ``x`` (``layout``: static ``(name, shape)`` pairs)."""
    params, start = {}, 0
    for name, shape in layout:
        size = int(np.prod(shape, dtype=int))
        params[name] = x[start : start + size].reshape(shape)
        start += size
    return params


#: LLVM optimisation level of the default co-design's program (with XLA:CPU's elemental
#: emitters, :func:`jaxbal._src.config.compiler_options`). The program runs tens of
#: times and is compiled once per structure, so its compile time is most of a first
#: co-design: measured on the 2-core CPU (fresh cache), level 0 instead of 3 cut the
#: DUAL-V's compile 0.57 -> 0.47 s and the 20-variable arm's 0.79 -> 0.51 s, for 1.0 ->
#: 1.6 ms and 0.83 -> 1.24 ms per evaluation (20 and 43 evaluations per co-design). The
#: arithmetic is the same (no fast-math at any level); the tests compare the optima
#: with SLSQP's and with closed forms.
OPTIMIZATION_LEVEL = 0


@cache
def loss_grad_program():
    """The jitted :func:`_loss_grad_flat` (built on first use: its compiler options
    probe the backend, which importing jaxbal must not start)."""
    options = compiler_options(OPTIMIZATION_LEVEL)
    return jax.jit(_loss_grad_flat, static_argnums=(0, 1), compiler_options=options)


def _loss_grad_flat(layout, structure, x, leaves, at_start):
    """:func:`_loss_grad` of the flat parameters ``x``, with the robot, motion and
    problem as a flat list of array leaves (``structure``: their tree and static part):
    the compiled program the default co-design calls once per L-BFGS iteration, with a
    dispatch of microseconds (no pytree filtering per call)."""
    treedef, static = structure
    robot, motion, problem = eqx.combine(jax.tree_util.tree_unflatten(treedef, leaves), static)
    loss, grad, values, floors = _loss_grad(_unflatten(x, layout), robot, motion, problem, at_start)
    grad = jnp.concatenate([jnp.ravel(grad[name]) for name, _ in layout])
    return loss, grad, values, floors


class _Structure:
    """A static argument of ``jit`` whose hash is computed once (hashing a robot's
    static part field by field cost ~0.1 ms per call of the L-BFGS loop). Interned by
    :func:`_structure`: ``jit``'s cache compares a new key with the stored one by
    identity first, and comparing two robots' static parts field by field cost ~50 µs
    per call (the 20-variable arm's co-design: 44 calls)."""

    def __init__(self, value):
        self.value = value
        self._hash = hash(value)

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        return self is other or (isinstance(other, _Structure) and self.value == other.value)

    def __iter__(self):
        return iter(self.value)


#: interned :class:`_Structure` objects (hash -> those seen; least recently used dropped)
_STRUCTURES: OrderedDict = OrderedDict()
_STRUCTURES_KEPT = 64


def _structure(value) -> _Structure:
    """The interned :class:`_Structure` equal to ``value`` (compared once per co-design,
    not once per evaluation)."""
    new = _Structure(value)
    for kept in _STRUCTURES.get(new._hash, ()):
        if kept == new:
            _STRUCTURES.move_to_end(new._hash)
            return kept
    _STRUCTURES.setdefault(new._hash, []).append(new)
    _STRUCTURES.move_to_end(new._hash)
    while len(_STRUCTURES) > _STRUCTURES_KEPT:
        _STRUCTURES.popitem(last=False)
    return new


def loss_grad_function(robot: Robot, motion: Motion, problem: _Problem, layout):
    """``(x, at_start) -> (loss, grad (n,), values, floors)`` (see
    :func:`_loss_grad_flat`); compiled once per structure."""
    dynamic, static = eqx.partition((robot, motion, problem), eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    structure = _structure((treedef, static))
    program = loss_grad_program()

    def call(x, at_start):
        return program(layout, structure, x, leaves, at_start)

    return call


def _combine_numpy(values, constrained, problem: _Problem) -> float:
    """:func:`_combine` in NumPy (the loss of the starting design, on the host)."""
    loss = np.sum(np.asarray(problem.weights) * (values / np.asarray(problem.scales)) ** 2)
    if problem.constrained:
        bounds, scales = np.asarray(problem.bounds), np.asarray(problem.bound_scales)
        excess = np.maximum((constrained - bounds) / scales, 0.0)
        loss = loss + float(problem.penalty) * np.sum(excess**2)
    return float(loss)


def _raise_invalid_start(motion: Motion, names, before) -> None:
    """The named error of a start the compiled co-design flagged (the robot was checked
    before, by ``check_robot``): a non-finite motion, else the non-finite values."""
    for name, value in zip(("q", "qd", "qdd"), motion, strict=True):
        value = np.asarray(value)
        if not np.all(np.isfinite(value)):
            raise ValueError(f"motion {name} must be finite, got {value[~np.isfinite(value)]!r}")
    listed = {n: float(v) for n, v in zip(names, before, strict=True)}
    raise ValueError(f"metrics of the starting design are not finite: {listed}")


def design_loss(params: dict[str, Array], robot: Robot, motion: Motion, problem: _Problem):
    """The co-design loss (module doc) at the parameters ``r`` (module level: the
    compiled L-BFGS loop of :func:`jaxbal.minimize` is cached on its identity)."""
    return _loss_of(robot.with_design(_to_design(params, problem)), motion, problem)[0]


def _floor(robot: Robot, motion: Motion, metric) -> Scalar:
    """Scale floor of a metric: the bare robot's mass or base inertia for the added
    ones, :data:`SCALE_FLOOR` otherwise."""
    if metric not in ("added_mass", "added_inertia"):
        return jnp.asarray(SCALE_FLOOR)
    design = robot.design()
    bare = robot.with_design(
        {n: jnp.zeros_like(design[n]) for n in ADDED_MASS_VARIABLES if n in design}
    )
    reference = total_mass(bare) if metric == "added_mass" else base_inertia(bare, motion.q[0])
    return jnp.maximum(reference, SCALE_FLOOR)


def _objective_terms(objective) -> tuple[tuple, tuple[float, ...]]:
    if isinstance(objective, Mapping):
        if not objective:
            raise ValueError("objective dict is empty; give {metric name: weight}")
        terms, weights = tuple(objective), tuple(float(w) for w in objective.values())
    else:
        terms, weights = (objective,), (1.0,)
    for term in terms:
        resolve_metric(term)
        check_hashable(term)  # the compiled loss is keyed on it
    if not all(np.isfinite(w) and w >= 0 for w in weights):
        raise ValueError(f"objective weights must be finite and non-negative, got {weights}")
    return terms, weights


def _bounds(robot, free, lower, upper):
    design = robot.design()
    merged = dict(robot.design_lower_bounds())
    merged.update(lower or {})
    check_design_names(robot, merged)
    check_design_names(robot, upper or {})
    lows, highs, two_sided = [], [], []
    for name in free:
        shape = np.shape(design[name])
        lo = finite_array(f"lower[{name!r}]", merged.get(name, 0.0), shape)
        two = upper is not None and name in upper
        hi = finite_array(f"upper[{name!r}]", upper[name], shape) if two else lo
        if two and not np.all(hi > lo):
            raise ValueError(f"upper[{name!r}] = {hi!r} must exceed lower = {lo!r}")
        lows.append(np.asarray(lo, dtype=float))
        highs.append(np.asarray(hi, dtype=float))
        two_sided.append(bool(two))
    check_lower_bounds(robot, free, lows)
    return tuple(lows), tuple(highs), tuple(two_sided)


@eqx.filter_jit
def _evaluate(robot: Robot, motion: Motion, metrics: tuple):
    """Values and scale floors of ``metrics`` (jit-compiled, cached on the structure)."""
    floors = jnp.stack([_floor(robot, motion, m) for m in metrics])
    return _values(robot, motion, metrics), floors


@eqx.filter_jit
def _designed(robot: Robot, params, problem: _Problem):
    """The robot at the optimiser's parameters and its design variables (compiled once
    per structure)."""
    optimised = robot.with_design(_to_design(params, problem))
    return optimised, optimised.design()
