"""Motion factories (end-effector and COM trapezoids, φ law, cycle time) and the
torque-rate metric of Briot et al. (2012), eqs (5)-(6).

References: the torque rate against central finite differences of the torques along
time and against the serial arms' closed-form rate (``inverse_dynamics_rate``); the COM
plan against its definition (COM on the straight line, end configurations reached);
the cycle time against a move built directly with that duration; the constraint by its
value after :func:`joint_codesign`.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.design import (
    ComTrapezoid,
    JerkMotion,
    Motion,
    TrapezoidLine,
    joint_codesign,
    motion_samples,
    peak_force,
    peak_torque_rate,
)
from jaxbal.planning import EndEffectorLine, torque_rate_along
from jaxbal.profiles import TrapezoidalAcceleration

THETA = {"u2": 0.25, "ratio": 0.5}
START, END = jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70])
CYCLE = 0.5


@pytest.fixture(scope="module")
def arm():
    return jaxbal.robots.planar_2r()


@eqx.filter_jit
def _torques_at(robot, path, t):
    q, qd, qdd = jaxbal.joint_motion(robot, path, t)
    return jaxbal.actuator_torques(robot, q, qd, qdd)


@pytest.mark.slow
def test_torque_rate_equals_the_closed_form(arm):
    times = jaxbal.sample_times(CYCLE, 41)
    move = TrapezoidLine(START, END, times, order=3)
    motion = move(arm, THETA)
    assert isinstance(motion, JerkMotion)
    profile = TrapezoidalAcceleration(0.125, 0.25)
    path = EndEffectorLine(arm, jaxbal.StraightLine(START, END, profile, CYCLE))
    closed = np.asarray(torque_rate_along(arm, path, times))  # eq (5), serial closed form
    rate = eqx.filter_jit(peak_torque_rate)  # eagerly: op by op, ~10 s on 2 cores
    np.testing.assert_allclose(float(rate(arm, motion)), np.abs(closed).max(), rtol=1e-12)


@pytest.mark.slow
def test_torque_rate_of_a_serial_arm_equals_finite_differences(arm):
    profile = TrapezoidalAcceleration(0.125, 0.25)
    path = EndEffectorLine(arm, jaxbal.StraightLine(START, END, profile, CYCLE))
    rate = eqx.filter_jit(peak_torque_rate)
    # central differences inside a jerk phase (the rate is smooth there)
    h = 1e-6
    for t in jnp.array([0.03, 0.2, 0.45]):
        fd = (_torques_at(arm, path, t + h) - _torques_at(arm, path, t - h)) / (2 * h)
        q, qd, qdd, qddd = jaxbal.sample(path, jnp.array([t]), order=3)
        exact = rate(arm, JerkMotion(q, qd, qdd, qddd))
        np.testing.assert_allclose(float(exact), np.abs(np.asarray(fd)).max(), rtol=1e-6)


@pytest.mark.slow
def test_torque_rate_of_a_closed_chain_equals_finite_differences():
    robot = jaxbal.robots.orthoglide()
    line = jaxbal.StraightLine(
        jnp.zeros(3), jnp.array([-0.1, 0.07, -0.11]), TrapezoidalAcceleration(0.1, 0.3), 0.1
    )
    path = EndEffectorLine(robot, line)
    t, h = jnp.array([0.02]), 1e-6
    motion = motion_samples(robot, path, t, order=3)
    fd = (_torques_at(robot, path, t[0] + h) - _torques_at(robot, path, t[0] - h)) / (2 * h)
    rate = eqx.filter_jit(peak_torque_rate)(robot, motion)
    np.testing.assert_allclose(float(rate), np.abs(np.asarray(fd)).max(), rtol=1e-6)


def test_torque_rate_needs_the_jerk(arm):
    motion = TrapezoidLine(START, END, jaxbal.sample_times(CYCLE, 8))(arm, THETA)
    assert type(motion) is Motion
    with pytest.raises(ValueError, match="JerkMotion"):
        peak_torque_rate(arm, motion)
    with pytest.raises(ValueError, match="order"):
        TrapezoidLine(START, END, jaxbal.sample_times(CYCLE, 8), order=4)


@pytest.mark.slow
def test_jerk_motion_gives_the_same_other_metrics(arm):
    times = jaxbal.sample_times(CYCLE, 12)
    two = TrapezoidLine(START, END, times)(arm, THETA)
    three = TrapezoidLine(START, END, times, order=3)(arm, THETA)
    # q, q̇ identical; q̈ from two separately compiled programs agrees to rounding
    for a, b in zip(two, three[:3], strict=True):
        np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=0, atol=1e-13 * 450)
    for name in ("peak_force", "rms_torque"):
        metric = eqx.filter_jit(jaxbal.design.METRICS[name])
        np.testing.assert_allclose(float(metric(arm, three)), float(metric(arm, two)), rtol=1e-13)


def test_a_robot_with_negative_lengths_is_refused(arm):
    """Set with ``eqx.tree_at``: the IK alone returned a mirrored motion without error;
    the factories refuse the robot, naming the field and its value."""
    bad = eqx.tree_at(lambda r: r.lengths, arm, -arm.lengths)
    with pytest.raises(ValueError, match=r"must be >= 0.*PlanarArm\.lengths.*-0\."):
        TrapezoidLine(START, END, jaxbal.sample_times(CYCLE, 8))(bad, THETA)


def test_duration_is_the_cycle_time(arm):
    times = jaxbal.sample_times(CYCLE, 12)
    scaled = TrapezoidLine(START, END, times)(arm, {**THETA, "duration": 0.8})
    direct = TrapezoidLine(START, END, jaxbal.sample_times(0.8, 12))(arm, THETA)
    for a, b in zip(scaled, direct, strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-13)
    with pytest.raises(ValueError, match="duration"):
        TrapezoidLine(START, END, times)(arm, {**THETA, "duration": -1.0})


@pytest.mark.slow
def test_com_trapezoid_keeps_the_com_on_its_line_and_joins_the_configurations():
    robot = jaxbal.robots.planar_3r()
    q_start = robot.inverse_kinematics(jnp.array([0.225, 0.25, 0.0]))
    q_end = robot.inverse_kinematics(jnp.array([0.225, 0.70, 2.0]))
    # the elbow of the end-effector IK's branch +1 is the COM IK's branch -1 (eq 15)
    move = ComTrapezoid(q_start, q_end, jaxbal.sample_times(CYCLE, 21), branch=-1)
    theta = {**THETA, "phi": jnp.array([0.5, -1.0, 2.0])}
    motion = move(robot, theta)
    with pytest.raises(ValueError, match="does not start at q_start / end at q_end"):
        ComTrapezoid(q_start, q_end, move.times, branch=1)(robot, theta)
    coms = jax.jit(jax.vmap(lambda q: jaxbal.center_of_mass(robot, q)))(motion.q)
    coms = np.asarray(coms)[:, :2]
    a, b = coms[0], coms[-1]
    np.testing.assert_allclose(a, np.asarray(jaxbal.center_of_mass(robot, q_start))[:2], atol=1e-12)
    np.testing.assert_allclose(b, np.asarray(jaxbal.center_of_mass(robot, q_end))[:2], atol=1e-12)
    direction = (b - a) / np.linalg.norm(b - a)
    off_line = (coms - a) - np.outer((coms - a) @ direction, direction)
    assert np.abs(off_line).max() < 1e-12
    # the ends are at rest and φ ends at its end value for every coefficient choice
    np.testing.assert_allclose(np.asarray(motion.q[-1]), np.asarray(q_end), atol=1e-10)
    assert np.abs(np.asarray(motion.qd[jnp.array([0, -1])])).max() < 1e-10
    # the coefficients change the motion in between
    other = move(robot, {**THETA, "phi": jnp.zeros(3)})
    assert np.abs(np.asarray(other.q[10] - motion.q[10])).max() > 1e-3
    with pytest.raises(ValueError, match="phi"):
        orthoglide = jaxbal.robots.orthoglide()
        q0 = orthoglide.inverse_kinematics(jnp.zeros(3))
        ComTrapezoid(q0, q0, jaxbal.sample_times(0.1, 5))(orthoglide, theta)


@pytest.mark.slow
def test_joint_codesign_holds_a_torque_rate_limit_and_a_cycle_time(arm):
    move = TrapezoidLine(START, END, jaxbal.sample_times(CYCLE, 16), order=3)
    theta = {**THETA, "duration": CYCLE}
    nominal = float(peak_torque_rate(arm, move(arm, theta)))
    limit = 0.8 * nominal
    solution = joint_codesign(
        arm, move, theta, "peak_force", free=(),
        trajectory_lower={"u2": 0.05, "ratio": 0.05, "duration": 0.3},
        trajectory_upper={"u2": 0.45, "ratio": 1.0, "duration": 0.6},
        constraints={"peak_torque_rate": limit}, max_steps=80,
    )  # fmt: skip
    value, bound = (float(v) for v in solution.constraints["peak_torque_rate"])
    assert bound == limit
    assert value <= limit * (1 + 1e-6)
    assert 0.3 <= float(solution.trajectory["duration"]) <= 0.6
    after = float(peak_force(arm, move(arm, solution.trajectory)))
    assert after < float(peak_force(arm, move(arm, theta)))
    assert np.isfinite(float(solution.grad_norm))


@pytest.mark.slow
def test_phase_samples_give_the_planning_torque_rate(arm):
    """``per_phase`` samples inside the jerk phases: the COM trapezoid's peak rate equals
    that of the rate-limited planning of Briot et al. (eqs 5-6, serial closed form) on
    the same instants."""
    from jaxbal.planning import peak_torque_rate as planning_rate
    from jaxbal.robots.planar_arm_studies import ComPath

    q_a = arm.inverse_kinematics(START, branch=-1)
    q_b = arm.inverse_kinematics(END, branch=-1)
    theta = {"u2": 0.45, "ratio": 0.01}  # u1 = 2.25 ms, inside the first 25 ms sample gap
    profile = TrapezoidalAcceleration(0.0045, 0.45)
    coms = [jaxbal.center_of_mass(arm, q)[:2] for q in (q_a, q_b)]
    reference = planning_rate(arm, ComPath(CYCLE, 1), (arm, *coms), profile, CYCLE, 21, 16)
    times = jaxbal.sample_times(CYCLE, 21)
    rate = eqx.filter_jit(peak_torque_rate)
    dense = ComTrapezoid(q_a, q_b, times, branch=1, order=3, per_phase=16)(arm, theta)
    np.testing.assert_allclose(float(rate(arm, dense)), float(reference), rtol=1e-10)
