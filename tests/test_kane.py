"""``jaxbal.inverse_dynamics`` (Kane's form: the Newton–Euler wrench of every body
projected on its partial velocities) against an independent evaluation, Lagrange's
equations by differentiating the kinetic and potential energies twice
(``dynamics.lagrange_forces``), on the five robots and on random 3-D MJCF mechanisms
(hinges, slides, full inertias), gravity included: 1e-11 of the largest force."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for
from test_contract import DURATION, _motion
from test_mjcf_robot import _mechanism, _random_states, _template

import jaxbal
from jaxbal import robots
from jaxbal._src.actuation import velocity_basis
from jaxbal._src.dynamics import lagrange_forces
from jaxbal.design import motion_samples
from jaxbal.robots import from_mjcf

GRAVITY = jnp.array([0.3, -1.2, -9.81])


def _compare(robot, q, qd, qdd):
    """Forces projected on the velocities that keep the loops closed (``Nᵀ Q``; all of
    ``Q`` for a serial robot), at ``q̇`` in those directions: the Orthoglide's
    parallelogram frames are rotations only on its loops, so the two forms differ in
    the other directions, which the actuator torques never see."""

    def both(a, b, c):
        basis = velocity_basis(robot, a)
        b = basis @ b[np.asarray(robot.independent)]
        kane = jaxbal.inverse_dynamics(robot, a, b, c, GRAVITY)
        return basis.T @ kane, basis.T @ lagrange_forces(robot, a, b, c, GRAVITY)

    kane, lagrange = jax.jit(jax.vmap(both))(q, qd, qdd)
    scale = float(jnp.max(jnp.abs(lagrange)))
    assert scale > 1e-3 and np.all(np.isfinite(np.asarray(kane)))
    np.testing.assert_allclose(kane, lagrange, rtol=0, atol=1e-11 * scale)


# the 2R, 3R and SCARA (serial, like the random spatial mechanism below, which stays) and
# the DUAL-V (a closed chain, like the Orthoglide, which stays) in make test-all; the 2R's
# torques stay checked by virtual work (test_contract) and the base moment (test_planar_arm)
@pytest.mark.parametrize(
    "name", slow_for(sorted(robots.ROBOTS), "planar_2r", "planar_3r", "scara", "dual_v")
)
def test_kane_equals_lagrange_on_every_robot(name):
    """Each robot (the closed chains' generalised forces reduced by their loop
    closures) at poses along the contract's line with random rates."""
    robot, path = _motion(name)
    q = motion_samples(robot, [path], jaxbal.sample_times(DURATION, 16)).q
    rng = np.random.default_rng(7)
    qd, qdd = (jnp.asarray(rng.uniform(-s, s, q.shape)) for s in (3.0, 10.0))
    _compare(robot, q, qd, qdd)


@pytest.mark.parametrize("seed", slow_for([0, 1, 2], 0, 1, 2))  # make test-all
def test_kane_equals_lagrange_on_random_spatial_mechanisms(seed):
    """Random MJCF trees of 5 hinge/slide joints with rotated full inertias."""
    rng = np.random.default_rng(seed)
    robot = from_mjcf(_mechanism(_template(rng, 5), rng))
    _compare(robot, *(jnp.asarray(x) for x in _random_states(rng, robot, 16)))


def test_wrong_gravity_shape_is_refused():
    robot = robots.planar_2r()
    zero = jnp.zeros(2)
    with pytest.raises(ValueError, match="gravity"):
        jaxbal.inverse_dynamics(robot, zero, zero, zero, jnp.zeros(2))
