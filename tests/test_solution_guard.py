"""A solver's output that failed is NaN with the runtime checks off (an optimiser's line
search, a sweep, a tolerance search), not finite joint angles of another motion.

Found in session 38 through ``jaxbal.sensitivity.tolerance``: a re-planned COM motion out
of the robot's reach evaluated finite in a program traced with the checks off (the
closed-form COM inverse kinematics clamps its discriminant, Newton returns its last
iterate), and ended an interval as if the metric had risen there; the co-design line
searches run the same way."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal import robots
from jaxbal._src.com_components import planned_com
from jaxbal._src.com_ik import com_inverse_kinematics
from jaxbal.design import ComTrapezoid, rms_force

FAR = {  # (robot, what is solved, a reachable end-effector pose, a target out of reach)
    "planar_2r_com": (robots.planar_2r, "com", [0.225, 0.25], [5.0, 5.0]),
    "planar_2r_pose": (robots.planar_2r, "pose", [0.225, 0.25], [5.0, 5.0]),
    "orthoglide_com": (robots.orthoglide, "com", [0.0, 0.0, 0.0], [2.0, 2.0, 2.0]),
    "dual_v_com_newton": (robots.dual_v, "com", [0.0, 0.0, 0.0], [3.0, 3.0]),
    "dual_v_pose": (robots.dual_v, "pose", [0.0, 0.0, 0.0], [3.0, 3.0, 0.0]),
}


def _solve(robot, kind, target):
    if kind == "com":  # the robot's closed form, or Newton (the DUAL-V)
        return com_inverse_kinematics(robot, target)
    return robot.inverse_kinematics(target)


def _target(robot, kind, pose):
    if kind == "pose":
        return pose
    return planned_com(robot, robot.inverse_kinematics(pose), robot.com_components)


@pytest.mark.parametrize("name", sorted(FAR))
def test_an_unreachable_target_is_nan_with_the_checks_off(name):
    make, kind, pose, far = FAR[name]
    robot = make()
    near, far = _target(robot, kind, jnp.asarray(pose)), jnp.asarray(far)
    with jaxbal.runtime_checks(False):
        solve = jax.jit(lambda r, x: _solve(r, kind, x))
        assert np.all(np.isnan(np.asarray(solve(robot, far))))
        np.testing.assert_allclose(solve(robot, near), _solve(robot, kind, near), rtol=1e-12)
    with pytest.raises(ValueError, match="reach|workspace"):
        _solve(robot, kind, far)
    with pytest.raises(Exception, match="reach|workspace"):
        jax.block_until_ready(jax.jit(lambda r, x: _solve(r, kind, x))(robot, far))


def test_a_re_planned_com_motion_out_of_reach_is_nan_and_its_gradient_finite_in_reach():
    """The 2R's ComTrapezoid across the base: an 8 kg counter-mass on link 2 shrinks
    link 2's equivalent length and the COM line crosses the hole of the COM workspace
    (2 kg does not). NaN with the checks off (it was a finite motion), and within reach
    the counter-mass gradient of the RMS force is finite and the same as checked."""
    arm = robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.2, 0.5]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([-0.2, 0.5]), branch=-1)
    factory = ComTrapezoid(q0, q1, jnp.linspace(0.0, 0.5, 21), branch=1)
    theta = {"u2": 0.25, "ratio": 1.0}

    def designed(mass):
        design = {"counter_mass": jnp.stack([0.0, mass]), "counter_distance": jnp.array([0.0, 0.1])}
        return arm.with_design(design)

    def rms(mass):
        robot = designed(mass)
        return rms_force(robot, factory(robot, theta))

    masses = jnp.array([2.0, 8.0])
    assert [bool(np.all(factory.valid(designed(m), theta))) for m in masses] == [True, False]
    with jaxbal.runtime_checks(False):
        values = jax.jit(jax.vmap(rms))(masses)
        grad_off = jax.jit(jax.grad(rms))(masses[0])
    assert np.isfinite(values[0]) and np.isnan(values[1])
    grad_on = jax.jit(jax.grad(rms))(masses[0])
    assert np.isfinite(grad_on) and float(grad_off) == pytest.approx(float(grad_on), rel=1e-12)
    with pytest.raises(Exception, match="not reachable|does not start"):
        jax.block_until_ready(jax.jit(rms)(masses[1]))
