"""Peak metrics differentiated at their peak sample.

A peak metric is a maximum over the samples of a motion: ``max_t ‖v(t)‖`` (peak force,
moment, torque) or ``max_t max_i |v_i(t)|`` (peak torque rate, per actuator). Wherever
the maximising sample (and component) is unique, the maximum equals that one sample's
value in a neighbourhood, so its derivative is the derivative of that sample alone.
Under a trace these metrics are ``custom_jvp`` functions: a plain evaluation (a sweep,
a value) evaluates every sample and nothing else, and a derivative (``jvp``, ``grad``,
of any order) re-evaluates the one peak sample with tangents. ``grad`` then costs
about one evaluation, instead of reverse mode through every sample (~3× the value, and
for the torque rate -- itself a ``jvp`` of the torques, a Kane ``vjp`` -- a program
that took ~15 s to compile for the 3R's COM plan). At an exact tie the derivative is
the one at the first maximiser (a subgradient; ``jnp.max`` would average them).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from jaxbal._src.along_motion import batched, samples
from jaxbal._src.momentum import replayed
from jaxbal._src.motion_samples import Motion, as_motion
from jaxbal._src.planning import peak_norm
from jaxbal._src.robot import Robot
from jaxbal._src.types import Scalar
from jaxbal._src.validation import is_traced, runtime_checks


def unit_scale(vectors):
    """``max |v|`` when the squares of ``vectors`` would overflow (> 1e150), else 1 (exact:
    the usual values are unchanged); no gradient."""
    big = jax.lax.stop_gradient(jnp.max(jnp.abs(vectors), initial=0.0))
    return jnp.where(big > 1e150, big, 1.0)


def peak(evaluate, pick, robot: Robot, motion: Motion, what: str) -> Scalar:
    """``max_t ‖pick(evaluate(robot, q_t, q̇_t, q̈_t))‖`` (:func:`peak_norm` of every
    sample), differentiated at its peak sample (module doc)."""
    motion = as_motion(motion)
    if not is_traced(robot, motion):
        return peak_norm(pick(batched(evaluate, robot, motion, what)))
    return _peak_traced(evaluate, pick, robot, motion)


def peak_abs(evaluate, robot: Robot, motion, what: str) -> Scalar:
    """``max_t max_i |evaluate(robot, *state_t)_i|`` over the samples of ``motion`` (all
    its parts are states, e.g. a :class:`~jaxbal.metrics.JerkMotion`), differentiated at
    its peak sample and component (module doc)."""
    if not is_traced(robot, motion):
        return jnp.max(jnp.abs(batched(evaluate, robot, motion, what, jerk=True)))
    return _peak_abs_traced(evaluate, robot, motion)


@partial(jax.custom_jvp, nondiff_argnums=(0, 1))
def _peak_traced(evaluate, pick, robot, motion):
    return peak_norm(pick(samples(evaluate, robot, motion)))


def _peak_traced_jvp(evaluate, pick, primals, tangents):
    robot, motion = primals
    vectors = pick(samples(evaluate, robot, motion))
    index = jnp.argmax(jnp.sum(jnp.square(vectors / unit_scale(vectors)), axis=-1))

    def at_peak(*state):
        return peak_norm(pick(evaluate(*state))[None])

    return peak_norm(vectors), _tangent_at(at_peak, primals, tangents, index)


_peak_traced.defjvp(_peak_traced_jvp, symbolic_zeros=True)


@partial(jax.custom_jvp, nondiff_argnums=(0,))
def _peak_abs_traced(evaluate, robot, motion):
    return jnp.max(jnp.abs(samples(evaluate, robot, motion)))


def _peak_abs_jvp(evaluate, primals, tangents):
    robot, motion = primals
    values = samples(evaluate, robot, motion)
    values = values.reshape(values.shape[0], -1)
    flat = jnp.argmax(jnp.abs(values).reshape(-1))
    index, component = jnp.divmod(flat, values.shape[1])

    def at_peak(*state):
        return jnp.abs(jnp.ravel(evaluate(*state))[component])

    return jnp.max(jnp.abs(values)), _tangent_at(at_peak, primals, tangents, index)


_peak_abs_traced.defjvp(_peak_abs_jvp, symbolic_zeros=True)


def _tangent_at(at_peak, primals, tangents, index):
    """Tangent of ``at_peak(robot, *(part[index] for part in motion))``: only the inputs
    with a tangent are differentiated, the others stay constants of the re-evaluation,
    as they are of the evaluation of every sample. The values were checked by that
    evaluation (same robot, same states): the re-evaluation runs without its own runtime
    checks. It is one sample, not a batch, so it is evaluated as written, without the
    straight-line replay (:func:`~jaxbal._src.momentum.replayed`): the replay's gain is
    XLA fusing its scalar code across the batch, while for a single sample its ~1,000
    scalar operations compile to more kernels than the array code (measured on the
    2-core CPU: DUAL-V peak-force gradient ~75 → ~50 µs against a ~35 µs value, first
    gradient 1.65 → 1.43 s)."""
    leaves, treedef = jax.tree_util.tree_flatten(primals)
    directions = jax.tree_util.tree_leaves(tangents, is_leaf=lambda t: isinstance(t, SymbolicZero))
    active = [not isinstance(t, SymbolicZero) for t in directions]

    def local(*moving):
        it = iter(moving)
        full = [next(it) if a else leaf for leaf, a in zip(leaves, active, strict=True)]
        robot, motion = jax.tree_util.tree_unflatten(treedef, full)
        return at_peak(robot, *(part[index] for part in motion))

    moving = [leaf for leaf, a in zip(leaves, active, strict=True) if a]
    directions = [t for t, a in zip(directions, active, strict=True) if a]
    with runtime_checks(False), replayed(False):
        _, derivative = jax.jvp(local, moving, directions)
    return derivative
