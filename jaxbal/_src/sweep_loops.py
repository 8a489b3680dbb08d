"""A sweep along a fixed motion must keep that motion on the loops of every robot it builds.

A closed chain's motion is solved for one geometry (its loop closures ``Φ(q) = 0``). A
sweep axis with a setter (``where=`` / ``set=``) may change that geometry (a link
length of the DUAL-V, the Orthoglide's parallelograms): the fixed motion then violates
the loops of the swept robot, and its shaking wrench and torques were computed for a
state the mechanism cannot reach — finite, silently wrong numbers (found by ``make
fuzz``: an Orthoglide with its parallelograms scaled by 1e-8 gave 3e42 N·m). Before
anything compiles, :func:`check_loops` evaluates the loop closures
(:func:`jaxbal.state_valid`) of the robots at the first and last value of each axis
with a setter and refuses the sweep naming the axis; a motion factory ``motion(robot,
θ)``, solved for every point, is the remedy. Design variables (masses, counter-mass
positions, payloads) do not change the loops and are not checked. The motion on the
robot as given is checked first, eagerly as the metrics check it
(:func:`~jaxbal._src.loop_checks.check_samples_eagerly`).
"""

from __future__ import annotations

import jax
import numpy as np

from jaxbal._src.loop_checks import check_samples_eagerly
from jaxbal._src.metrics import as_motion
from jaxbal._src.motion import has_loops, states_valid
from jaxbal._src.sweep_program import apply_parameters
from jaxbal._src.validation import runtime_checks

__all__ = ["check_loops"]


#: :func:`~jaxbal._src.motion.states_valid`, compiled once per robot structure
_valid = jax.jit(states_valid)


def check_loops(axes: dict, robot, motion, plan: tuple) -> None:
    """Refuse a fixed motion off the loops of the robot as given (e.g. held while a
    length was changed with ``eqx.tree_at``: the affine fast path would evaluate it
    without the metrics' runtime checks), and an axis whose setter moves it off them
    (module doc). Nothing is checked for a serial robot or a motion factory.

    Raises:
        ValueError: the loop-closure message of the metrics naming the samples off the
            loops (the robot as given), or naming the axis, the parameter's value and
            the first samples off the loops.
    """
    if callable(motion):
        return
    motion = as_motion(motion)
    if not has_loops(robot):
        return
    check_samples_eagerly(robot, *motion[:3])  # the motion held on the robot as given
    if not any(how == "set" for _, how, _ in plan):
        return
    first = {n: v[0] for axis in axes.values() for n, v in axis.values.items()}
    for dim, axis in axes.items():
        if not any(name in axis.setters for name in axis.values):
            continue
        for index in sorted({0, axis.size - 1}):
            params = {**first, **{n: v[index] for n, v in axis.values.items()}}
            with runtime_checks(False):  # a non-physical point is named by the sweep
                swept, _ = apply_parameters(robot, plan, params)
                valid = np.asarray(_valid(swept, *motion))
            if not valid.all():
                value = {n: np.asarray(v[index]).tolist() for n, v in axis.values.items()}
                raise ValueError(
                    f"sweep axis {dim!r} changes the geometry of {type(robot).__name__}: at "
                    f"{value} the fixed motion leaves its loop closures (samples "
                    f"{np.flatnonzero(~valid)[:5].tolist()}); pass a motion factory "
                    "motion(robot, θ) so that the motion is solved for every point"
                )
