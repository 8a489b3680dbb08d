"""Eager calls of the single-state functions as one compiled program.

Called on concrete values (a notebook's ``shaking_wrench(robot, q, q̇, q̈)``), a JAX
function runs operation by operation: each operation is a dispatch, and in a fresh
process a compilation of its own (~20–100 ms each on the 2-core CPU; ~30 of them for
the DUAL-V's wrench of one state). :func:`run_compiled` runs it as one program instead,
compiled once per function and robot structure, traced without the runtime checks (no
host callbacks, so the persistent compilation cache keeps it) and returning the
validity mask of the robot (and of the state: a closed chain's loops) with the result.
When the robot or the state is invalid, or an input or the result is not finite, the
function runs again operation by operation: its checks raise the ``ValueError`` naming
the offending values, exactly as an eager call always did.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import numpy as np

from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_leaves
from jaxbal._src.validation import _under_trace, runtime_checks


@eqx.filter_jit
def _program(fn: Callable, faulty: Callable, robot: Robot, arrays):
    with runtime_checks(False):
        return fn(robot, *arrays), faulty(robot, *arrays)


def run_compiled(fn: Callable, faulty: Callable, robot: Robot, *arrays):
    """``fn(robot, *arrays)`` for a concrete robot and arrays, as one compiled program.

    Args:
        fn: a module-level function (its identity keys the compiled program) whose
            value checks are the robot's validity and finite inputs and result.
        faulty: ``(robot, *arrays) -> bool`` (traceable, module-level): would ``fn``'s
            checks reject the robot or the arrays (e.g. a state off a closed chain's
            loops)?
        robot: a concrete robot.
        arrays: the other arguments: array-likes (as float arrays) or ``None``.

    Returns:
        ``fn(robot, *arrays)``; where a check fails, the result of the operation-by-
        operation call (which raises the named ``ValueError``). Inside another trace
        (concrete values closed over by a user's ``jax.jit``) ``fn`` itself, staged
        into the enclosing program: the compiled program's results would be tracers
        there, which the checks below cannot read (it raised
        ``TracerArrayConversionError``).
    """
    if _under_trace():
        return fn(robot, *arrays)
    check_leaves(robot)  # a Python number: static to filter_jit, a TypeError in the physics
    values = [None if a is None else np.asarray(a, dtype=float) for a in arrays]
    if all(v is None or np.all(np.isfinite(v)) for v in values):
        out, rejected = _program(fn, faulty, robot, values)
        finite = all(np.all(np.isfinite(np.asarray(x))) for x in jax.tree_util.tree_leaves(out))
        if finite and not bool(rejected):
            return out
    return fn(robot, *arrays)
