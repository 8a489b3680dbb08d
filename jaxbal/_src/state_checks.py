"""Checks of a robot's state ``(q, q̇, q̈)`` shared by the physics functions
(:func:`jaxbal.shaking_wrench`, :func:`jaxbal.inverse_dynamics`, the regressor): the
shapes at trace time; the finiteness and a closed chain's loop closures eagerly or inside
compiled code."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxbal._src.loop_checks import MESSAGE as LOOP_MESSAGE
from jaxbal._src.loop_checks import check_loops_eagerly, closure_excess
from jaxbal._src.motion import has_loops
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_leaves
from jaxbal._src.validation import (
    _under_trace,
    check_shape,
    guard,
    is_traced,
    runtime_checks_enabled,
)

#: the message of a non-finite state (the offending values follow it)
MESSAGE = "non-finite state (q, qd, qdd)"


class StateCheck:
    """The checks of one state, applied to the outputs computed from it
    (:func:`state_check`).

    Calling it guards the outputs with the state's finiteness (message ``non-finite
    state (q, qd, qdd)``, the state as offending values). :meth:`loops` guards them with
    a closed chain's loop closures (:mod:`jaxbal._src.loop_checks`); ``traced_loops``
    tells the caller whether that check is traced (a closed chain under a trace with the
    runtime checks on), so that it computes the residual with its physics.
    """

    def __init__(self, robot: Robot, state: tuple, concrete: bool, loops: bool, given=None):
        self.robot, self.state, self.concrete, self.given = robot, state, concrete, given
        # eagerly (concrete robot and state, outside any trace: a closed-over state
        # under a user's jit is staged, its compiled check would give a tracer)
        self.eager_loops = loops and concrete and not is_traced(robot) and not _under_trace()
        self.traced_loops = (
            loops and not self.eager_loops and runtime_checks_enabled() and has_loops(robot)
        )

    def __call__(self, outputs):
        if self.concrete or not runtime_checks_enabled():
            return outputs  # checked at once, or nothing traced for a check that is off
        q, qd, qdd = self.state
        # elementwise, not of a stacked copy: XLA wrote the stacked batch to memory
        invalid = ~(jnp.isfinite(q) & jnp.isfinite(qd) & jnp.isfinite(qdd))
        return guard(outputs, invalid, MESSAGE, self.state)

    def loops(self, outputs, excess=None):
        """``outputs`` guarded by the loop closures, to be applied after the robot's own
        checks (a negative length is named as such, not as the loops it opens): eagerly
        the whole state (Φ, Φ̇, Φ̈); traced, ``excess`` (the
        :func:`~jaxbal._src.loop_checks.closure_excess` the caller computed with its
        outputs; else computed here)."""
        if self.eager_loops:
            check_loops_eagerly(self.robot, *self.state, given=self.given)
        if not (self.traced_loops and runtime_checks_enabled()):
            return outputs
        excess = closure_excess(self.robot, self.state[0]) if excess is None else excess
        return guard(outputs, ~(excess <= 1.0), LOOP_MESSAGE, excess)


def state_check(robot: Robot, q, qd, qdd, loops: bool = False, gravity=None):
    """``(q, q̇, q̈, check)``: the state as float arrays, shape-checked ``(dof,)``, and its
    :class:`StateCheck`; ``loops``: the physics of a *motion* of the robot (the shaking
    wrench, the actuator torques), whose closed chain must close its loops.

    Under ``jit`` the guard is applied to the outputs rather than threaded through the
    state: a runtime check's value passes a barrier (a ``cond``), and a state taken
    through it is stacked, copied and sliced before any physics can fuse with it, which
    cost the DUAL-V's vmapped wrench ~2x (one fused loop became about twenty). A
    concrete state is checked at once for finiteness, before anything is evaluated, and
    so is a concrete ``gravity`` (a NaN one was reported as an overflow of the robot's
    largest parameter)."""
    given = (q, qd, qdd)
    q, qd, qdd = (jnp.asarray(a, dtype=float) for a in given)
    for name, value in (("q", q), ("qd", qd), ("qdd", qdd)):
        check_shape(name, value, (robot.dof,))
    check_leaves(robot)
    concrete = not is_traced(q, qd, qdd)
    if concrete:  # concrete (even inside a jit): checked in NumPy now
        state = np.stack([np.asarray(q), np.asarray(qd), np.asarray(qdd)])
        guard(None, ~np.isfinite(state), MESSAGE, state)
    if gravity is not None and not is_traced(gravity):
        g = np.asarray(gravity, dtype=float)
        guard(None, ~np.isfinite(g), "gravity must be finite [m/s^2]", g)
    return q, qd, qdd, StateCheck(robot, (q, qd, qdd), concrete, loops, given)


def checked_state(robot: Robot, q, qd, qdd):
    """``(q, q̇, q̈)`` as float arrays, shape-checked ``(dof,)`` and checked finite, the
    check threaded through the state (the form :func:`state_check` replaced; kept as the
    benchmark's baseline, benchmarks/wrench_bench.py)."""
    q, qd, qdd, check = state_check(robot, q, qd, qdd)
    state = check(jnp.stack([q, qd, qdd]))
    return state[0], state[1], state[2]
