"""MuJoCo C / MJX independently confirm jaxbal's base reactions.

Reference: MuJoCo's recursive Newton-Euler inverse dynamics (``mj_inverse``) on a
model whose kinematics come from the robot's own geometric parameters
(:mod:`jaxbal.mjx_trees`), not from jaxbal's ``body_frames``. Tolerances: 1e-9
relative for trees (both sides are exact to round-off, observed ~1e-14).
"""

import jax
import mujoco
import numpy as np
import pytest

import jaxbal
from jaxbal.mjcf import prescribed_tree, robot_tree, to_mjcf
from jaxbal.mjx import mujoco_base_reaction, mujoco_inverse, mujoco_model
from jaxbal.robots.planar_arm import PlanarArm, planar_2r, planar_3r

GRAVITY = np.array([0.3, -1.0, -9.81])


def _balanced_3r():
    arm = planar_3r()
    return PlanarArm(
        arm.lengths,
        arm.com_ratios,
        arm.masses,
        arm.inertias,
        payload=5.0,
        counter_masses=[3.0, 1.0, 0.5],
        counter_distances=[0.1, 0.05, 0.02],
    )


ROBOTS = {"2R": planar_2r, "3R": planar_3r, "3R+counterweights": _balanced_3r}


def _states(dof, count, seed=0):
    rng = np.random.default_rng(seed)
    scale = np.array([3.0, 5.0, 50.0])[:, None, None]
    return rng.normal(size=(3, count, dof)) * scale


def _relative(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(np.asarray(b)))


@pytest.mark.parametrize("gravity", [None, GRAVITY], ids=["no-gravity", "gravity"])
@pytest.mark.parametrize("name", list(ROBOTS))
def test_mujoco_base_reaction_matches_shaking_wrench(name, gravity):
    """MuJoCo C base reaction = jaxbal shaking wrench, 1e-9 relative, random states."""
    robot = ROBOTS[name]()
    q, qd, qdd = _states(robot.dof, 8)
    force, moment = mujoco_base_reaction(robot, q, qd, qdd, gravity=gravity)
    ref_force, ref_moment = jax.vmap(
        lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c, gravity=gravity)
    )(q, qd, qdd)
    assert force.shape == (8, 3) and moment.shape == (8, 3)
    assert _relative(force, ref_force) < 1e-9
    assert _relative(moment, ref_moment) < 1e-9
    single = mujoco_base_reaction(robot, q[0], qd[0], qdd[0], gravity=gravity)
    np.testing.assert_array_equal(single[0], force[0])


@pytest.mark.parametrize("name", list(ROBOTS))
def test_mujoco_joint_torques_match_lagrange(name):
    """The tree's qfrc_inverse on the joints = jaxbal.inverse_dynamics (Lagrange), 1e-9."""
    robot = ROBOTS[name]()
    q, qd, qdd = _states(robot.dof, 3, seed=1)
    for sample in zip(q, qd, qdd, strict=True):
        torques = mujoco_inverse(robot, *sample)[6:]
        assert _relative(torques, jaxbal.inverse_dynamics(robot, *sample)) < 1e-9


def test_prescribed_fallback_agrees():
    """The generic (less independent) prescribed tree agrees too, 1e-9 relative."""
    robot = _balanced_3r()
    q, qd, qdd = _states(robot.dof, 4, seed=2)
    tree = prescribed_tree(robot)
    assert not tree.independent
    force, moment = mujoco_base_reaction(robot, q, qd, qdd, gravity=GRAVITY, tree=tree)
    ref_force, ref_moment = jax.vmap(
        lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c, gravity=GRAVITY)
    )(q, qd, qdd)
    assert _relative(force, ref_force) < 1e-9
    assert _relative(moment, ref_moment) < 1e-9


def test_mujoco_kinematics_match_body_frames():
    """MuJoCo's body poses from the tree = jaxbal's body_frames (independent kinematics)."""
    robot = _balanced_3r()
    compiled = mujoco_model(robot)
    data = mujoco.MjData(compiled.model)
    q = np.array([0.3, -1.2, 2.0])
    data.qpos[:] = compiled.qpos(q)
    mujoco.mj_kinematics(compiled.model, data)
    origins, rotations = robot.body_frames(q)
    for i, name in enumerate(robot.mass_properties().names):
        body = compiled.model.body(name).id
        np.testing.assert_allclose(data.xpos[body], origins[i], atol=1e-14)
        np.testing.assert_allclose(data.xmat[body].reshape(3, 3), rotations[i], atol=1e-14)


def test_mjcf_loads_with_masses_and_actuators():
    """The MJCF carries jaxbal's masses, a contact-free option and one motor per joint."""
    robot = _balanced_3r()
    model = mujoco.MjModel.from_xml_string(to_mjcf(robot, gravity=GRAVITY))
    bodies = robot.mass_properties()
    for name, mass in zip(bodies.names, np.asarray(bodies.mass), strict=True):
        assert model.body(name).mass[0] == pytest.approx(mass, rel=1e-15)
    assert model.nu == 3 and model.nv == 6 + 3
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    np.testing.assert_array_equal(model.opt.gravity, GRAVITY)
    assert len(robot_tree(robot).bodies) == len(bodies.names)


def test_bad_input_raises():
    """Wrong shapes and a massless moving link raise a clear ValueError."""
    robot = planar_2r()
    with pytest.raises(ValueError, match="shape"):
        mujoco_base_reaction(robot, np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="shape"):
        mujoco_base_reaction(robot, np.zeros(2), np.zeros(3), np.zeros(2))
    massless = PlanarArm([0.5, 0.3], [0.3, 0.1], [0.0, 8.3], [0.0, 0.05], payload=1.0)
    with pytest.raises(ValueError, match="no mass"):
        to_mjcf(massless)
