"""Tests of jaxbal.robots.planar_arm_studies (Briot, Arakelian & Le Baron 2012)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.planning import ComLine, peak_norm, torque_rate_along, wrench_along
from jaxbal.profiles import BangBang, Quintic
from jaxbal.robots import planar_2r, planar_3r
from jaxbal.robots import planar_arm_studies as pas
from jaxbal.robots.planar_arm import force_balanced

# Reproduction studies (their numbers are also written by `make reproduce`): make test-all.
pytestmark = pytest.mark.slow

DURATION = 0.5
RATE_LIMIT = 3.0e4  # N·m/s, §3.1
P5, P9 = jnp.array([0.225, 0.25]), jnp.array([0.225, 0.7])  # 2R test square, Fig 3
PHI = (0.0, 2.0 * np.pi / 3.0)
TIMES = jaxbal.sample_times(DURATION, 101)


def _com(robot, q):
    return jaxbal.center_of_mass(robot, q)[:2]


@pytest.mark.slow
def test_2r_motion_laws_endpoints_constant_force_and_rate_limit():
    # references: case 1 joins the end-effector points; cases 2-3 join the COMs of their
    # IK; case 2 (bang-bang COM line) has |f| = m_tot·4|ΔS|/T² (eq 3); case 3 meets the
    # torque-rate limit (eq 6) on a dense grid, with a smaller peak force than case 1
    robot = planar_2r()
    laws = pas.motion_laws(robot, P5, P9, DURATION, RATE_LIMIT)
    assert laws.coefficients is None and set(laws.trajectories) == {"case1", "case2", "case3"}
    case1 = laws.trajectories["case1"]
    np.testing.assert_allclose(robot.end_effector(case1(0.0)), P5, atol=1e-12)
    np.testing.assert_allclose(robot.end_effector(case1(DURATION)), P9, atol=1e-12)
    s_a = _com(robot, robot.inverse_kinematics(P5, branch=-1))
    s_b = _com(robot, robot.inverse_kinematics(P9, branch=-1))
    for case in ("case2", "case3"):
        path = laws.trajectories[case]
        assert isinstance(path, ComLine) and path.branch == 1
        np.testing.assert_allclose(_com(robot, path(DURATION)), s_b, atol=1e-12)
    force = wrench_along(robot, laws.trajectories["case2"], TIMES[1:-1])[0]
    closed = jaxbal.total_mass(robot) * 4 * jnp.linalg.norm(s_b - s_a) / DURATION**2
    np.testing.assert_allclose(jnp.linalg.norm(force, axis=1), closed, rtol=1e-9)
    dense = jaxbal.sample_times(DURATION, 4001)
    rates = torque_rate_along(robot, laws.trajectories["case3"], dense)
    assert float(jnp.max(jnp.abs(rates))) <= RATE_LIMIT * (1 + 1e-3)
    assert float(laws.plan.peak_rate) <= RATE_LIMIT
    peak3 = peak_norm(wrench_along(robot, laws.trajectories["case3"], TIMES)[0])
    assert peak3 < peak_norm(wrench_along(robot, case1, TIMES)[0])

    # §3.3: the base moment is minus the first joint torque (planar arm, no gravity),
    # and the counterweights cancel the shaking force of case 1
    torques = pas.input_torques(robot, laws, (0.35, 0.2), TIMES)
    assert set(torques) == {"unbalanced", "counterweights", "com_bang_bang", "com_trapezoid"}
    moment = wrench_along(robot, laws.trajectories["case2"], TIMES)[1]
    np.testing.assert_allclose(torques["com_bang_bang"][:, 0], -moment[:, 2], atol=1e-9)
    balanced = force_balanced(robot, (0.35, 0.2))
    path = jaxbal.planning.EndEffectorLine(balanced, case1.line, -1)
    assert peak_norm(wrench_along(balanced, path, TIMES)[0]) < 1e-9
    with pytest.raises(ValueError, match="phi"):
        pas.motion_laws(robot, P5, P9, DURATION, RATE_LIMIT, phi=PHI)


def test_3r_com_path_meets_eq20_and_objective_bounds_and_gradients():
    # references: eq (20) boundary conditions of φ(t) (φ_0, φ_f, zero rates at both ends);
    # smooth_peak bound max ≤ τ·logsumexp(|m|/τ) ≤ max + τ log t; finite differences
    robot = planar_3r()
    q_a = robot.inverse_kinematics(jnp.array([-0.15, 0.337, PHI[0]]), branch=-1)
    q_b = robot.inverse_kinematics(jnp.array([0.15, 0.637, PHI[1]]), branch=-1)
    start, end = _com(robot, q_a), _com(robot, q_b)
    path = pas.ComPath(DURATION, 1, PHI)
    coefficients = jnp.array([1.0, -2.0, 0.5])
    trajectory = path(BangBang(), (robot, start, end, coefficients))

    def phi_and_rates(t):
        return jaxbal.time_derivatives(lambda s: jnp.sum(trajectory(s)), t, order=2)

    for t, phi in ((0.0, PHI[0]), (DURATION, PHI[1])):
        value, rate, acceleration = phi_and_rates(t)
        assert float(value) == pytest.approx(phi, abs=1e-12)
        assert abs(float(rate)) < 1e-9 and abs(float(acceleration)) < 1e-7
    samples, temperature = 41, 0.5
    times = jaxbal.sample_times(DURATION, samples)
    true_max = float(jnp.max(jnp.abs(wrench_along(robot, trajectory, times)[1][:, 2])))
    args = (robot, start, end, temperature, path, samples)
    smooth = float(pas.moment_objective(coefficients, *args))
    rounding = 1e-12 * true_max  # two programs evaluate the moment
    assert true_max - rounding <= smooth <= true_max + temperature * np.log(samples) + rounding
    objective = jax.jit(lambda c: pas.moment_objective(c, *args))
    check_grads(objective, (coefficients,), order=1, modes=("rev",), eps=1e-4, rtol=1e-4)


@pytest.mark.slow
def test_optimal_phi_law_lowers_the_peak_moment():
    # reference: the quintic law (coefficients 0) is the optimiser's first start, so the
    # optimum's true peak |m_z| can only be lower; one start, one temperature (fast)
    robot = planar_3r()
    q_a = robot.inverse_kinematics(jnp.array([-0.15, 0.337, PHI[0]]), branch=-1)
    q_b = robot.inverse_kinematics(jnp.array([0.15, 0.637, PHI[1]]), branch=-1)
    start, end = _com(robot, q_a), _com(robot, q_b)
    path = pas.ComPath(DURATION, 1, PHI)
    best = pas.optimal_phi_coefficients(
        robot, start, end, path, starts=1, temperatures=(1.0,), samples=41
    )

    def peak(c):
        trajectory = path(BangBang(), (robot, start, end, c))
        return float(jnp.max(jnp.abs(wrench_along(robot, trajectory, TIMES)[1][:, 2])))

    assert best.shape == (3,)
    assert peak(best) < 0.95 * peak(jnp.zeros(3))
    line = jaxbal.StraightLine(jnp.zeros(2), jnp.ones(2), Quintic(), DURATION)
    with pytest.raises(ValueError, match="phi"):
        pas.motion_laws(robot, line.start, line.end, DURATION, RATE_LIMIT)
