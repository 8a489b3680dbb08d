"""An inertia that is zero up to rounding is accepted as a mass is, and the DUAL-V's
counter-mass inertia is derived without cancellation.

Found in session 38 with :func:`jaxbal.sensitivity.tolerance`: the sensitivity of the
co-designed DUAL-V (the README's, counter-masses of no own inertia) to its counter-masses
was refused — under ``jit`` ``with_design`` rounded their inertias to −1.8e-18 kg·m², and
the inertia check's floor was 1e-21 kg·m² (the mass check's is 1e-12 kg)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.profiles import Quintic

#: counter-masses of no own inertia; at this mass and distance ``m·p² − m·(m·p/m)²``
#: is −1.4e-17 in float64 (the README's co-design rounded alike under ``jit``)
DESIGN = {
    "counter_mass": jnp.array([5.694370902855412, 3.10158531, 4.76258825, 3.74247629]),
    "counter_distance": jnp.array([0.114718951157425, 0.1, 0.1, 0.1]),
}


@pytest.fixture(scope="module")
def dual_v_move():
    robot = jaxbal.robots.dual_v(counter_masses=False)
    u0, u1 = jnp.array([0.0, -0.05, 0.0]), jnp.array([0.05, 0.05, 0.0])
    move = jaxbal.planning.EndEffectorLine(robot, jaxbal.StraightLine(u0, u1, Quintic(), 0.1))
    motion = jaxbal.design.motion_samples(robot, [move], jaxbal.sample_times(0.1, 16))
    return robot.with_design(DESIGN), motion


def test_codesigned_dual_v_sensitivity_to_its_counter_masses(dual_v_move):
    robot, motion = dual_v_move
    result = jaxbal.sensitivity.sensitivity(
        robot, motion, "rms_force", wrt=("counter_mass", "counter_distance"), check=True
    )
    for gradient in result.gradient.values():
        assert np.all(np.isfinite(np.asarray(gradient)))
        assert np.all(np.abs(np.asarray(gradient)) > 1e-3)


def test_dual_v_redesigned_keeps_non_negative_inertias(dual_v_move):
    robot, _ = dual_v_move

    def inertias(design):
        return robot.with_design(design).mass_properties().inertia[..., 2, 2]

    assert np.all(np.asarray(inertias(robot.design())) >= 0.0)
    assert np.all(np.asarray(jax.jit(inertias)(robot.design())) >= 0.0)
    # Table 1's counter-masses (tuning masses folded in) keep their inertia about A_i
    table = jaxbal.robots.dual_v()
    redesigned = table.with_design(table.design())
    np.testing.assert_allclose(
        redesigned.counter_mass_inertia_about_base(),
        table.counter_mass_inertia_about_base(),
        rtol=1e-14,
    )


def test_an_inertia_zero_up_to_rounding_passes_and_a_negative_one_is_refused():
    arm = jaxbal.robots.planar_2r()
    q = jnp.array([0.3, 1.1])

    def force(inertias):
        robot = eqx.tree_at(lambda r: r.inertias, arm, inertias)
        return jaxbal.shaking_wrench(robot, q, jnp.ones(2), jnp.ones(2))[0]

    rounded = jnp.array([float(arm.inertias[0]), -1.8e-18])
    zero = jnp.array([float(arm.inertias[0]), 0.0])
    np.testing.assert_allclose(jax.jit(force)(rounded), force(zero), atol=1e-12)
    with pytest.raises(Exception, match="positive semi-definite"):
        jax.block_until_ready(jax.jit(force)(jnp.array([float(arm.inertias[0]), -1e-6])))
