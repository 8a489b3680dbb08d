"""A one-state function evaluated at every sample of a motion (``vmap``), checked.

:func:`batched` is what the metrics (:mod:`jaxbal._src.metrics`) and the wrench
regressor run: traced (under ``jit``/``grad``, or closed over by a ``jit``) a plain
``vmap``; eagerly, the robot and the states are checked by name first and the samples
run as one compiled program.
"""

from __future__ import annotations

import equinox as eqx
import jax
import numpy as np

from jaxbal._src.loop_checks import check_samples_eagerly
from jaxbal._src.motion_samples import Motion, as_motion, check_motion_shape
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_robot, checked_finite
from jaxbal._src.validation import (
    _under_trace,
    is_traced,
    raise_if_invalid,
    runtime_checks,
    runtime_checks_enabled,
)


def batched(evaluate, robot: Robot, motion: Motion, what: str, jerk: bool = False, run=None):
    """``evaluate(robot, q, qd, qdd)`` at every sample of the motion (``vmap``);
    ``evaluate(robot, q, qd, qdd, qddd)`` with ``jerk`` (``motion`` a JerkMotion);
    ``run(evaluate, robot, motion)`` evaluates the samples (default: traced
    :func:`samples`, eagerly :func:`compiled_samples`; e.g. the regressor's compiled
    program keyed on :func:`~jaxbal.runtime_checks` being on or off).

    An eager call checks the values first (the robot, finite states, a closed chain's
    loop closures) and raises ``ValueError``: inside ``vmap`` the
    runtime checks would surface as a JAX-internal callback error (``INTERNAL:
    CpuCallback error``) instead of naming the offending value.
    """
    motion = motion if jerk else as_motion(motion)
    check_motion_shape(robot, motion)
    if is_traced(robot, motion) or _under_trace():  # traced, or closed over by a jit
        return (samples if run is None else run)(evaluate, robot, motion)
    run = compiled_samples if run is None else run
    check_robot(robot)
    # NumPy: eagerly each small JAX operation is a dispatch, and in a fresh process a
    # compilation of its own (~20-90 ms each on the 2-core CPU)
    states = np.concatenate([np.asarray(part, dtype=float) for part in motion], axis=-1)
    finite = np.all(np.isfinite(states), axis=-1)
    raise_if_invalid(finite, "non-finite state (q, qd, qdd) in the motion at samples",
                     np.arange(finite.shape[0]))  # fmt: skip
    check_samples_eagerly(robot, *motion[:3])  # a closed chain: on its loops
    with runtime_checks(False):  # checked above and below, eagerly
        out = run(evaluate, robot, motion)
    return checked_finite(what, robot, out)


def samples(evaluate, robot: Robot, motion):
    """``evaluate(robot, *state)`` at every sample of the motion (``vmap``, unchecked)."""
    return jax.vmap(lambda *state: evaluate(robot, *state))(*motion)


@eqx.filter_jit
def _program(evaluate, robot: Robot, motion, checks: bool):
    """:func:`samples` compiled once per ``evaluate``, robot structure, motion length and
    ``checks`` (static: the runtime value checks on or off while tracing, so that each
    setting has its own program)."""
    with runtime_checks(checks):
        return samples(evaluate, robot, motion)


def compiled_samples(evaluate, robot: Robot, motion):
    """:func:`samples` as one compiled program: an eager call (a notebook's
    ``peak_torque(robot, motion)``) ran the ``vmap`` operation by operation, measured on
    the 2-core CPU, the DUAL-V's peak torque along 24 samples 21 s, now ~7 s cold
    (compiling) and 0.01 s warm."""
    return _program(evaluate, robot, motion, runtime_checks_enabled())
