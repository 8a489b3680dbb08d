"""The benchmark cases: the five built-in robots on a straight end-effector move, and
the hand-written closed form of the 2R shaking wrench (the speed limit).

The moves are those of the contract tests (tests/test_contract.py): a 0.2 s quintic
straight line between two reachable poses, sampled at 1,000 instants through the
robot's inverse kinematics (loop closures included), so every state is consistent.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxbal
from jaxbal.design import motion_samples
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic

#: name -> (constructor, reachable start pose, reachable end pose)
MOVES = {
    "planar_2r": (jaxbal.robots.planar_2r, (0.4, 0.3), (0.2, 0.5)),
    "planar_3r": (jaxbal.robots.planar_3r, (0.4, 0.3, 0.5), (0.2, 0.5, 1.0)),
    "scara": (jaxbal.robots.scara, (0.15, 0.2, 1.4, 0.0), (-0.15, 0.2, 2.7, 0.05)),
    "dual_v": (jaxbal.robots.dual_v, (0.0, -0.05, 0.0), (0.05, 0.05, 0.0)),
    "orthoglide": (
        lambda: jaxbal.robots.orthoglide(payload=1.0),
        (0.0, 0.0, 0.0),
        (-0.1, 0.07, -0.11),
    ),
}
DURATION = 0.2  # [s]
SAMPLES = 1000


def robot_and_motion(name: str):
    """``(robot, Motion)`` of ``SAMPLES`` consistent states along the move of ``name``."""
    make, start, end = MOVES[name]
    robot = make()
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), DURATION)
    times = jnp.linspace(0.0, DURATION, SAMPLES)
    return robot, motion_samples(robot, EndEffectorLine(robot, line), times)


def tiled_states(motion, count: int, seed: int = 0):
    """``count`` states: the move's states repeated, velocities and accelerations scaled
    by random factors in [0.5, 2] (still consistent states of a faster or slower move
    only for ``q``; the wrench does not require loop-consistent rates)."""
    reps = -(-count // motion.q.shape[0])
    q, qd, qdd = (jnp.tile(a, (reps, 1))[:count] for a in motion)
    scale = jnp.asarray(np.random.default_rng(seed).uniform(0.5, 2.0, (count, 1)))
    return q, qd * scale, qdd * scale**2


def closed_form_2r(arm: jaxbal.robots.PlanarArm):
    """Hand-written JAX closed form of the 2R shaking wrench (links + tip payload;
    Briot et al. 2012, eq 1 with x_S of eq 7): two sines, two cosines, a few products.
    Returns a function ``(q, qd, qdd) -> (force (3,), moment (3,))`` of one state."""
    (l1, l2), (r1, r2) = arm.lengths, arm.com_ratios
    (m1, m2), mt, (i1, i2) = arm.masses, arm.payload, arm.inertias

    def wrench(q, qd, qdd):
        t12, w1, w12 = q[0] + q[1], qd[0], qd[0] + qd[1]
        a1, a12 = qdd[0], qdd[0] + qdd[1]
        c1, s1, c12, s12 = jnp.cos(q[0]), jnp.sin(q[0]), jnp.cos(t12), jnp.sin(t12)
        # Accelerations of the unit points at angle θ1 and θ1+θ2, and first moments.
        ax1, ay1 = -a1 * s1 - w1**2 * c1, a1 * c1 - w1**2 * s1
        ax2, ay2 = -a12 * s12 - w12**2 * c12, a12 * c12 - w12**2 * s12
        k1 = (m1 * r1 + m2 + mt) * l1  # Σ m_i × (lever along link 1)
        k2 = (m2 * r2 + mt) * l2
        fx, fy = -(k1 * ax1 + k2 * ax2), -(k1 * ay1 + k2 * ay2)
        # Moment: Σ m x × a, expanded over the two unit vectors.
        j11 = (m1 * r1**2 + m2 + mt) * l1**2
        j22 = (m2 * r2**2 + mt) * l2**2
        j12 = (m2 * r2 + mt) * l1 * l2
        cross11 = c1 * ay1 - s1 * ax1
        cross22 = c12 * ay2 - s12 * ax2
        cross12 = c1 * ay2 - s1 * ax2 + c12 * ay1 - s12 * ax1
        mz = -(j11 * cross11 + j22 * cross22 + j12 * cross12) - i1 * a1 - i2 * a12
        zero = jnp.zeros_like(fx)
        return jnp.stack([fx, fy, zero]), jnp.stack([zero, zero, mz])

    return wrench


def _chunk_loop(fn, chunk: int):
    """``(q, qd, qdd) -> outputs`` of ``fn`` (one state) over ``(N, ·)`` states, ``vmap``
    over chunks of ``chunk`` states in a loop. Each chunk is a dynamic slice of the
    inputs (the last one overlaps its predecessor when ``chunk`` does not divide ``N``):
    ``lax.map(batch_size=)`` copies every input first when it does not (the first
    ``N − N mod chunk`` rows, reshaped), which cost more than the DUAL-V's wrench itself
    (~100 ns per 11-coordinate state on the 2-core CPU)."""
    batched = jax.vmap(fn)

    def run(*states):
        n = states[0].shape[0]
        size = min(chunk, n)
        shapes = jax.eval_shape(batched, *(x[:size] for x in states))
        outs = jax.tree_util.tree_map(lambda s: jnp.zeros((n, *s.shape[1:]), s.dtype), shapes)

        def body(i, outs):
            start = jnp.minimum(i * size, n - size)
            part = batched(*(jax.lax.dynamic_slice_in_dim(x, start, size) for x in states))
            return jax.tree_util.tree_map(
                lambda o, p: jax.lax.dynamic_update_slice_in_dim(o, p, start, 0), outs, part
            )

        return jax.lax.fori_loop(0, -(-n // size), body, outs)

    return run


def chunked(fn, chunk: int):
    """``jit`` of ``fn`` (one state) over ``(N, ·)`` states in chunks of ``chunk``."""
    return jax.jit(_chunk_loop(fn, chunk))


def sharded(fn, chunk: int):
    """Like :func:`chunked`, with the states split over all local devices (``pmap``)."""
    devices = jax.local_device_count()

    mapped = jax.pmap(_chunk_loop(fn, chunk))

    def call(q, qd, qdd):
        usable = q.shape[0] - q.shape[0] % devices
        args = (a[:usable].reshape(devices, usable // devices, -1) for a in (q, qd, qdd))
        return mapped(*args)

    return call, devices
