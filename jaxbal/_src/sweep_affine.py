"""The shaking wrench along a fixed motion as an affine function of the swept robot
parameters: the fast path of :func:`jaxbal.sweep` for mass-type sweeps.

Along a fixed joint motion, the shaking wrench is linear in every body's mass, first
moment and inertia (Newton-Euler: ``f = −Σ m_i a_i``, ``m = −Σ (m_i c_i × a_i + I_i α_i
+ ω_i × I_i ω_i)``, the kinematics ``a_i, α_i, ω_i`` independent of the masses), so
when a sweep changes only masses and inertias (counter-masses, payloads, tuning
masses), at every sample ``t``

    w(t; θ) = w(t; θ₀) + J(t) (θ − θ₀),       J(t) = ∂w(t)/∂θ,

exactly. :func:`affine_model` evaluates ``w(·; 0)`` and ``J`` once, along all samples
(one ``jacfwd``), at ``θ₀ = 0`` (every swept mass zero: the terms are then summed as
the direct evaluation sums ``Σ m_i a_i``, and a point whose masses are all zero gives an
exact zero, as directly), or at the sweep's first point when the robot's model is
affine only away from zero; each point then costs ``t × 3 × p``
multiply-adds (``p`` swept scalars) instead of the robot's kinematics and dynamics at
every sample. The named wrench metrics (``peak_force``, ``rms_force``, ``peak_moment``,
``rms_moment``) reduce it as the direct metrics do (:func:`~jaxbal._src.planning.peak_norm`,
the RMS); the robot at each point is still built and its mass and parameter checks run.

Affinity is *verified*, never assumed: the direct wrench at :data:`CHECK_POINTS` points
of the sweep (its two extreme corners and random points of the grid, fixed seed) must
equal the affine model to :data:`TOLERANCE` of the wrench's gross scale, force and
moment apart. A parameter that enters nonlinearly (a counter-mass *distance*, a link
length) fails this by many orders of magnitude (a relative deviation of ~1e-2 against
1e-9), and the sweep evaluates the metric directly instead (``linear="auto"``) or
raises (``linear=True``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.momentum import shaking_wrench
from jaxbal._src.robot_checks import checked_bodies, checked_parameters
from jaxbal._src.sweep_program import PROGRAM_JITS, apply_parameters
from jaxbal._src.validation import runtime_checks

__all__ = ["CHECK_POINTS", "TOLERANCE", "WRENCH_METRICS", "AffineMetric", "AffineWrench",
           "affine_model"]  # fmt: skip

#: named metrics with an affine fast path: name -> (part, reduction); part 0 the force,
#: 1 the moment about the base origin.
WRENCH_METRICS = {
    "peak_force": (0, "peak"),
    "rms_force": (0, "rms"),
    "peak_moment": (1, "peak"),
    "rms_moment": (1, "rms"),
}
#: largest deviation of the affine model from the direct wrench, relative to the gross
#: scale ``max|w(θ₀)| + max_t Σ_k |J_k(t)·(θ − θ₀)_k|`` (rounding is ~1e-15 of it).
TOLERANCE = 1e-9
#: points of the sweep at which the direct wrench checks the affine model.
CHECK_POINTS = 8


class AffineWrench(eqx.Module):
    """The shaking wrench along a fixed motion, affine in the swept parameters.

    Attributes:
        robot: the robot the sweep was given (its values at the swept parameters are
            replaced at every point, for the mass and parameter checks).
        values: the swept parameters at this point ``{name: array}`` (the model's
            design: ``design()``/``with_design`` as a robot's).
        origin: ``(p,)`` the flat parameters ``θ₀`` where ``offset`` and ``basis``
            were evaluated (zero, or the sweep's first point).
        offset: ``(2, 3, t)`` force [N] and moment [N·m] at ``θ₀`` (components first:
            the samples are the contiguous, vectorised axis).
        basis: ``(2, p, 3, t)`` their derivatives in the ``p`` swept scalars.
        offset_max, basis_max: ``(2,)`` and ``(2, p)`` largest magnitudes of each, for
            an overflow-safe scale without a pass over the samples.
        plan: how each parameter reaches the robot (as in a sweep's program).
    """

    robot: object
    values: dict
    origin: jax.Array
    offset: jax.Array
    basis: jax.Array
    offset_max: jax.Array
    basis_max: jax.Array
    plan: tuple = eqx.field(static=True)

    def design(self) -> dict:
        return dict(self.values)

    def with_design(self, design: dict) -> AffineWrench:
        return eqx.tree_at(lambda m: m.values, self, {**self.values, **design})

    def squares(self, index: int) -> tuple[jax.Array, jax.Array]:
        """``(‖v(t)/s‖², s)``: the squared norms ``(t,)`` of the force (0) or moment (1)
        at :attr:`values`, divided by a power of two ``s`` (1 unless the magnitudes may
        exceed 1e150, so that the squares never overflow; a power of two scales
        exactly, short of an underflow)."""
        delta = _flat(self.values, self.plan) - self.origin
        bound = self.offset_max[index] + jnp.sum(self.basis_max[index] * jnp.abs(delta))
        scale = jnp.where(bound > 1e150, jnp.exp2(jnp.ceil(jnp.log2(bound))), 1.0)
        inverse = 1.0 / scale
        squares = 0.0
        # one (t,) array per component, sums in a fixed order: XLA fuses the whole point
        # into one vectorised loop over the samples (a (3, t) array and its slices were
        # materialised, 3.7× slower), and no batch-size-dependent dot changes the rounding
        for c in range(3):
            component = self.offset[index, c]
            for k in range(self.basis.shape[1]):
                component = component + self.basis[index, k, c] * delta[k]
            squares = squares + jnp.square(component * inverse)
        return squares, scale


@dataclass(frozen=True)
class AffineMetric:
    """A named wrench metric of an :class:`AffineWrench` (hashable, picklable): the
    peak ``s·sqrt(max_t ‖v/s‖²)`` (= ``max_t ‖v‖``: the square root is monotone) or
    the RMS ``s·sqrt(mean_t ‖v/s‖²)``."""

    name: str

    def __call__(self, model: AffineWrench, motion=None):
        index, reduction = WRENCH_METRICS[self.name]
        squares, scale = model.squares(index)
        reduced = jnp.max(squares) if reduction == "peak" else jnp.mean(squares)
        value = scale * jnp.sqrt(reduced)
        robot, _ = apply_parameters(model.robot, model.plan, model.values)
        return checked_parameters(robot, checked_bodies(robot, value))


def _flat(values: dict, plan: tuple) -> jax.Array:
    return jnp.concatenate([jnp.ravel(jnp.asarray(values[name], float)) for name, _, _ in plan])


def _point(axes: dict, index: tuple) -> dict:
    return {n: np.asarray(v[i]) for (a, i) in zip(axes.values(), index, strict=True)
            for n, v in a.values.items()}  # fmt: skip


def _check_indices(axes: dict) -> list[tuple]:
    sizes = [a.size for a in axes.values()]
    rng = np.random.default_rng(0)
    corners = [tuple(0 for _ in sizes), tuple(s - 1 for s in sizes)]
    random = [tuple(int(rng.integers(s)) for s in sizes) for _ in range(CHECK_POINTS - 2)]
    return corners + random


def _unflatten(flat, layout: tuple) -> dict:
    """``{name: array}`` from the flat parameter vector; ``layout``: ``((name, shape), …)``."""
    sizes = [int(np.prod(shape, dtype=int)) for _, shape in layout]
    parts = jnp.split(flat, np.cumsum(sizes)[:-1].tolist())
    return {name: p.reshape(shape) for (name, shape), p in zip(layout, parts, strict=True)}


def _wrench(plan, layout, robot, motion, flat):
    """``(2, t, 3)`` force and moment along ``motion`` at the flat parameters.

    Traced without runtime checks, always (so the compiled function never depends on
    the global setting): a check point may be non-physical (a negative mass set through
    a setter); the sweep's own evaluation checks every point, and a non-finite wrench
    here fails the affinity check (the sweep then runs directly and raises there)."""
    with runtime_checks(False):
        at, _ = apply_parameters(robot, plan, _unflatten(flat, layout))
        force, moment = jax.vmap(lambda q, qd, qdd: shaking_wrench(at, q, qd, qdd))(*motion)
    return jnp.stack([force, moment])


@partial(jax.jit, static_argnums=(0, 1))
def _linearise(plan, layout, robot, motion, flat):
    """The wrench at ``flat`` and its derivatives ``(2, t, 3, p)`` (one ``jacfwd``)."""
    wrench = partial(_wrench, plan, layout, robot, motion)
    return wrench(flat), jax.jacfwd(wrench)(flat)


@partial(jax.jit, static_argnums=(0, 1))
def _direct(plan, layout, robot, motion, points):
    """The wrench ``(V, 2, t, 3)`` at each of the flat parameter ``points``."""
    return jax.vmap(partial(_wrench, plan, layout, robot, motion))(points)


PROGRAM_JITS += [_linearise, _direct]


def _deviation(offset, basis, theta0, points, direct) -> float:
    deviation = 0.0
    for point, exact in zip(points, direct, strict=True):
        terms = basis * (point - theta0)  # (2, t, 3, p)
        model = offset + jnp.sum(terms, axis=-1)
        for part in range(2):
            gross = jnp.max(jnp.abs(offset[part])) + jnp.max(jnp.sum(jnp.abs(terms[part]), -1))
            error = float(jnp.max(jnp.abs(model[part] - exact[part])))
            gross = float(gross)
            relative = error / gross if gross > 0 else (0.0 if error == 0 else np.inf)
            deviation = max(deviation, relative if np.isfinite(relative) else np.inf)
    return deviation


#: the last models, with the very robot and motion they were built for (a repeated
#: sweep reuses the model's arrays, and so the folded program compiled for them).
_MODELS: list = []


def affine_model(metric: str, robot, motion, axes: dict, plan: tuple):
    """``(model, deviation)``: the :class:`AffineWrench` of ``robot`` along the fixed
    ``motion`` for the sweep's parameters, and the largest deviation of the affine model
    from the direct wrench at the check points, relative to the gross scale (affine
    when ``deviation <= TOLERANCE``). ``model`` is ``None`` when ``metric`` has no
    affine form."""
    if metric not in WRENCH_METRICS:
        return None, np.inf
    shapes = {n: np.shape(v)[1:] for a in axes.values() for n, v in a.values.items()}
    layout = tuple((name, tuple(shapes[name])) for name, _, _ in plan)
    first = _point(axes, tuple(0 for _ in axes))
    points = np.stack([np.asarray(_flat(_point(axes, i), plan)) for i in _check_indices(axes)])
    key = (plan, layout, points.tobytes(), np.asarray(_flat(first, plan)).tobytes())
    for cached_robot, cached_motion, cached_key, result in _MODELS:
        if cached_robot is robot and cached_motion is motion and cached_key == key:
            return result
    direct = _direct(plan, layout, robot, motion, jnp.asarray(points))
    # θ₀ = 0 first (terms summed as directly, exact zeros stay zero); a robot whose
    # model is affine only away from zero (the DUAL-V guards a division by the brass
    # mass with max(m, 1e-12)) is linearised at the sweep's first point instead
    for theta0 in (jnp.zeros(points.shape[1]), _flat(first, plan)):
        offset, basis = _linearise(plan, layout, robot, motion, theta0)
        deviation = _deviation(offset, basis, theta0, jnp.asarray(points), direct)
        if deviation <= TOLERANCE:
            break
    values = {n: jnp.asarray(first[n], float) for n, _ in layout}
    offset = jnp.swapaxes(offset, -1, -2)  # (2, 3, t)
    basis = jnp.moveaxis(basis, -1, 1).swapaxes(-1, -2)  # (2, p, 3, t)
    offset_max = jnp.max(jnp.abs(offset), axis=(-2, -1))
    basis_max = jnp.max(jnp.abs(basis), axis=(-2, -1))
    model = AffineWrench(robot, values, theta0, offset, basis, offset_max, basis_max, plan)
    result = model, deviation
    _MODELS[:] = [(robot, motion, key, result), *_MODELS[:3]]
    return result
