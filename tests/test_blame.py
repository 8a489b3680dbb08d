"""A refusal names what is wrong (session 42's hostile use):

* the inverse kinematics of a robot with a NaN or negative parameter (set with
  ``eqx.tree_at``) named the pose ("outside the workspace"), or solved the mirrored
  robot (a negative length squared as a positive one) while every physics function
  refuses that robot: now the robot's parameters are checked first, by name;
* a closed chain's state given in float32 was refused as "off the loops" with a question
  about a changed geometry: its rounding alone exceeds the loop tolerance, and the
  message now says so.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal import robots


def _nan_first(x):
    return jnp.ravel(x).at[0].set(jnp.nan).reshape(jnp.shape(x))


CASES = {  # robot, a reachable pose, the field set to NaN / made negative
    "2r": (robots.planar_2r, [0.3, 0.2], "lengths"),
    "scara": (robots.scara, [0.18, 0.25, 1.5, 0.0], "lengths"),
    "orthoglide": (robots.orthoglide, [0.0, 0.0, 0.0], "length"),
    "dual_v": (robots.dual_v, [0.0, 0.0, 0.0], "l1"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_ik_names_a_bad_robot_parameter_not_the_pose(name):
    make, pose, field = CASES[name]
    robot, pose = make(), jnp.asarray(pose, dtype=float)
    robot.inverse_kinematics(pose)  # reachable by the robot as given
    nan = eqx.tree_at(lambda r: getattr(r, field), robot, _nan_first(getattr(robot, field)))
    with pytest.raises(ValueError, match=rf"must be finite.*{type(robot).__name__}\.{field}"):
        nan.inverse_kinematics(pose)
    negative = eqx.tree_at(lambda r: getattr(r, field), robot, -getattr(robot, field))
    with pytest.raises(ValueError, match=rf"must be >= 0.*{type(robot).__name__}\.{field}"):
        negative.inverse_kinematics(pose)
    # batched code asks for the mask and is never raised at
    q, valid = nan.inverse_kinematics(pose, return_valid=True)
    assert not bool(valid)


def test_com_ik_names_a_bad_robot_parameter():
    arm = robots.planar_2r()
    com = jaxbal.center_of_mass(arm, arm.inverse_kinematics(jnp.array([0.3, 0.2])))
    bad = eqx.tree_at(lambda r: r.lengths, arm, _nan_first(arm.lengths))
    with pytest.raises(ValueError, match=r"must be finite.*PlanarArm\.lengths"):
        bad.com_inverse_kinematics(com)
    ortho = robots.orthoglide()
    com = jaxbal.center_of_mass(ortho, ortho.inverse_kinematics(jnp.array([0.01, 0.0, 0.0])))
    bad = eqx.tree_at(lambda r: r.length, ortho, -ortho.length)
    with pytest.raises(ValueError, match=r"must be >= 0.*Orthoglide\.length"):
        bad.com_inverse_kinematics(com)


def test_a_float32_closed_chain_state_names_its_precision():
    robot = robots.dual_v()
    pose, rate, acceleration = jnp.array([[0.03, -0.02, 0.0], [0.4, 0.3, 0.0], [2, -1, 0.0]])
    q, qd, qdd = jaxbal.pose_motion(robot, pose, rate, acceleration)
    force64, _ = jaxbal.shaking_wrench(robot, q, qd, qdd)
    single = [np.asarray(x, dtype=np.float32) for x in (q, qd, qdd)]
    with pytest.raises(ValueError, match=r"loop closures.*the state is float32.*float64"):
        jaxbal.shaking_wrench(robot, *single)
    with pytest.raises(ValueError, match=r"loop closures.*the state is float32"):
        jaxbal.design.peak_force(robot, jaxbal.design.Motion(*(x[None] for x in single)))
    # the same state in float64 passes, and an off-loop float64 state has no such hint
    assert np.all(np.isfinite(np.asarray(force64)))
    with pytest.raises(ValueError, match=r"another geometry") as refused:
        jaxbal.shaking_wrench(robot, q + 1e-3, qd, qdd)
    assert "float32" not in str(refused.value)
