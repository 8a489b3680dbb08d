"""Inputs on the edge of a function's domain are refused by name, never answered with a
silent wrong number or NaN (found by a session of hostile use, session 41).

* a pose or COM target on the singular boundary of the workspace (the arm stretched or
  folded): the clipped ``arccos`` / floored root gave a valid-looking ``q`` whose
  derivative was zero where the true one is infinite (a line ending there had
  ``q̇ = 0`` and a wrong ``q̈``: 0 N at the last sample, 77 N just before);
* ``sensitivity(check=True)`` with a NaN finite difference passed (``max`` drops NaN);
* ``smooth_peak`` with a temperature ≤ 0 (below the maximum it bounds, or NaN), the
  trapezoid's ``peak_acceleration`` with switch times it refuses elsewhere, ``peak_norm``
  of a NaN row under ``jit``;
* a motion whose parts differ in length, a bound of the wrong shape, a scale ≤ 0 in
  ``joint_codesign``, a robot parameter set to a Python number.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for

import jaxbal
from jaxbal import design
from jaxbal._src.linalg import elbow_angle
from jaxbal.planning import peak_norm, plan_rate_limited, smooth_peak
from jaxbal.profiles import TrapezoidalAcceleration


def test_elbow_angle_is_valid_only_strictly_inside():
    cosines = jnp.array([0.5, 1.0 - 1e-16, 1.0, 1.0 + 1e-9, -1.0, jnp.nan, jnp.inf])
    angle, valid = elbow_angle(cosines)
    np.testing.assert_array_equal(np.asarray(valid), [True] + [False] * 6)
    assert np.all(np.isfinite(np.asarray(angle)))
    np.testing.assert_allclose(float(angle[0]), np.pi / 3, rtol=1e-15)
    slope = jax.grad(lambda c: elbow_angle(c)[0])(0.5)
    np.testing.assert_allclose(float(slope), -1.0 / np.sqrt(0.75), rtol=1e-14)


@pytest.mark.parametrize("q2", slow_for([0.0, np.pi], np.pi))  # stretched, folded (twin)
def test_2r_pose_on_the_singular_boundary_is_refused(q2):
    arm = jaxbal.robots.planar_2r()
    pose = arm.end_effector(jnp.array([0.3, q2]))
    _, valid = arm.inverse_kinematics(pose, return_valid=True)
    assert not bool(valid)
    with pytest.raises(ValueError, match="singular boundary"):
        arm.inverse_kinematics(pose)
    # just inside: valid, and the derivative of the IK inverts the forward kinematics
    inside = arm.end_effector(jnp.array([0.3, abs(q2 - 1e-3)]))
    ik_jacobian = jax.jacfwd(lambda p: arm.inverse_kinematics(p, branch=1))(inside)
    q = arm.inverse_kinematics(inside, branch=1)
    product = jax.jacfwd(arm.end_effector)(q) @ ik_jacobian
    np.testing.assert_allclose(np.asarray(product), np.eye(2), atol=1e-8)


@pytest.mark.slow  # make test-all: the 2R's twin (the same two_link_ik)
def test_scara_stretched_pose_is_refused():
    robot = jaxbal.robots.scara()
    pose = robot.end_effector(jnp.array([0.2, 0.0, 0.1, 0.05]))
    _, valid = robot.inverse_kinematics(pose, return_valid=True)
    assert not bool(valid)


def test_2r_com_on_the_boundary_of_its_com_workspace_is_refused_and_shapes_checked():
    arm = jaxbal.robots.planar_2r()
    com = jaxbal.center_of_mass(arm, jnp.array([0.3, 0.0]))  # stretched: Δ = 0
    _, valid = arm.com_inverse_kinematics(com, return_valid=True)
    assert not bool(valid)
    with pytest.raises(ValueError, match="singular boundary"):
        arm.com_inverse_kinematics(com)
    inside = jaxbal.center_of_mass(arm, jnp.array([0.3, 0.2]))
    _, valid = arm.com_inverse_kinematics(inside, return_valid=True)
    assert bool(valid)
    with pytest.raises(ValueError, match=r"shape \(2,\) or \(3,\), got \(4,\)"):
        arm.com_inverse_kinematics(jnp.zeros(4))
    arm3 = jaxbal.robots.planar_3r()
    with pytest.raises(ValueError, match=r"free \(φ\) must have shape"):
        arm3.com_inverse_kinematics(jnp.array([0.1, 0.2]), jnp.zeros(2))


@pytest.fixture(scope="module")
def move_2r():
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    plan = jaxbal.planning.com_line(arm, q0, q1, jaxbal.profiles.BangBang(), 0.5)
    return arm, design.motion_samples(arm, [plan], jaxbal.sample_times(0.5, 8))


def _nan_off_the_base(robot, motion):
    """``payload²`` at the robot's own payload (0.5 kg below), NaN at any other."""
    return jnp.where(robot.payload == 0.5, robot.payload**2, jnp.nan)


def test_sensitivity_check_refuses_a_bad_step_and_a_nan_difference(move_2r):
    arm, motion = move_2r
    arm = arm.with_design({"payload": 0.5})
    for step in (0.0, -1e-6, np.nan):
        with pytest.raises(ValueError, match="rel_step must be a finite number > 0"):
            jaxbal.sensitivity.sensitivity(arm, motion, "rms_force", check=True, rel_step=step)
    result = jaxbal.sensitivity.sensitivity(arm, motion, _nan_off_the_base, wrt=("payload",))
    np.testing.assert_allclose(float(result.gradient["payload"]), 1.0, rtol=1e-15)
    with pytest.raises(ValueError, match="differs from central finite differences by nan"):
        jaxbal.sensitivity.sensitivity(arm, motion, _nan_off_the_base, wrt=("payload",), check=True)


def test_smooth_peak_bounds_the_maximum_and_refuses_its_domain_edges():
    values = jnp.array([1.0, -2.0, 0.5])
    peak = float(smooth_peak(values, 0.01))
    assert 2.0 <= peak <= 2.0 + 0.01 * np.log(3)
    for temperature in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="temperature must be > 0"):
            smooth_peak(values, temperature)
    with pytest.raises(ValueError, match="values must be finite"):
        smooth_peak(values.at[1].set(jnp.nan), 0.01)
    with pytest.raises(ValueError, match=r"shape \(t,\) with t >= 1"):
        smooth_peak(jnp.zeros(0), 0.01)
    with pytest.raises(ValueError, match="temperature must be > 0"):
        jaxbal.checked_jit(smooth_peak)(values, jnp.asarray(0.0))


def test_trapezoid_peak_acceleration_is_the_plateau_and_checks_its_switch_times():
    profile = TrapezoidalAcceleration(0.1, 0.3)
    plateau = jax.grad(jax.grad(profile))(0.2)  # s'' on [u1, u2]
    np.testing.assert_allclose(float(profile.peak_acceleration), float(plateau), rtol=1e-12)
    for u1, u2 in ((0.3, 0.2), (0.0, 0.25), (0.1, 0.6)):
        with pytest.raises(ValueError, match="switch times"):
            TrapezoidalAcceleration(u1, u2).peak_acceleration  # noqa: B018


def test_peak_norm_of_a_nan_row_raises_under_jit_too():
    vectors = jnp.ones((4, 3)).at[2, 1].set(jnp.nan)
    with pytest.raises(ValueError, match="non-finite rows"):
        peak_norm(vectors)
    with pytest.raises(ValueError, match="peak_norm: vectors must be finite"):
        jaxbal.checked_jit(peak_norm)(vectors)
    with jaxbal.runtime_checks(False):  # documented: the checks off, NaN comes back
        assert np.isnan(float(jax.jit(peak_norm)(vectors)))


@pytest.mark.parametrize("bad", [{"grid": 0}, {"grid": 1}, {"refinements": -1}, {"grid": 2.5}])
def test_rate_limited_planning_refuses_a_degenerate_search(bad):
    with pytest.raises(ValueError, match="must be an int >="):
        plan_rate_limited(None, None, None, 0.5, 100.0, **bad)


def test_a_motion_of_mismatched_parts_is_refused_by_shape(move_2r):
    arm, motion = move_2r
    short = design.Motion(motion.q, motion.qd[:-1], motion.qdd)
    with pytest.raises(ValueError, match=r"got q \(8, 2\), qd \(7, 2\), qdd \(8, 2\)"):
        design.rms_force(arm, short)
    flat = design.Motion(*(x[0] for x in motion))
    with pytest.raises(ValueError, match=r"each have shape \(t, 2\)"):
        design.rms_force(arm, flat)
    with pytest.raises(ValueError, match=r"each have shape \(t, 2\)"):
        design.codesign(arm, flat, "rms_force")


def test_a_bound_of_the_wrong_shape_is_named(move_2r):
    arm, motion = move_2r
    with pytest.raises(ValueError, match=r"upper\['counter_mass'\] has shape \(5,\)"):
        design.codesign(arm, motion, "rms_force", upper={"counter_mass": jnp.ones(5)})


def test_a_robot_parameter_set_to_a_python_number_is_named():
    arm = eqx.tree_at(lambda r: r.payload, jaxbal.robots.planar_2r(), 1.0)
    with pytest.raises(ValueError, match="PlanarArm.payload is a Python number"):
        jaxbal.center_of_mass(arm, jnp.zeros(2))
