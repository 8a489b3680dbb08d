"""MuJoCo C / MJX independently confirm jaxbal's base reactions.

Reference: MuJoCo's recursive Newton-Euler inverse dynamics (``mj_inverse``,
``mjx.inverse``) on models whose kinematics come from each robot's own geometric
parameters (each robot's :meth:`~jaxbal.Robot.mujoco_tree`), not from jaxbal's
``body_frames``.
Tolerances: 1e-9 relative for every robot (trees and closed chains alike; both sides
are exact to round-off and agree to ~1e-14 -- the margin covers MuJoCo's 1e-14
inertia floor on point masses with joints).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import jaxbal
from jaxbal.mujoco import (
    confirm,
    export_mjcf,
    mjx_base_reaction,
    mjx_model,
    mujoco_actuator_efforts,
    mujoco_base_reaction,
    mujoco_inverse,
    mujoco_model,
    prescribed_tree,
    simulate_open_loop,
    to_mjcf,
)
from jaxbal.robots import PlanarArm, Scara, by_name, dual_v, orthoglide, planar_2r, planar_3r

# MuJoCo/MJX cross-checks in depth (test_contract confirms all five robots with
# MuJoCo C in make test): make test-all.
pytestmark = pytest.mark.slow

GRAVITY = np.array([0.3, -1.0, -9.81])
TOL = 1e-9


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


def _scara():
    """A SCARA with every mass leaf non-zero (counter-masses, vertical counterweight)."""
    return Scara(
        [0.125, 0.225],
        [0.0625, 0.1125, 0.01],
        [1.2, 2.0, 0.5],
        [0.014, 0.036, 0.0126],
        payload=0.3,
        counter_masses=[1.0, 0.5, 0.2],
        vertical_counterweight=0.5,
    )


def _random_states(dof, count, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(3, count, dof)) * np.array([3.0, 5.0, 50.0])[:, None, None]


def _quintic(start, end, duration):
    start, end = jnp.asarray(start), jnp.asarray(end)

    def pose(t):
        u = t / duration
        return start + (10 * u**3 - 15 * u**4 + 6 * u**5) * (end - start)

    return pose


def _ik_states(robot, start, end, duration=0.1, count=4):
    """Exact (q, q̇, q̈) along a short quintic move of the platform, by the robot's IK."""
    pose = _quintic(start, end, duration)
    times = jnp.linspace(0.1 * duration, 0.9 * duration, count)
    return jax.jit(lambda ts: jaxbal.sample(lambda t: robot.inverse_kinematics(pose(t)), ts, 2))(
        times
    )[:3]


SERIAL = {
    "2R": (planar_2r, None),
    "3R": (planar_3r, GRAVITY),
    "3R+counterweights": (_balanced_3r, GRAVITY),
    "SCARA": (_scara, GRAVITY),
}


@pytest.mark.parametrize("name", list(SERIAL))
def test_serial_base_reaction_matches_shaking_wrench(name):
    """MuJoCo C base reaction = jaxbal shaking wrench on random states, 1e-9 relative."""
    constructor, gravity = SERIAL[name]
    robot = constructor()
    q, qd, qdd = _random_states(robot.dof, 6)
    result = confirm(robot, q, qd, qdd, gravity=gravity)
    assert result.independent and result.relative < TOL, result
    forces, moments = mujoco_base_reaction(robot, q, qd, qdd, gravity=gravity)
    force, moment = mujoco_base_reaction(robot, q[0], qd[0], qdd[0], gravity=gravity)
    assert forces.shape == (6, 3) and force.shape == (3,) and moment.shape == (3,)
    np.testing.assert_allclose(force, forces[0], rtol=1e-14)  # batch = single sample
    np.testing.assert_allclose(moment, moments[0], rtol=1e-14)


def test_dual_v_base_reaction_closed_chain():
    """DUAL-V (connect-closed loops), balanced and unbalanced, along a quintic move."""
    robot = dual_v(payload=0.5)
    q, qd, qdd = _ik_states(robot, [-0.05, -0.1, -0.2], [0.08, 0.15, 0.3])
    for design in (robot, robot.without_counter_masses()):
        result = confirm(design, q, qd, qdd)
        assert result.independent and result.relative < TOL, result


def test_orthoglide_base_reaction_closed_chain():
    """Orthoglide (ball-jointed parallelograms closed by connect), gravity on."""
    robot = orthoglide(payload=1.0)
    q, qd, qdd = _ik_states(robot, [-0.05, -0.1, -0.02], [0.08, 0.05, 0.1])
    result = confirm(robot, q, qd, qdd, gravity=GRAVITY)
    assert result.independent and result.relative < TOL, result


def test_closed_chain_state_closes_the_loops():
    """The IK state satisfies MuJoCo's connect constraints (residual < 1e-12 m)."""
    for robot, pose in ((dual_v(), [0.03, -0.1, 0.2]), (orthoglide(), [0.02, -0.03, 0.05])):
        compiled = mujoco_model(robot)
        data = mujoco.MjData(compiled.model)
        data.qpos[:] = compiled.qpos(robot.inverse_kinematics(jnp.asarray(pose)))
        mujoco.mj_forward(compiled.model, data)
        assert data.nefc > 0 and np.max(np.abs(data.efc_pos)) < 1e-12


def test_kinematics_match_body_frames():
    """MuJoCo's body poses from the trees = jaxbal's body_frames (independent kinematics)."""
    cases = [
        (_balanced_3r(), jnp.array([0.3, -1.2, 2.0])),
        (_scara(), jnp.array([0.3, 1, 2, 0.05])),
    ]
    cases.append((dual_v(), dual_v().inverse_kinematics(jnp.array([0.03, -0.1, 0.2]))))
    cases.append((orthoglide(), orthoglide().inverse_kinematics(jnp.array([0.02, -0.03, 0.05]))))
    for robot, q in cases:
        compiled = mujoco_model(robot)
        data = mujoco.MjData(compiled.model)
        data.qpos[:] = compiled.qpos(q)
        mujoco.mj_kinematics(compiled.model, data)
        origins, rotations = robot.body_frames(q)
        for i, name in enumerate(robot.mass_properties().names):
            body = compiled.model.body(name).id
            np.testing.assert_allclose(data.xpos[body], origins[i], atol=1e-14)
            np.testing.assert_allclose(data.xmat[body].reshape(3, 3), rotations[i], atol=1e-14)


def test_actuator_efforts_match_jaxbal():
    """MuJoCo RNE efforts = jaxbal's: Lagrange torques of the 3R, and the DUAL-V's
    minimum-norm torques by virtual work (1e-9 relative)."""
    from jaxbal.robots.dual_v_dynamics import virtual_work_torques

    robot = _balanced_3r()
    q, qd, qdd = (a[0] for a in _random_states(3, 1, seed=1))
    torques = mujoco_inverse(robot, q, qd, qdd)[6:]
    reference = jax.jit(jaxbal.inverse_dynamics)(robot, q, qd, qdd)
    np.testing.assert_allclose(torques, reference, rtol=TOL)

    robot = dual_v(payload=0.3)
    u, ud, udd = (
        jnp.array([0.03, -0.1, 0.15]),
        jnp.array([1.0, -2, 3]),
        jnp.array([50.0, 100, -200]),
    )
    efforts = mujoco_actuator_efforts(robot, robot.inverse_kinematics, u, ud, udd)
    reference = jax.jit(virtual_work_torques)(robot, u, ud, udd)
    np.testing.assert_allclose(efforts, reference, rtol=TOL)


def test_prescribed_fallback_agrees():
    """The generic (less independent) prescribed tree agrees too, 1e-9 relative."""
    robot = _balanced_3r()
    q, qd, qdd = _random_states(robot.dof, 2, seed=2)
    tree = prescribed_tree(robot)
    result = confirm(robot, q, qd, qdd, gravity=GRAVITY, tree=tree)
    assert not result.independent and result.relative < TOL, result


def test_mjx_matches_and_gradient_wrt_counter_mass():
    """MJX (vmap over time and over designs) = jaxbal, and d(peak shaking force)/
    d(counter-masses) from jaxbal and through mjx.inverse agree (1e-9 relative)."""
    robot = planar_2r()
    robot = eqx.tree_at(lambda r: r.counter_distances, robot, jnp.array([0.1, 0.05]))
    q, qd, qdd = (jnp.asarray(a) for a in _random_states(2, 4, seed=3))
    compiled = mjx_model(robot)
    counter = jnp.array([3.0, 1.0])

    def with_counter(mass):
        return eqx.tree_at(lambda r: r.counter_masses, robot, mass)

    def peak_mjx(mass):
        force, moment = jax.vmap(mjx_base_reaction, in_axes=(None, None, 0, 0, 0))(
            compiled, with_counter(mass), q, qd, qdd
        )
        return jnp.max(jnp.linalg.norm(force, axis=-1)), (force, moment)

    @jax.jit
    def peak_jaxbal(mass):
        design = with_counter(mass)
        force, _ = jax.vmap(lambda a, b, c: jaxbal.shaking_wrench(design, a, b, c))(q, qd, qdd)
        return jnp.max(jnp.linalg.norm(force, axis=-1))

    @jax.jit
    def evaluate(mass, designs):
        (peak, aux), grad = jax.value_and_grad(peak_mjx, has_aux=True)(mass)
        return peak, aux, grad, jax.vmap(lambda m: peak_mjx(m)[0])(designs)  # vmap designs

    designs = jnp.array([[0.0, 0.0], [3.0, 1.0], [10.0, 2.0]])
    peak, (force, moment), grad_mjx, design_peaks = evaluate(counter, designs)
    for design, design_peak in zip(designs, design_peaks, strict=True):
        assert design_peak == pytest.approx(float(peak_jaxbal(design)), rel=TOL)
    reference = jax.jit(
        jax.vmap(lambda a, b, c: jaxbal.shaking_wrench(with_counter(counter), a, b, c))
    )(q, qd, qdd)
    np.testing.assert_allclose(force, reference[0], rtol=TOL, atol=TOL * 100)
    np.testing.assert_allclose(moment, reference[1], rtol=TOL, atol=TOL * 100)
    grad_jaxbal = jax.jit(jax.grad(peak_jaxbal))(counter)
    assert np.all(np.isfinite(grad_mjx)) and np.abs(grad_jaxbal).max() > 1.0
    np.testing.assert_allclose(grad_mjx, grad_jaxbal, rtol=TOL)
    assert peak == pytest.approx(float(peak_jaxbal(counter)), rel=TOL)


def test_dual_v_open_loop_simulation_tracks_the_plan():
    """jaxbal's DUAL-V torques (the paper's model, eqs 3-29), applied open-loop in
    MuJoCo, reproduce the planned platform motion: error < 3e-6 m / 1e-5 rad on a
    0.04 s quintic move (time step 1e-4 s; the error is discretisation, O(dt²)), while
    a 0.1 % torque error moves the platform 30x more."""
    from jaxbal.robots.dual_v_dynamics import paper_torques

    robot = dual_v()
    duration = 0.04
    pose = _quintic([-0.02, -0.05, -0.05], [0.02, 0.05, 0.05], duration)

    def efforts(t):
        u, ud, udd = jaxbal.time_derivatives(pose, t, 2)[:3]
        return paper_torques(robot, robot.inverse_kinematics(u), ud, udd)

    def path(t):
        return robot.inverse_kinematics(pose(t))

    tracked = ("x5", "y5", "theta5")
    result = simulate_open_loop(robot, path, efforts, duration, tracked=tracked)
    assert np.all(result.error < [1e-6, 3e-6, 1e-5]), result.error
    assert result.constraint_violation < 1e-7
    assert np.ptp(result.planned[:, 1]) > 0.09  # it moved 0.1 m along y
    wrong = simulate_open_loop(robot, path, efforts, duration, tracked, effort_scale=1.001)
    assert wrong.error.max() > 30 * result.error.max()


def test_mjcf_export_loads_with_masses_and_actuators():
    """The MJCF carries jaxbal's masses, no contacts, the gravity and one motor per joint."""
    robot = _balanced_3r()
    model = mujoco.MjModel.from_xml_string(to_mjcf(robot, gravity=GRAVITY))
    bodies = robot.mass_properties()
    for name, mass in zip(bodies.names, np.asarray(bodies.mass), strict=True):
        assert model.body(name).mass[0] == pytest.approx(mass, rel=1e-15)
    assert model.nu == 3 and model.nv == 6 + 3
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    np.testing.assert_array_equal(model.opt.gravity, GRAVITY)
    assert len(robot.mujoco_tree().bodies) == len(bodies.names)
    for name in ("planar_2r", "planar_3r", "scara", "dual_v", "orthoglide"):
        model = mujoco.MjModel.from_xml_string(export_mjcf(by_name(name)))
        assert model.nu > 0 and model.jnt_type.size > 0
    assert mujoco.MjModel.from_xml_string(export_mjcf(dual_v())).neq == 4


def test_bad_input_raises_and_massless_link_is_handled():
    """Wrong shapes / unknown names raise ValueError; a massless moving link compiles
    (MuJoCo's minimum mass, 1e-14 kg) and still agrees."""
    robot = planar_2r()
    with pytest.raises(ValueError, match="shape"):
        mujoco_base_reaction(robot, np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="shape"):
        mujoco_base_reaction(robot, np.zeros(2), np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="unknown robot"):
        by_name("hexapod")
    with pytest.raises(ValueError, match="engine"):
        confirm(robot, np.zeros(2), np.zeros(2), np.zeros(2), engine="bullet")
    massless = PlanarArm([0.5, 0.3], [0.3, 0.1], [0.0, 8.3], [0.0, 0.05], payload=1.0)
    q, qd, qdd = np.array([0.3, 0.5]), np.array([1.0, -2.0]), np.array([10.0, 20.0])
    force, _ = mujoco_base_reaction(massless, q, qd, qdd)
    np.testing.assert_allclose(force, jaxbal.shaking_wrench(massless, q, qd, qdd)[0], rtol=TOL)


MJX_CASES = {
    "3R": lambda: (planar_3r(), _random_states(3, 3, seed=5), GRAVITY),
    "SCARA": lambda: (_scara(), _random_states(4, 3, seed=6), GRAVITY),
    "DUAL-V": lambda: (
        dual_v(),
        _ik_states(dual_v(), [-0.05, -0.1, -0.2], [0.08, 0.15, 0.3], count=3),
        None,
    ),
    "Orthoglide": lambda: (
        orthoglide(payload=2.0),
        _ik_states(orthoglide(payload=2.0), [0.0, 0.0, 0.0], [-0.1, 0.07, -0.11], count=3),
        None,
    ),
}


@pytest.mark.parametrize("name", list(MJX_CASES))
def test_mjx_engine_confirms_every_robot(name):
    """MJX (``mjx.inverse``, jitted, vmapped over time) = jaxbal on a short trajectory of
    each robot, trees and closed chains: 1e-9 relative (issue: 1e-6 for closed chains)."""
    robot, (q, qd, qdd), gravity = MJX_CASES[name]()
    result = confirm(robot, q, qd, qdd, gravity=gravity, engine="mjx")
    assert result.engine == "mjx" and result.independent
    assert result.relative < TOL, result
