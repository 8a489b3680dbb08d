"""Joint couplings (MuJoCo joint equalities, URDF mimic joints): a counter-rotating
disk geared to a link cancels its shaking moment (jaxbal._src.robots.mjcf_couplings).

References: the closed form of a link and a geared disk turning about the same fixed
axis (angular momentum ``(I_link − r I_disk) q̇``), MuJoCo C closing the coupling itself
(``mj_inverse`` on the exported model), finite differences of the gear ratio's
gradient, MuJoCo's own URDF compiler for ``<mimic>``.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.mujoco import confirm
from jaxbal.robots import from_mjcf, from_urdf

I_LINK, I_DISK = 0.06, 0.012  # kg·m² about z, both COMs on the axis
BALANCING_RATIO = I_LINK / I_DISK  # disk turns 5x faster the other way
STATE = (0.3, 1.7, -4.2)  # link angle [rad], rate [rad/s], acceleration [rad/s²]


def _geared(polycoef: str, ref: float = 0.0) -> str:
    """A bar turning about z through its COM and a disk on the same axis, the disk
    geared to the bar: ``q_disk − ref = p(q_bar)``; a tip site on the bar."""
    inertial = '<inertial pos="0 0 0" mass="{m}" diaginertia="{i} {i} {j}"/>'
    return (
        '<mujoco><compiler angle="radian"/><option gravity="0 0 0"/><worldbody>'
        f'<body name="bar"><joint name="bar" axis="0 0 1"/>{inertial.format(m=2, i=0.03, j=I_LINK)}'
        '<site name="tip" pos="0.3 0 0"/></body>'
        f'<body name="disk" pos="0 0 0.05"><joint name="disk" axis="0 0 1" ref="{ref}"/>'
        f"{inertial.format(m=1, i=0.007, j=I_DISK)}</body>"
        f'</worldbody><equality><joint joint1="disk" joint2="bar" polycoef="{polycoef}"/>'
        '</equality><actuator><motor joint="bar"/></actuator></mujoco>'
    )


def _state(robot, u=STATE):
    """Full ``(q, q̇, q̈)`` from the bar's angle, rate and acceleration (coupling solved)."""
    return robot.closure_motion(*(jnp.array([v]) for v in u))


def test_the_disk_is_a_dependent_coordinate_following_its_polynomial():
    """The coupled disk is not independent (default: the motor's joint); its angle,
    rate and acceleration follow the polynomial (here with a quadratic term and a
    reference angle) exactly (1e-12)."""
    robot = from_mjcf(_geared("0.1 -2 0.5 0 0", ref=0.2))
    assert robot.independent == robot.actuated == (robot.coordinate("bar"),)
    assert robot.closure_count() == 1 and robot.coupling_names == ("equality0",)
    q, q_d, q_dd = _state(robot)
    x, v, a = STATE
    np.testing.assert_allclose(q, [x, 0.2 + 0.1 - 2 * x + 0.5 * x**2], atol=1e-12)
    np.testing.assert_allclose(q_d[1], (-2 + x) * v, atol=1e-12)
    np.testing.assert_allclose(q_dd[1], (-2 + x) * a + v**2, atol=1e-12)


@pytest.mark.parametrize("ratio", [BALANCING_RATIO, 2.0])
def test_a_geared_counter_rotation_cancels_the_shaking_moment(ratio):
    """Angular momentum about the axis ``(I_link − r I_disk) q̇`` (gear ratio ``−r``):
    the base feels ``−(I_link − r I_disk) q̈`` about z and no force; zero (1e-12) at
    ``r = I_link / I_disk``."""
    robot = from_mjcf(_geared(f"0 {-ratio} 0 0 0"))
    force, moment = jaxbal.shaking_wrench(robot, *_state(robot))
    np.testing.assert_allclose(force, 0.0, atol=1e-12)
    np.testing.assert_allclose(
        moment, [0.0, 0.0, -(I_LINK - ratio * I_DISK) * STATE[2]], atol=1e-12
    )


def test_mujoco_closes_the_coupling_itself_and_agrees():
    """MuJoCo C, given the bar's motion only, places the disk by its own joint equality
    (exported with the model: same angle to 1e-12) and its base reaction equals jaxbal's
    (1e-9), also with a quadratic coupling (its curvature term in the acceleration)."""
    robot = from_mjcf(_geared("0.1 -3 0.7 0.2 0", ref=0.2))
    times = np.linspace(0.0, 1.0, 4)
    u = jnp.stack([0.4 * np.sin(3 * times), 1.2 * np.cos(3 * times), -3.6 * np.sin(3 * times)])
    motion = jax.jit(jax.vmap(lambda r, a, b, c: _state(r, (a, b, c)), (None, 0, 0, 0)))(robot, *u)
    result = confirm(robot, *motion)
    assert result.independent and result.closed_by_mujoco
    assert result.relative < 1e-9 and result.closure_difference < 1e-12, result


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_gradient_of_the_moment_in_the_gear_ratio():
    """d(moment_z)/d(a1) through the coupling's Newton solve (implicit differentiation)
    equals the closed form ``−I_disk q̈`` and central finite differences."""
    robot = from_mjcf(_geared(f"0 {-2.0} 0 0 0"))

    def moment(a1):
        coef = robot.coupling_coef.at[0, 1].set(a1)
        geared = eqx.tree_at(lambda r: r.coupling_coef, robot, coef)
        return jaxbal.shaking_wrench(geared, *_state(geared))[1][2]

    moment = jax.jit(moment)
    gradient = jax.grad(moment)(-2.0)
    assert np.isfinite(gradient)
    np.testing.assert_allclose(gradient, -I_DISK * STATE[2], rtol=1e-10)
    check_grads(moment, (-2.0,), order=1, modes=("rev",))


def test_urdf_mimic_joint_is_a_coupling():
    """A URDF ``<mimic multiplier="2" offset="0.1">`` elbow follows its shoulder
    (MuJoCo's URDF compiler writes a joint equality): one independent joint, and the
    elbow at ``2 q + 0.1``."""
    link = (
        '<link name="{n}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/>'
        '<inertia ixx="1e-3" iyy="1e-2" izz="1e-2" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    )
    urdf = (
        f'<robot name="arm"><link name="base"/>{link.format(n="l1")}{link.format(n="l2")}'
        '<joint name="shoulder" type="continuous"><parent link="base"/><child link="l1"/>'
        '<axis xyz="0 0 1"/></joint>'
        '<joint name="elbow" type="continuous"><parent link="l1"/><child link="l2"/>'
        '<origin xyz="0.2 0 0"/><axis xyz="0 0 1"/>'
        '<mimic joint="shoulder" multiplier="2" offset="0.1"/></joint></robot>'
    )
    robot = from_urdf(urdf)
    assert robot.independent == (robot.coordinate("shoulder"),)
    np.testing.assert_allclose(robot.closure(jnp.array([0.3])), [0.3, 0.7], atol=1e-12)


def test_unsupported_equalities_are_named():
    """A weld is still refused, naming the kinds jaxbal reads."""
    xml = _geared("0 -2 0 0 0").replace(
        "</equality>", '<weld name="glue" body1="bar" body2="disk"/></equality>'
    )
    with pytest.raises(ValueError, match="'glue' of type 'weld' .*only connect and joint"):
        from_mjcf(xml)
