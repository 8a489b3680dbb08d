"""Checks of a robot's state ``(q, q̇, q̈)`` shared by the physics functions
(:func:`jaxbal.shaking_wrench`, :func:`jaxbal.inverse_dynamics`, the regressor): the
shapes at trace time; the finiteness and a closed chain's loop closures eagerly or inside
compiled code."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxbal._src.loop_checks import MESSAGE as LOOP_MESSAGE
from jaxbal._src.loop_checks import check_loops_eagerly, closure_excess, has_loops
from jaxbal._src.robot import Robot
from jaxbal._src.validation import check_shape, guard, is_traced, runtime_checks_enabled

#: the message of a non-finite state (the offending values follow it)
MESSAGE = "non-finite state (q, qd, qdd)"


def state_check(robot: Robot, q, qd, qdd, loops: bool = False):
    """``(q, q̇, q̈, check)``: the state as float arrays, shape-checked ``(dof,)``, and
    ``check(outputs)`` that guards the outputs computed from it with the state's
    finiteness (message ``non-finite state (q, qd, qdd)``, the state as offending values).

    With ``loops`` (the physics of a *motion* of the robot: the shaking wrench, the
    actuator torques), ``check.loops(outputs, excess=None)`` guards them with a closed
    chain's loop closures (:mod:`jaxbal._src.loop_checks`), to be applied after the
    robot's own checks (a negative length is named as such, not as the loops it opens);
    ``excess`` is the :func:`~jaxbal._src.motion.loop_excess` the caller computed with
    its outputs, else it is computed here. ``check.traced_loops`` tells the caller
    whether that check is traced (a closed chain under a trace with the runtime checks
    on), so that it computes the excess with its physics.

    Under ``jit`` the guard is applied to the outputs rather than threaded through the
    state: a runtime check's value passes a barrier (a ``cond``), and a state taken
    through it is stacked, copied and sliced before any physics can fuse with it, which
    cost the DUAL-V's vmapped wrench ~2x (one fused loop became about twenty). A
    concrete state is checked at once for finiteness, before anything is evaluated."""
    q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))
    for name, value in (("q", q), ("qd", qd), ("qdd", qdd)):
        check_shape(name, value, (robot.dof,))
    concrete = not is_traced(q, qd, qdd)
    if concrete:  # concrete (even inside a jit): checked in NumPy now
        state = np.stack([np.asarray(q), np.asarray(qd), np.asarray(qdd)])
        guard(None, ~np.isfinite(state), MESSAGE, state)
    eager_loops = loops and concrete and not is_traced(robot)
    traced_loops = loops and not eager_loops and runtime_checks_enabled() and has_loops(robot)

    def check(outputs):
        if concrete or not runtime_checks_enabled():
            return outputs  # checked above, or nothing traced for a check that is off
        # elementwise, not of a stacked copy: XLA wrote the stacked batch to memory
        invalid = ~(jnp.isfinite(q) & jnp.isfinite(qd) & jnp.isfinite(qdd))
        return guard(outputs, invalid, MESSAGE, (q, qd, qdd))

    def loop_check(outputs, excess=None):
        if eager_loops:
            check_loops_eagerly(robot, q, qd, qdd)
        if not (traced_loops and runtime_checks_enabled()):
            return outputs
        excess = closure_excess(robot, q) if excess is None else excess
        return guard(outputs, ~(excess <= 1.0), LOOP_MESSAGE, excess)

    check.loops = loop_check
    check.traced_loops = traced_loops
    return q, qd, qdd, check


def checked_state(robot: Robot, q, qd, qdd):
    """``(q, q̇, q̈)`` as float arrays, shape-checked ``(dof,)`` and checked finite, the
    check threaded through the state (the form :func:`state_check` replaced; kept as the
    benchmark's baseline, benchmarks/wrench_bench.py)."""
    q, qd, qdd, check = state_check(robot, q, qd, qdd)
    state = check(jnp.stack([q, qd, qdd]))
    return state[0], state[1], state[2]
