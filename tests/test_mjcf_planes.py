"""MJCF mechanisms in other planes than x-y, and the load-time checks of their options.

References and tolerances, per test:

* the COM planned in the plane the mechanism moves in (``robot.com_components``): the
  COM of the solved configuration, recomputed by :func:`jaxbal.center_of_mass`, equals
  the target to 1e-10 m, and the configuration whose COM it was is found again to 1e-8;
* the same arm drawn in the x-y plane (hinges about z) is the x-z arm mirrored: the
  same peak shaking force of the COM plan to 1e-9 relative, and the COM of the x-z
  plan on its straight x-z line at every sample to 1e-9 m (slow: ~1 min of compiles);
* the built-in robots keep the slice ``[:2]``: their COM plan's ends are bit-identical
  to ``center_of_mass(robot, q)[:2]``;
* the default pose axes are independent: the pose Jacobian of the yawed vertical-plane
  arm is regular (``|det|`` > 1e-3 m², a generic configuration);
* errors: the message names the option at fault (``pose_components``, ``ik_free``,
  ``no moving bodies``, ``com_components``).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.com_components import com_components, planned_com
from jaxbal._src.com_ik import numerical_com_inverse_kinematics
from jaxbal._src.planning import com_plan
from jaxbal.profiles import Quintic
from jaxbal.robots import from_mjcf, from_urdf

ARM_XZ = """<mujoco><worldbody>
 <body name="l1"><joint name="j1" axis="0 1 0"/>
  <inertial pos="0.2 0 0" mass="2" diaginertia="0.001 0.03 0.03"/>
  <body name="l2" pos="0.4 0 0"><joint name="j2" axis="0 1 0"/>
   <inertial pos="0.15 0 0" mass="1" diaginertia="0.001 0.01 0.01"/>
   <site name="tip" pos="0.3 0 0"/></body></body></worldbody></mujoco>"""
ARM_XY = ARM_XZ.replace('axis="0 1 0"', 'axis="0 0 1"')
#: the x-z arm mounted with a 45° yaw: its tip's x and y are always equal.
ARM_YAWED = (
    ARM_XZ.replace("<mujoco>", "<mujoco><compiler angle='radian'/>")
    .replace('<body name="l1">', '<body name="mount" euler="0 0 0.785398163"><body name="l1">')
    .replace("</body></body></worldbody>", "</body></body></body></worldbody>")
)
FIVE_BAR = """<mujoco><worldbody>
 <body name="L1" pos="-0.1 0 0"><joint name="a1" axis="0 0 1"/>
  <inertial pos="0.1 0 0" mass="0.4" diaginertia="1e-4 4e-3 4e-3"/>
  <body name="L2" pos="0.2 0 0"><joint name="p1" axis="0 0 1"/>
   <inertial pos="0.12 0 0" mass="0.3" diaginertia="1e-4 3e-3 3e-3"/>
   <site name="tip" pos="0.25 0 0"/></body></body>
 <body name="R1" pos="0.1 0 0"><joint name="a2" axis="0 0 1"/>
  <inertial pos="0.1 0 0" mass="0.4" diaginertia="1e-4 4e-3 4e-3"/>
  <body name="R2" pos="0.2 0 0"><joint name="p2" axis="0 0 1"/>
   <inertial pos="0.12 0 0" mass="0.3" diaginertia="1e-4 3e-3 3e-3"/>
   <site name="end2" pos="0.25 0 0"/></body></body></worldbody>
 <equality><connect site1="tip" site2="end2"/></equality>
 <actuator><motor joint="a1"/><motor joint="a2"/></actuator></mujoco>"""
Q0, Q1 = jnp.array([-0.3, 1.0]), jnp.array([-1.2, 1.4])


@pytest.fixture(scope="module")
def arm_xz():
    return from_mjcf(ARM_XZ).with_reference(Q0)


@pytest.fixture(scope="module")
def arm_xy():
    return from_mjcf(ARM_XY).with_reference(Q0)


# --- defect 1: the COM is planned in the plane the mechanism moves in -----------------


def test_xz_arm_plans_its_com_in_x_z(arm_xz, arm_xy):
    assert arm_xz.pose_components == (0, 2) and arm_xz.com_components == (0, 2)
    assert arm_xz.com_dims == 2 and com_components(arm_xz) == (0, 2)
    assert arm_xy.com_components == (0, 1) and com_components(arm_xy) == (0, 1)
    # another count than the plane's is refused by name (it planned x, y, z: singular)
    with pytest.raises(ValueError, match="com_components"):
        com_plan(arm_xz, Q0, Q1, Quintic(), 0.5, dims=3)


def test_xz_com_inverse_kinematics(arm_xz):
    """Reference: the configuration whose COM is the target (found again, 1e-8), and
    the COM recomputed at the solution (1e-10 m). Before: the residual took the world
    (x, y) of an x-z arm, y constant: a singular Newton solve."""
    q_true = jnp.array([-0.5, 1.1])
    com = jaxbal.center_of_mass(arm_xz, q_true)
    target = com[jnp.array([0, 2])]
    q = numerical_com_inverse_kinematics(arm_xz, target, guess=arm_xz.end_effector(q_true))
    np.testing.assert_allclose(q, q_true, atol=1e-8)
    np.testing.assert_allclose(planned_com(arm_xz, q, (0, 2)), target, atol=1e-10)
    # a world COM (a user's center_of_mass as the target) gives its (x, z)
    q3 = numerical_com_inverse_kinematics(arm_xz, com, guess=arm_xz.end_effector(q_true))
    np.testing.assert_array_equal(q3, q)


def test_builtin_robots_keep_the_leading_slice():
    """Reference: ``center_of_mass(robot, q)[:2]``, bit for bit (the built-in robots
    plan x, y as before the projection existed)."""
    robot = jaxbal.robots.scara()
    q0 = robot.inverse_kinematics(robot.end_effector(jnp.full(robot.dof, 0.3)))
    q1 = robot.inverse_kinematics(robot.end_effector(jnp.full(robot.dof, 0.6)))
    assert com_components(robot) == tuple(range(robot.com_dims))
    plan = com_plan(robot, q0, q1, Quintic(), 0.5)
    d = robot.com_dims
    np.testing.assert_array_equal(plan.line.start, jaxbal.center_of_mass(robot, q0)[:d])
    np.testing.assert_array_equal(plan.line.end, jaxbal.center_of_mass(robot, q1)[:d])
    np.testing.assert_array_equal(
        planned_com(robot, q0, com_components(robot)), jaxbal.center_of_mass(robot, q0)[:d]
    )


@pytest.mark.slow
def test_xz_com_line_matches_the_xy_arm(arm_xz, arm_xy):
    """Reference: the x-y arm is the x-z arm mirrored (the same peak force, 1e-9
    relative), and the x-z plan's COM lies on its straight x-z line (1e-9 m)."""
    from jaxbal._src.trajectory import sample

    times = jaxbal.sample_times(0.5, 11)
    plans, peaks = [], []
    for arm in (arm_xz, arm_xy):
        plans.append(jaxbal.planning.com_line(arm, Q0, Q1, Quintic(), 0.5))
        force, _ = jaxbal.planning.wrench_along(arm, plans[-1], times)
        peaks.append(float(jaxbal.planning.peak_norm(force)))
    np.testing.assert_allclose(peaks[0], peaks[1], rtol=1e-9)
    (q,) = sample(plans[0], times, order=0)
    coms = jax.vmap(lambda c: jaxbal.center_of_mass(arm_xz, c))(q)
    start, end = (jaxbal.center_of_mass(arm_xz, c) for c in (Q0, Q1))
    fraction = Quintic()(times / 0.5)
    expected = start[None, :] + np.asarray(fraction)[:, None] * (end - start)[None, :]
    np.testing.assert_allclose(coms, expected, atol=1e-9)


# --- defect 2: default pose axes are independent ---------------------------------------


def test_yawed_vertical_arm_gets_independent_pose_axes():
    """Reference: a regular pose Jacobian at a generic configuration. Before: (x, y),
    always equal for this arm, a singular pose."""
    robot = from_mjcf(ARM_YAWED)
    assert robot.pose_components == (0, 2)
    jacobian = jax.jacfwd(robot.end_effector)(jnp.array([-0.3, 1.0]))
    assert abs(float(jnp.linalg.det(jacobian))) > 1e-3


# --- defect 3: no moving bodies ---------------------------------------------------------


@pytest.mark.parametrize(
    "load",
    [
        lambda: from_mjcf("<mujoco/>"),
        lambda: from_urdf('<robot name="x"><link name="only"/></robot>'),
        lambda: from_mjcf("<mujoco><worldbody><body><geom size='.1'/></body></worldbody></mujoco>"),
    ],
    ids=["empty", "urdf-one-link", "no-joints"],
)
def test_no_moving_bodies_is_refused(load):
    with pytest.raises(ValueError, match="no moving bodies"):
        load()


# --- defect 4: a site on the base is never the default end effector ---------------------

PENDULUM = (
    "<mujoco><worldbody><site name='marker' pos='1 0 0'/><body name='bob'>"
    "<joint name='swing' axis='0 1 0'/><geom size='.05' pos='0 0 -0.3'/>{site}</body>"
    "</worldbody></mujoco>"
)


def test_ground_marker_is_not_the_end_effector():
    robot = from_mjcf(PENDULUM.format(site=""))
    assert robot.dof == 1 and robot.site_name is None
    # the only site on a moving body is picked, the marker ignored
    robot = from_mjcf(PENDULUM.format(site="<site name='bob_tip' pos='0 0 -0.3'/>"))
    assert robot.site_name == "bob_tip" and robot.pose_components == (0,)


# --- defect 5: pose options checked at load, by name ------------------------------------


@pytest.mark.parametrize(
    ("source", "options", "named"),
    [
        (FIVE_BAR, {"end_effector_site": "tip", "ik_free": "p1"}, "ik_free: 'p1'"),
        (ARM_XZ, {"pose_components": (0, 1, 2)}, "pose_components"),
        (ARM_XZ, {"ik_free": "j1,j2"}, "ik_free"),
        (ARM_XZ, {"pose_components": (0, 1)}, r"pose_components \(0, 1\).*\(0, 2\)"),
    ],
    ids=["dependent-ik-free", "too-many-axes", "too-many-free", "axis-never-moved"],
)
def test_pose_options_checked_at_load(source, options, named):
    with pytest.raises(ValueError, match=named):
        from_mjcf(source, **options)


def test_pose_options_that_fit_load():
    robot = from_mjcf(ARM_XZ, pose_components=(0,), ik_free="j2")
    assert robot.pose_labels() == ("tip.x", "j2")
    assert from_mjcf(FIVE_BAR, end_effector_site="tip").pose_components == (0, 1)


def test_a_moving_body_without_mass_names_the_missing_inertial():
    """A URDF link without ``<inertial>`` gave MuJoCo's "mass and inertia of moving
    bodies must be larger than mjMINVAL" alone; now also what to add."""
    urdf = """<robot name="x"><link name="base"/><link name="l1"/>
    <joint name="j" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""
    with pytest.raises(ValueError, match=r"(?s)mjMINVAL.*give it an <inertial>"):
        from_urdf(urdf)
