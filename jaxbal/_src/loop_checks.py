"""The loop-closure check of a closed chain's state in the physics of its motion.

A parallel robot's coordinates ``q`` are those of *all* its bodies; a state ``(q, q̇,
q̈)`` is a motion of the robot only if it satisfies the loop closures ``Φ(q) = 0`` and
their first two time derivatives (:meth:`jaxbal.Robot.constraint`). A state that does
not (a motion built for another geometry, then the robot's lengths changed with
``eqx.tree_at`` or by a design variable; a state made by hand) gives finite, meaningless
wrenches and torques: found by ``make fuzz``, an Orthoglide whose parallelograms were
scaled by 1e-8 under a held motion gave 3e42 N·m. The shaking wrench, the actuator
torques and the metrics along a motion therefore refuse such a state, as they refuse a
non-finite one: eagerly with ``ValueError``, under ``jit`` at run time while the runtime
checks are on (:func:`jaxbal.set_runtime_checks`). The generalised forces
(:func:`jaxbal.inverse_dynamics`) are defined for any state and do not check.

What is checked where. Eagerly (a notebook's call on concrete values: the single-state
functions, the metrics along a :class:`~jaxbal.design.Motion`) the whole state, ``Φ``,
``Φ̇`` and ``Φ̈`` (:func:`~jaxbal._src.motion.loop_excess`, the test of
:func:`jaxbal.state_valid`), as the motion builders (:func:`jaxbal.joint_motion`,
:func:`~jaxbal.design.motion_samples`) do. Compiled, the positions ``Φ(q)``
(:func:`closure_excess`), computed with the wrench or the generalised forces as one
straight-line program (:func:`with_closure_excess`) that shares their sines and cosines:
the samples of a smooth motion whose positions close the loops have consistent rates
(``Φ(q(t)) ≡ 0`` implies ``Φ̇ = Φ̈ = 0``), and a motion held while the geometry changed
fails it; only a state whose rates were made by hand passes it, and the
eager checks and the motion builders refuse that one. Measured on the 2-core CPU,
chunked ``jit(vmap)`` of the checked wrench: DUAL-V +20 % (with ``Φ̇``, ``Φ̈`` +42 %),
Orthoglide +7 % (+12 %). ``jaxbal.set_runtime_checks(False)`` removes it with the
other compiled checks.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.motion import LOOP_TOLERANCE, has_loops, loop_excess
from jaxbal._src.robot import Robot
from jaxbal._src.types import Array, Scalar

#: the message of a state off the loop closures (the largest relative residual follows)
MESSAGE = (
    "state violates the loop closures (the robot's constraints) beyond the tolerance of "
    f"jaxbal.state_valid ({LOOP_TOLERANCE:g}): was the motion built for another geometry "
    "(a length changed with eqx.tree_at or as a design variable)? Rebuild it for this "
    "robot (jaxbal.design.motion_samples, jaxbal.joint_motion, a motion factory). "
    "Residual / tolerance"
)


def closure_excess(robot: Robot, q) -> Scalar:
    """``max |Φ(q)| / LOOP_TOLERANCE``: the positions' part of :func:`loop_excess` (the
    compiled check, module doc)."""
    return jnp.max(jnp.abs(robot.constraint(q))) / LOOP_TOLERANCE


def with_closure_excess(physics):
    """``physics(robot, q, q̇, q̈, gravity)`` returning ``(output, closure_excess)``: one
    function, so that its straight-line replay computes both from shared terms."""

    def both(robot: Robot, q, qd, qdd, gravity):
        return physics(robot, q, qd, qdd, gravity), closure_excess(robot, q)

    both.__name__ = both.__qualname__ = f"{physics.__name__}_with_closure_excess"
    return both


def loops_faulty(robot: Robot, q, qd, qdd) -> Array:
    """Scalar bool (traceable, never raises): is a state of a closed chain off its loops
    (a non-finite excess included)? False for a robot without loops."""
    if not has_loops(robot):
        return jnp.asarray(False)
    return ~(loop_excess(robot, q, qd, qdd) <= 1.0)


def _precision(*states) -> str:
    """A hint for a state given in less than float64 (its rounding, ~1e-7 relative in
    float32, is above the tolerance: the message's question about the geometry would
    mislead), else ``""``."""
    dtypes = {getattr(x, "dtype", np.dtype(float)) for x in states}
    low = sorted(str(d) for d in dtypes if jnp.issubdtype(d, jnp.floating) and d.itemsize < 8)
    if not low:
        return ""
    return (
        f" [the state is {', '.join(low)}: its rounding alone exceeds the tolerance; "
        "jaxbal computes in float64: pass float64 arrays]"
    )


def check_loops_eagerly(robot: Robot, q, qd, qdd, given=None) -> None:
    """Raise ``ValueError`` (:data:`MESSAGE` and the relative residual) if a concrete
    state of a closed chain is off its loops (one small program compiled per robot
    structure, not operation by operation). The state is finite (checked before): a
    residual that overflows is refused too, as the compiled check does. ``given``: the
    state as the caller passed it (before its conversion to float64), for the hint of a
    float32 state."""
    if not has_loops(robot):
        return
    excess = float(_excesses(robot, q[None], qd[None], qdd[None])[0])
    if not excess <= 1.0:
        hint = _precision(*(given or (q, qd, qdd)))
        raise ValueError(f"{MESSAGE}: {excess:.3g}{hint}")


@eqx.filter_jit
def _excesses(robot: Robot, q, qd, qdd):
    return jax.vmap(lambda a, b, c: loop_excess(robot, a, b, c))(q, qd, qdd)


def check_samples_eagerly(robot: Robot, q, qd, qdd) -> None:
    """Raise ``ValueError`` naming the samples (rows of the ``(t, dof)`` states) of a
    closed chain that are off its loops, with their relative residuals (one program
    compiled per robot structure and sample count). Non-finite states are left to the
    state check, which names them."""
    if not has_loops(robot):
        return
    if not all(np.all(np.isfinite(np.asarray(x))) for x in (q, qd, qdd)):
        return
    excess = np.asarray(_excesses(robot, q, qd, qdd))
    bad = np.flatnonzero(~(excess <= 1.0))  # the states are finite (checked before)
    if bad.size:
        listed = {int(k): float(f"{excess[k]:.3g}") for k in bad[:8]}
        more = f" (and {bad.size - 8} more)" if bad.size > 8 else ""
        hint = _precision(q, qd, qdd)
        raise ValueError(f"{MESSAGE} at samples {{sample: residual}}: {listed}{more}{hint}")
