"""Concrete robots and states closed over by a user's ``jax.jit``: every entry point
stages into the enclosing program and gives the eager value (``center_of_mass`` and
``shaking_wrench`` raised ``TracerArrayConversionError``: their eager fast path ran a
compiled program whose results are tracers there), and an invalid concrete robot still
raises a ``ValueError`` naming the value."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.design import ComTrapezoid, motion_samples, peak_force, peak_torque, rms_force
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic

ROBOT = jaxbal.robots.planar_2r()
STATE = (jnp.array([0.3, 0.4]), jnp.array([1.0, -0.5]), jnp.array([2.0, 1.0]))
LINE = jaxbal.StraightLine(jnp.array([0.4, 0.3]), jnp.array([0.2, 0.5]), Quintic(), 0.2)
PATH = EndEffectorLine(ROBOT, LINE)
TIMES = jaxbal.sample_times(0.2, 11)
MOTION = motion_samples(ROBOT, [PATH], TIMES)

CASES = {
    "center_of_mass": lambda: jaxbal.center_of_mass(ROBOT, STATE[0]),
    "shaking_wrench": lambda: jaxbal.shaking_wrench(ROBOT, *STATE)[1],
    "actuator_torques": lambda: jaxbal.actuator_torques(ROBOT, *STATE),
    "inverse_kinematics": lambda: ROBOT.inverse_kinematics(jnp.array([0.4, 0.3])),
    "motion_samples": lambda: motion_samples(ROBOT, [PATH], TIMES).qdd,
    "peak_force": lambda: peak_force(ROBOT, MOTION),
    "rms_force": lambda: rms_force(ROBOT, MOTION),
    "peak_torque": lambda: peak_torque(ROBOT, MOTION),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_closed_over_values_stage_into_the_users_jit(name):
    evaluate = CASES[name]
    eager = np.asarray(evaluate())
    staged = np.asarray(jax.jit(lambda scale: evaluate() * scale)(2.0))
    np.testing.assert_allclose(staged, 2.0 * eager, rtol=1e-12, atol=1e-14)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_motion_factory_with_a_closed_over_robot_under_jit():
    """The COM plan's end points are centres of mass of the concrete robot (the path of
    the crash), the trajectory parameters traced."""
    q_a = ROBOT.inverse_kinematics(jnp.array([0.4, 0.3]), branch=-1)
    q_b = ROBOT.inverse_kinematics(jnp.array([0.2, 0.45]), branch=-1)
    # the elbow of the end-effector IK's branch -1 is the COM IK's branch +1 (eq 15)
    move = ComTrapezoid(q_a, q_b, TIMES, branch=1)
    theta = {"u2": jnp.asarray(0.3), "ratio": jnp.asarray(0.5), "duration": jnp.asarray(0.2)}
    eager = np.asarray(move(ROBOT, theta).qdd)
    staged = jax.jit(lambda th: move(ROBOT, th).qdd)(theta)
    np.testing.assert_allclose(staged, eager, rtol=1e-12, atol=1e-12)


def test_an_invalid_closed_over_robot_still_raises_the_named_error():
    bad = eqx.tree_at(lambda r: r.masses, ROBOT, jnp.array([-1.0, 1.0]))
    with pytest.raises(ValueError, match="mass"):
        jax.jit(lambda scale: jaxbal.center_of_mass(bad, STATE[0]) * scale)(1.0)


def test_a_host_side_analysis_under_jit_is_refused_by_name():
    """``balancing_conditions`` (a NumPy SVD) inside a user's ``jit`` raised a
    ``TracerArrayConversionError``; now a ``ValueError`` saying what to call instead."""
    from jaxbal.balancing import balancing_conditions

    with pytest.raises(ValueError, match="outside jit"):
        jax.jit(lambda scale: balancing_conditions(ROBOT, MOTION).__class__ and scale)(1.0)


DUAL_V = jaxbal.robots.dual_v()
DUAL_V_STATE = jaxbal.pose_motion(DUAL_V, jnp.zeros(3), jnp.ones(3), jnp.full(3, 5.0))
DUAL_V_LINE = jaxbal.StraightLine(jnp.zeros(3), jnp.array([0.05, 0.05, 0.0]), Quintic(), 0.2)
DUAL_V_MOTION = motion_samples(DUAL_V, [EndEffectorLine(DUAL_V, DUAL_V_LINE)], TIMES)


@pytest.mark.parametrize(
    "name",
    [
        "shaking_wrench",
        *(pytest.param(n, marks=pytest.mark.slow) for n in ("actuator_torques", "peak_torque")),
    ],
)
def test_a_closed_chain_closed_over_checks_its_loops_in_the_users_jit(name):
    """The DUAL-V's state and motion closed over (the loop check ran a compiled program
    there and raised ``ConcretizationTypeError``): staged, the eager value; a state or
    motion off the loops (a length changed under it) is refused by the runtime check."""
    longer = eqx.tree_at(lambda r: r.l1, DUAL_V, DUAL_V.l1 * 1.01)
    evaluate = {
        "shaking_wrench": lambda r: jaxbal.shaking_wrench(r, *DUAL_V_STATE)[0],
        "actuator_torques": lambda r: jaxbal.actuator_torques(r, *DUAL_V_STATE),
        "peak_torque": lambda r: peak_torque(r, DUAL_V_MOTION),
    }[name]
    eager = np.asarray(evaluate(DUAL_V))
    staged = np.asarray(jax.jit(lambda scale: evaluate(DUAL_V) * scale)(2.0))
    np.testing.assert_allclose(staged, 2.0 * eager, rtol=1e-12, atol=1e-12)
    with pytest.raises(Exception, match="loop closures"):
        jax.block_until_ready(jax.jit(lambda scale: evaluate(longer) * scale)(2.0))
