"""Checks of a robot's state ``(q, q̇, q̈)`` shared by the physics functions
(:func:`jaxbal.shaking_wrench`, :func:`jaxbal.inverse_dynamics`, the regressor): the
shapes at trace time, the finiteness eagerly or inside compiled code."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxbal._src.robot import Robot
from jaxbal._src.validation import check_shape, guard, is_traced, runtime_checks_enabled

#: the message of a non-finite state (the offending values follow it)
MESSAGE = "non-finite state (q, qd, qdd)"


def state_check(robot: Robot, q, qd, qdd):
    """``(q, q̇, q̈, check)``: the state as float arrays, shape-checked ``(dof,)``, and
    ``check(outputs)`` that guards the outputs computed from it with the state's
    finiteness (message ``non-finite state (q, qd, qdd)``, the state as offending values).

    Under ``jit`` the guard is applied to the outputs rather than threaded through the
    state: a runtime check's value passes a barrier (a ``cond``), and a state taken
    through it is stacked, copied and sliced before any physics can fuse with it, which
    cost the DUAL-V's vmapped wrench ~2x (one fused loop became about twenty). A
    concrete state is checked at once, before anything is evaluated."""
    q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))
    for name, value in (("q", q), ("qd", qd), ("qdd", qdd)):
        check_shape(name, value, (robot.dof,))

    def check(outputs):
        if not runtime_checks_enabled():
            return outputs  # nothing traced for a check that is off
        # elementwise, not of a stacked copy: XLA wrote the stacked batch to memory
        invalid = ~(jnp.isfinite(q) & jnp.isfinite(qd) & jnp.isfinite(qdd))
        return guard(outputs, invalid, MESSAGE, (q, qd, qdd))

    if not is_traced(q, qd, qdd):  # concrete (even inside a jit): checked in NumPy now
        state = np.stack([np.asarray(q), np.asarray(qd), np.asarray(qdd)])
        guard(None, ~np.isfinite(state), MESSAGE, state)
        return q, qd, qdd, lambda outputs: outputs
    return q, qd, qdd, check


def checked_state(robot: Robot, q, qd, qdd):
    """``(q, q̇, q̈)`` as float arrays, shape-checked ``(dof,)`` and checked finite, the
    check threaded through the state (the form :func:`state_check` replaced; kept as the
    benchmark's baseline, benchmarks/wrench_bench.py)."""
    q, qd, qdd, check = state_check(robot, q, qd, qdd)
    state = check(jnp.stack([q, qd, qdd]))
    return state[0], state[1], state[2]
