"""The planar evaluation of the shaking wrench equals the general 3-D one.

Reference: :func:`jaxbal._src.momentum.inertial_wrench` (3×3 rotations, angular momentum
R I Rᵀ ω) on the same robot and states; tolerance 1e-12 relative. The test robot has
products of inertia and COM heights, which only the general formula sees directly.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.momentum import inertial_wrench, tree_wrench
from jaxbal._src.planar import PlanarRobot, planar_inertial_wrench
from jaxbal._src.robot import Bodies


class Swinger(PlanarRobot):
    """Two bodies: a crank about O and a slider-crank-like body with its own angle."""

    length: jax.Array
    bodies: Bodies

    @property
    def dof(self):
        return 3

    def mass_properties(self):
        return self.bodies

    # The contract's kinematics: the coordinates are the pose (identity, every pose
    # reachable); only the shaking wrench is under test here.
    def end_effector(self, q):
        return jnp.asarray(q, dtype=float)

    def inverse_kinematics(self, pose, *, branch=None, return_valid=False):
        self.branch(branch)  # validates the argument
        q = jnp.asarray(pose, dtype=float)
        return (q, jnp.all(jnp.isfinite(q))) if return_valid else q

    def planar_frames(self, q):
        origin2 = self.length * jnp.stack([jnp.cos(q[0]), jnp.sin(q[0])])
        origins = jnp.stack([jnp.zeros(2), origin2 + jnp.array([0.0, q[2]])])
        return origins, jnp.stack([q[0], q[1]])


def swinger():
    inertia = jnp.array(
        [
            [[0.3, 0.02, 0.05], [0.02, 0.4, -0.03], [0.05, -0.03, 0.2]],
            [[0.1, 0.0, -0.02], [0.0, 0.12, 0.04], [-0.02, 0.04, 0.07]],
        ]
    )
    bodies = Bodies(
        mass=jnp.array([2.0, 1.5]),
        com=jnp.array([[0.1, 0.02, 0.05], [0.05, -0.03, -0.08]]),
        inertia=inertia,
        names=("crank", "rocker"),
    )
    return Swinger(jnp.asarray(0.4), bodies)


def random_states(count, dof, seed=0):
    rng = np.random.default_rng(seed)
    return tuple(jnp.asarray(rng.normal(size=(count, dof)) * s) for s in (2.0, 4.0, 40.0))


def test_planar_path_equals_general_path_with_products_of_inertia():
    robot = swinger()
    q, qd, qdd = random_states(20, 3)
    fast = jax.jit(jax.vmap(lambda *s: planar_inertial_wrench(robot, *s)))(q, qd, qdd)
    general = jax.jit(jax.vmap(lambda *s: inertial_wrench(robot, *s)))(q, qd, qdd)
    for a, b in zip(fast, general, strict=True):
        scale = float(jnp.max(jnp.abs(b)))
        np.testing.assert_allclose(a, b, atol=1e-12 * scale)
    assert float(jnp.max(jnp.abs(general[1][:, :2]))) > 1e-3  # x/y moments are exercised


@pytest.mark.slow
def test_shaking_wrench_dispatches_for_planar_arms():
    for arm in (jaxbal.robots.planar_2r(), jaxbal.robots.planar_3r()):
        assert isinstance(arm, PlanarRobot)
        q, qd, qdd = random_states(10, arm.dof, seed=1)
        fast = jax.vmap(lambda *s, arm=arm: jaxbal.shaking_wrench(arm, *s))(q, qd, qdd)
        general = jax.vmap(lambda *s, arm=arm: inertial_wrench(arm, *s))(q, qd, qdd)
        for a, b in zip(fast, general, strict=True):
            np.testing.assert_allclose(a, b, atol=1e-12 * float(jnp.max(jnp.abs(b))))


# make test-all: the DUAL-V's planar-path wrench is confirmed by MuJoCo in make test
# (test_mujoco_closure.py)
@pytest.mark.slow
def test_dual_v_planar_path_equals_general_path():
    """DUAL-V (22 bodies, counter-masses, rotors): planar = general evaluation, 1e-12."""
    robot = jaxbal.robots.dual_v()
    assert isinstance(robot, PlanarRobot)
    q, qd, qdd = random_states(5, 11, seed=2)
    # random states, off its loops: the bodies' wrench (tree_wrench), as inertial_wrench
    fast = jax.vmap(lambda *s: tree_wrench(robot, *s))(q, qd, qdd)
    general = jax.vmap(lambda *s: inertial_wrench(robot, *s))(q, qd, qdd)
    for a, b in zip(fast, general, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12 * float(jnp.max(jnp.abs(b))))
