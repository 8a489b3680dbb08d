"""A refused or singular pose gives no silent derivative (session 42's hostile use):

* under ``jit``, the derivatives of an inverse kinematics at a pose it refuses (out of
  reach) were zeros: its runtime check guards the primal ``q``, which ``jacfwd`` drops,
  and the NaN it put in ``q`` was a select (derivative 0). They are NaN now, and the
  rates of :func:`jaxbal.pose_motion` (its tangents) are checked themselves;
* an MJCF robot's implicit (Newton) inverse kinematics accepts a pose at a singular
  configuration (an arm stretched): :func:`jaxbal.pose_motion` returned ``q̇ = inf``,
  ``q̈ = NaN``, eagerly too. Now refused, naming the pose.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal

ARM_XZ = """
<mujoco>
  <worldbody>
    <body name="l1"><joint name="j1" axis="0 1 0"/>
      <inertial pos="0.15 0 0" mass="1" diaginertia="1e-3 1e-2 1e-2"/>
      <body name="l2" pos="0.3 0 0"><joint name="j2" axis="0 1 0"/>
        <inertial pos="0.1 0 0" mass="0.5" diaginertia="1e-4 4e-3 4e-3"/>
        <site name="tip" pos="0.25 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_derivatives_at_a_refused_pose_are_nan_under_jit_never_zero():
    arm = jaxbal.robots.planar_2r()
    reach = float(jnp.sum(arm.lengths))

    def ik(p):
        return arm.inverse_kinematics(p, branch=-1)

    poses = jnp.array([[0.5, 0.3], [1.5 * reach, 0.0]])  # reachable, out of reach
    jacobians = np.asarray(jax.jit(jax.vmap(jax.jacfwd(ik)))(poses))
    np.testing.assert_allclose(jacobians[0], np.asarray(jax.jacfwd(ik)(poses[0])), rtol=1e-14)
    assert np.all(np.isnan(jacobians[1]))  # was [[0, 0], [0, 0]]
    assert np.all(np.isnan(np.asarray(jax.jit(jax.grad(lambda p: ik(p).sum()))(poses[1]))))
    with jaxbal.runtime_checks(False):  # no check left: the value itself says it
        rate = jax.jit(lambda p: jaxbal.pose_motion(arm, p, jnp.array([0.1, 0]), jnp.zeros(2)))
        assert np.all(np.isnan(np.asarray(rate(poses[1])[1])))
    with pytest.raises(Exception, match="out of reach or at a singular configuration"):
        jax.jit(lambda p: jaxbal.pose_motion(arm, p, jnp.array([0.1, 0]), jnp.zeros(2))[1])(
            poses[1]
        ).block_until_ready()


def test_pose_motion_at_a_singular_configuration_of_an_mjcf_arm_is_refused():
    robot = jaxbal.robots.from_mjcf(ARM_XZ, end_effector_site="tip")
    stretched = robot.end_effector(jnp.zeros(2))
    bent = robot.end_effector(jnp.array([0.2, 0.9]))
    rate, acceleration = jnp.array([-1.0, 0.0]), jnp.zeros(2)
    q, qd, qdd = jaxbal.pose_motion(robot, bent, rate, acceleration)  # regular: finite
    np.testing.assert_allclose(jax.jacfwd(robot.end_effector)(q) @ qd, rate, atol=1e-12)
    with pytest.raises(ValueError, match="singular configuration"):
        jaxbal.pose_motion(robot, stretched, rate, acceleration)  # was q̇ = inf, q̈ = NaN
    with pytest.raises(ValueError, match="singular configuration"):
        robot.pose_motion(stretched, rate, acceleration)
    *_, valid = robot.pose_motion(stretched, rate, acceleration, return_valid=True)
    assert not bool(valid)
