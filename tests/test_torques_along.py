"""Actuator torques and their rates along a trajectory, any robot.

Before, ``torques_along`` and ``torque_rate_along`` returned the generalised forces of
*all* coordinates (``inverse_dynamics``): the actuator torques of a serial arm with
every coordinate actuated, but not of a closed chain (the Orthoglide's actuated rates
were 530 N/s off), so a rate-limited plan of a closed chain bounded internal forces.
References: ``jaxbal.actuator_torques`` at the joint motion's samples (1e-12), central
finite differences in time (1e-6 relative), and the serial closed case, where the rates
equal ``inverse_dynamics_rate`` (1e-10 relative).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for

import jaxbal
from jaxbal import robots
from jaxbal._src.dynamics import inverse_dynamics_rate
from jaxbal.planning import EndEffectorLine, torque_rate_along, torques_along
from jaxbal.profiles import Quintic

GRAVITY = (0.0, 0.0, -9.81)
CASES = {
    "planar_2r": (robots.planar_2r(), (0.4, 0.3), (0.2, 0.5)),
    "orthoglide": (robots.orthoglide(payload=1.0), (0.0, 0.0, 0.0), (-0.1, 0.07, -0.11)),
}


def _path(name):
    robot, start, end = CASES[name]
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), 0.2)
    return robot, EndEffectorLine(robot, line)


@pytest.mark.parametrize("name", slow_for(sorted(CASES), "orthoglide"))
def test_torques_and_rates_are_the_actuators(name):
    """(t, a) actuator torques equal ``actuator_torques`` at the samples; their rates
    equal central differences of the torques in time (h = 1e-5 s). For the Orthoglide
    the actuated columns of the generalised forces' rates (the old result) differ by
    far more than rounding."""
    robot, path = _path(name)
    times = jnp.linspace(0.02, 0.18, 9)
    torques = np.asarray(torques_along(robot, path, times, gravity=GRAVITY))
    assert torques.shape == (9, len(robot.actuated))
    for k in (0, 4, 8):
        state = jaxbal.joint_motion(robot, path, times[k])
        expected = jaxbal.actuator_torques(robot, *state, gravity=GRAVITY)
        np.testing.assert_allclose(torques[k], expected, rtol=1e-12, atol=1e-12)
    rates = np.asarray(torque_rate_along(robot, path, times, gravity=GRAVITY))
    h = 1e-5
    ahead, behind = (torques_along(robot, path, times + s, gravity=GRAVITY) for s in (h, -h))
    central = (np.asarray(ahead) - np.asarray(behind)) / (2 * h)
    assert np.max(np.abs(rates - central)) < 1e-6 * np.max(np.abs(rates))
    assert np.all(np.isfinite(rates))
    q, qd, qdd, qddd = jaxbal.sample(path, times[4:5], order=3)
    one = jaxbal.actuator_torque_rate(robot, q[0], qd[0], qdd[0], qddd[0], gravity=GRAVITY)
    np.testing.assert_allclose(one, rates[4], rtol=1e-12, atol=1e-12 * np.max(np.abs(rates)))
    if name == "orthoglide":
        q, qd, qdd, qddd = jaxbal.sample(path, times, order=3)
        old = jax.vmap(lambda *s: inverse_dynamics_rate(robot, *s, GRAVITY))(q, qd, qdd, qddd)
        gap = np.max(np.abs(np.asarray(old)[:, list(robot.actuated)] - rates))
        assert gap > 1e-2 * np.max(np.abs(rates))


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_serial_rates_equal_the_generalised_forces_rates():
    """2R, every coordinate actuated: the actuator rates are the generalised ones."""
    robot, path = _path("planar_2r")
    times = jnp.linspace(0.0, 0.2, 11)
    q, qd, qdd, qddd = jaxbal.sample(path, times, order=3)
    generalised = jax.vmap(lambda *s: inverse_dynamics_rate(robot, *s))(q, qd, qdd, qddd)
    rates = torque_rate_along(robot, path, times)
    np.testing.assert_allclose(rates, generalised, rtol=1e-10, atol=1e-10 * np.max(np.abs(rates)))


def test_samples_of_a_motion_equal_a_loop_and_the_metrics():
    """``wrench_samples`` / ``torque_samples`` of the DUAL-V along 7 samples equal a
    Python loop of the single-state functions (1e-12), compiled equals eager, and the
    peak metrics are their largest norms."""
    from jaxbal.design import (
        motion_samples,
        peak_force,
        peak_torque,
        torque_samples,
        wrench_samples,
    )

    robot = robots.dual_v()
    line = jaxbal.StraightLine(jnp.zeros(3), jnp.array([0.05, 0.05, 0.0]), Quintic(), 0.2)
    motion = motion_samples(robot, EndEffectorLine(robot, line), jnp.linspace(0, 0.2, 7))
    force, moment = wrench_samples(robot, motion)
    torques = torque_samples(robot, motion)
    assert force.shape == moment.shape == (7, 3) and torques.shape == (7, 4)
    for k in range(7):
        state = (motion.q[k], motion.qd[k], motion.qdd[k])
        f, m = jaxbal.shaking_wrench(robot, *state)
        np.testing.assert_allclose(force[k], f, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(moment[k], m, rtol=1e-12, atol=1e-12)
        tau = jaxbal.actuator_torques(robot, *state)
        np.testing.assert_allclose(torques[k], tau, rtol=1e-12, atol=1e-12)
    compiled = jax.jit(wrench_samples)(robot, motion)
    np.testing.assert_allclose(compiled[0], force, rtol=1e-12, atol=1e-12)
    assert float(peak_force(robot, motion)) == pytest.approx(np.max(np.linalg.norm(force, axis=1)))
    assert float(peak_torque(robot, motion)) == pytest.approx(
        np.max(np.linalg.norm(torques, axis=1))
    )
