"""The check of a solver's output (an inverse kinematics, a loop closure, a COM plan's
join): NaN where the solve failed, also with the runtime checks off.

:func:`~jaxbal._src.validation.guard` raises where a value is invalid, eagerly and under
``jit``; with the runtime checks off (the programs of an optimiser's line search, a
sweep, a tolerance search) it returns the value as it is. For most checks that value is
the invalid input itself (a negative mass, a non-finite state), which the metric carries
on as non-finite or as what was asked for. A solver's output is different: an
unreachable COM target gives the closed-form inverse kinematics' clamped root, a Newton
solve its last iterate, finite joint angles of another motion. Seen as a finite metric,
such a trial point steered a co-design's line search and ended a tolerance interval as
if the metric had risen there. Here the output is NaN where the solve failed, so every
caller sees the point as invalid (a line search rejects it, a sweep stores NaN), and the
check raises where the runtime checks are on.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxbal._src.robot_checks import checked_parameters
from jaxbal._src.validation import guard, is_traced


def guard_solution(value, invalid, message: str, offending, names=None, robot=None):
    """``value`` (a pytree of a solver's outputs for one problem), NaN where any entry
    of ``invalid`` is True when traced, then checked by
    :func:`~jaxbal._src.validation.guard` (eagerly a ``ValueError`` naming
    ``offending``, under ``jit`` a runtime error unless the checks are off). Gradients
    of a valid solution are unchanged (the value is multiplied by exactly 1), those of
    a failed one are NaN.

    ``robot``, the solver's robot: eagerly, its parameters are checked first
    (:func:`~jaxbal._src.robot_checks.checked_parameters`), so that a NaN length set
    with ``eqx.tree_at`` is named as such, not as an unreachable pose, and a negative
    length (a mirrored link, which the closed forms solve as if it were positive) is
    refused by the inverse kinematics as by the physics. Under a trace the physics
    that uses the solution checks the robot."""
    if robot is not None and not is_traced(value, invalid, robot):
        checked_parameters(robot, None)
    if is_traced(value, invalid):
        # a product, not a select: the derivatives are NaN too (a select's derivative
        # is 0 where it picks the constant, and under jit(jacfwd) the primal, with its
        # runtime check, is dropped: a refused pose's Jacobian came back as zeros)
        mask = jnp.where(jnp.any(invalid), jnp.nan, 1.0)
        value = jax.tree.map(lambda x: x * mask.astype(jnp.result_type(x)), value)
    return guard(value, invalid, message, offending, names)
