"""The shaking-wrench core and the planar arms of Briot et al. (2012).

References and tolerances are named in each test: hand-derived closed forms of the 2R
(1e-10 relative), Newton's law f = −m_tot ẍ_S, textbook 2R inverse dynamics (Spong),
finite differences (check_grads), vmap against a Python loop.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.planning import ComLine, com_line
from jaxbal.profiles import BangBang
from jaxbal.robots.planar_arm import force_balanced

RNG = np.random.default_rng(0)


def random_states(count, dof):
    q = RNG.uniform(-np.pi, np.pi, (count, dof))
    qd = RNG.normal(0.0, 3.0, (count, dof))
    qdd = RNG.normal(0.0, 30.0, (count, dof))
    return jnp.asarray(q), jnp.asarray(qd), jnp.asarray(qdd)


def closed_form_wrench_2r(arm, q, qd, qdd):
    """Hand-derived: f = −Σ m a, m_z = −Σ m (x a_y − y a_x) − Σ I θ̈ (about O)."""
    l1, l2 = (float(x) for x in arm.lengths)
    r1, r2 = (float(x) for x in arm.com_ratios)
    m1, m2 = (float(x) for x in arm.masses)
    i1, i2 = (float(x) for x in arm.inertias)
    mt = float(arm.payload)
    t1, t12 = q[0], q[0] + q[1]
    w1, w12 = qd[0], qd[0] + qd[1]
    a1, a12 = qdd[0], qdd[0] + qdd[1]

    def point(length, t):
        return length * np.array([np.cos(t), np.sin(t)])

    def accel(length, t, w, a):
        return length * (
            a * np.array([-np.sin(t), np.cos(t)]) - w**2 * np.array([np.cos(t), np.sin(t)])
        )

    bodies = [
        (m1, point(r1 * l1, t1), accel(r1 * l1, t1, w1, a1)),
        (
            m2,
            point(l1, t1) + point(r2 * l2, t12),
            accel(l1, t1, w1, a1) + accel(r2 * l2, t12, w12, a12),
        ),
        (mt, point(l1, t1) + point(l2, t12), accel(l1, t1, w1, a1) + accel(l2, t12, w12, a12)),
    ]
    force = -sum(m * a for m, _, a in bodies)
    moment = -sum(m * (p[0] * a[1] - p[1] * a[0]) for m, p, a in bodies) - i1 * a1 - i2 * a12
    return np.array([force[0], force[1], 0.0]), np.array([0.0, 0.0, moment])


def spong_inverse_dynamics_2r(arm, q, qd, qdd):
    """Textbook 2R dynamics (Spong, Hutchinson & Vidyasagar, §7.3) with a tip point mass."""
    l1, l2 = (float(x) for x in arm.lengths)
    lc1, lc2 = l1 * float(arm.com_ratios[0]), l2 * float(arm.com_ratios[1])
    m1, m2 = (float(x) for x in arm.masses)
    i1, i2 = (float(x) for x in arm.inertias)
    mt = float(arm.payload)
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    m11 = i1 + i2 + m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * c2)
    m11 += mt * (l1**2 + l2**2 + 2 * l1 * l2 * c2)
    m12 = i2 + m2 * (lc2**2 + l1 * lc2 * c2) + mt * (l2**2 + l1 * l2 * c2)
    m22 = i2 + m2 * lc2**2 + mt * l2**2
    h = (m2 * l1 * lc2 + mt * l1 * l2) * s2
    tau1 = m11 * qdd[0] + m12 * qdd[1] - h * (2 * qd[0] * qd[1] + qd[1] ** 2)
    tau2 = m12 * qdd[0] + m22 * qdd[1] + h * qd[0] ** 2
    return np.array([tau1, tau2])


@pytest.fixture(scope="module")
def arm():
    return jaxbal.robots.planar_2r()


def test_shaking_wrench_matches_closed_form(arm):
    qs, qds, qdds = random_states(50, 2)
    force, moment = jax.jit(jax.vmap(lambda *s: jaxbal.shaking_wrench(arm, *s)))(qs, qds, qdds)
    for k in range(50):
        f_ref, m_ref = closed_form_wrench_2r(arm, *(np.asarray(x[k]) for x in (qs, qds, qdds)))
        np.testing.assert_allclose(force[k], f_ref, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(moment[k], m_ref, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("maker", [jaxbal.robots.planar_2r, jaxbal.robots.planar_3r])
def test_force_is_minus_mass_times_com_acceleration(maker):
    """Briot eq (1): f_sh = −m_tot ẍ_S, ẍ_S differentiated independently along q(t)."""
    arm = maker()
    qs, qds, qdds = random_states(10, arm.dof)
    for q, qd, qdd in zip(qs, qds, qdds, strict=True):
        force, _ = jaxbal.shaking_wrench(arm, q, qd, qdd)

        def com(t, q=q, qd=qd, qdd=qdd):
            return jaxbal.center_of_mass(arm, q + qd * t + 0.5 * qdd * t**2)

        com_acc = jaxbal.time_derivatives(com, 0.0)[2]
        np.testing.assert_allclose(force, -jaxbal.total_mass(arm) * com_acc, rtol=1e-11, atol=1e-9)


def test_gravity_adds_weight_and_its_moment(arm):
    q, qd, qdd = (x[0] for x in random_states(1, 2))
    g = jnp.array([0.0, 0.0, -9.81])
    f0, m0 = jaxbal.shaking_wrench(arm, q, qd, qdd)
    f1, m1 = jaxbal.shaking_wrench(arm, q, qd, qdd, gravity=g)
    mass = jaxbal.total_mass(arm)
    np.testing.assert_allclose(f1 - f0, mass * g, rtol=1e-12)
    com = jaxbal.center_of_mass(arm, q)
    np.testing.assert_allclose(m1 - m0, jnp.cross(mass * com, g), rtol=1e-12, atol=1e-12)


def test_inverse_dynamics_matches_textbook(arm):
    qs, qds, qdds = random_states(20, 2)
    tau = jax.jit(jax.vmap(lambda *s: jaxbal.inverse_dynamics(arm, *s)))(qs, qds, qdds)
    for k in range(20):
        ref = spong_inverse_dynamics_2r(arm, *(np.asarray(x[k]) for x in (qs, qds, qdds)))
        np.testing.assert_allclose(tau[k], ref, rtol=1e-10, atol=1e-10)


def test_base_moment_equals_minus_first_joint_torque(arm):
    """Horizontal serial arm: the base reaction moment about O is −τ1 (action-reaction)."""
    q, qd, qdd = (x[3] for x in random_states(4, 2))
    _, moment = jaxbal.shaking_wrench(arm, q, qd, qdd)
    tau = jaxbal.inverse_dynamics(arm, q, qd, qdd)
    np.testing.assert_allclose(moment[2], -tau[0], rtol=1e-11)


def test_torque_rate_matches_finite_difference_in_time(arm):
    """dτ/dt along q(t) = q + q̇t + q̈t²/2 + q⃛t³/6 vs a central difference (h = 1e-5 s)."""
    q, qd, qdd = (x[1] for x in random_states(2, 2))
    qddd = jnp.array([40.0, -70.0])

    def tau_at(t):
        qt = q + qd * t + qdd * t**2 / 2 + qddd * t**3 / 6
        qdt = qd + qdd * t + qddd * t**2 / 2
        qddt = qdd + qddd * t
        return jaxbal.inverse_dynamics(arm, qt, qdt, qddt)

    h = 1e-5
    numeric = (tau_at(h) - tau_at(-h)) / (2 * h)
    exact = jaxbal.inverse_dynamics_rate(arm, q, qd, qdd, qddd)
    np.testing.assert_allclose(exact, numeric, rtol=1e-6)


def test_vmap_equals_loop():
    arm = jaxbal.robots.planar_3r()
    qs, qds, qdds = random_states(8, 3)
    batched = jax.jit(jax.vmap(lambda *s: jaxbal.shaking_wrench(arm, *s)))(qs, qds, qdds)
    one = jax.jit(lambda *s: jaxbal.shaking_wrench(arm, *s))
    for k in range(8):
        single = one(qs[k], qds[k], qdds[k])
        # Compiled straight-line code may contract a*b + c into one FMA: equal to rounding.
        np.testing.assert_allclose(batched[0][k], single[0], rtol=1e-14, atol=1e-12)
        np.testing.assert_allclose(batched[1][k], single[1], rtol=1e-14, atol=1e-12)


def test_vmap_over_robot_parameters_compiles_once():
    """A payload sweep: the robot is a pytree, vmap over its leaf, one compilation."""
    arm = jaxbal.robots.planar_2r()
    q, qd, qdd = (x[0] for x in random_states(1, 2))
    payloads = jnp.linspace(0.0, 5.0, 6)

    def peak(payload):
        robot = jaxbal.robots.PlanarArm(
            arm.lengths, arm.com_ratios, arm.masses, arm.inertias, payload
        )
        return jnp.linalg.norm(jaxbal.shaking_wrench(robot, q, qd, qdd)[0])

    swept = jax.jit(jax.vmap(peak))(payloads)
    looped = [float(peak(p)) for p in payloads]
    np.testing.assert_allclose(swept, looped, rtol=1e-13)
    assert float(swept[-1]) > float(swept[0])


def _arm_from(params):
    lengths, masses, payload = params
    return jaxbal.robots.PlanarArm(lengths, [0.289, 0.098], masses, [1.246, 0.057], payload)


def test_gradients_wrt_masses_lengths_payload():
    q, qd, qdd = (x[2] for x in random_states(3, 2))
    params = (jnp.array([0.5, 0.3]), jnp.array([24.4, 8.3]), jnp.asarray(5.0))

    def wrench_norms(params):
        force, moment = jaxbal.shaking_wrench(_arm_from(params), q, qd, qdd)
        return jnp.sum(force**2) + moment[2] ** 2

    check_grads(wrench_norms, (params,), order=1, modes=["fwd", "rev"], rtol=1e-6)
    grads = jax.grad(wrench_norms)(params)
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in jax.tree_util.tree_leaves(grads))


def test_com_ik_round_trip_and_modes(arm):
    """eqs (8)-(12): both working modes reach the same COM; '+' gives q2 < 0 here."""
    q = jnp.array([1.2, -0.8])
    com = jaxbal.center_of_mass(arm, q)[:2]
    for branch in (1, -1):
        q_branch = arm.com_inverse_kinematics(com, branch=branch)
        np.testing.assert_allclose(jaxbal.center_of_mass(arm, q_branch)[:2], com, atol=1e-13)
    np.testing.assert_allclose(arm.com_inverse_kinematics(com, branch=1), q, atol=1e-12)


def test_com_ik_eq10_literal(arm):
    """Our stable evaluation equals eq (10) as printed, t = (−b + √Δ)/(c − a)."""
    com = jnp.array([0.1, 0.25])
    l_eq = arm.equivalent_lengths()
    a, b = -2 * l_eq[0] * com[0], -2 * l_eq[0] * com[1]
    c = jnp.sum(com**2) + l_eq[0] ** 2 - l_eq[1] ** 2
    q1 = 2 * jnp.arctan((-b + jnp.sqrt(b**2 - c**2 + a**2)) / (c - a))
    np.testing.assert_allclose(arm.com_inverse_kinematics(com, branch=1)[0], q1, rtol=1e-12)


def test_3r_com_ik_round_trip():
    arm = jaxbal.robots.planar_3r()
    q = jnp.array([0.9, -1.1, 0.7])
    com = jaxbal.center_of_mass(arm, q)[:2]
    phi = jnp.sum(q)
    np.testing.assert_allclose(arm.com_inverse_kinematics(com, phi, branch=1), q, atol=1e-12)
    with pytest.raises(ValueError, match="free angle"):
        arm.com_inverse_kinematics(com)


def test_unreachable_com_raises_naming_target(arm):
    with pytest.raises(ValueError, match=r"COM target not reachable.*2\.5"):
        arm.com_inverse_kinematics(jnp.array([2.5, 0.0]))
    _, valid = jax.jit(lambda x: arm.com_inverse_kinematics(x, return_valid=True))(
        jnp.array([2.5, 0.0])
    )
    assert not bool(valid)
    _, valid = arm.com_inverse_kinematics(jnp.array([2.5, 0.0]), return_valid=True)
    assert not bool(valid)  # eager, with a mask asked for: no exception


def test_unreachable_pose_and_bad_inputs(arm):
    with pytest.raises(ValueError, match="outside the workspace"):
        arm.inverse_kinematics(jnp.array([0.0, 0.95]))
    with pytest.raises(ValueError, match="shape"):
        arm.inverse_kinematics(jnp.array([0.1, 0.2, 0.3]))
    with pytest.raises(ValueError, match="non-negative"):
        jaxbal.robots.PlanarArm([0.5, 0.3], [0.3, 0.1], [-1.0, 8.3], [1.0, 0.1], 5.0)
    with pytest.raises(ValueError, match="shape"):
        jaxbal.shaking_wrench(arm, jnp.zeros(3), jnp.zeros(3), jnp.zeros(3))


def test_end_effector_ik_round_trip():
    arm = jaxbal.robots.planar_3r()
    q = jnp.array([0.4, -1.3, 0.5])
    pose = arm.end_effector(q)
    np.testing.assert_allclose(arm.inverse_kinematics(pose, branch=-1), q, atol=1e-12)


@pytest.mark.parametrize("phi", [2.0, -3.0, 3.3, 7.5, -20.0, 500.0])
def test_3r_orientation_round_trips_with_its_turns(phi):
    """``end_effector(inverse_kinematics(pose))`` gave φ − 2π for φ = 2.0 (the last
    joint wrapped to (−π, π]): a COM plan's default φ law between two such poses then
    turned link 3 through 6.78 rad for a 0.5 rad reorientation (peak moment 55.6 for
    43.1 N·m). The joint angles now sum to φ itself, for the COM inverse kinematics
    too, and the tip stays exact."""
    arm = jaxbal.robots.planar_3r()
    pose = jnp.array([0.225, 0.25, phi])
    for branch in (1, -1):
        q = arm.inverse_kinematics(pose, branch=branch)
        np.testing.assert_allclose(arm.end_effector(q), pose, rtol=1e-15, atol=1e-13)
        com = jaxbal.center_of_mass(arm, q)[:2]
        q_com = arm.com_inverse_kinematics(com, phi, branch=branch)
        assert float(jnp.sum(q_com)) == pytest.approx(phi, rel=1e-15, abs=1e-13)
    check_grads(lambda p: arm.inverse_kinematics(p, branch=-1), (pose,), order=1)


def test_3r_default_phi_law_takes_the_asked_reorientation():
    """The 0.5 rad reorientation of the helper's case, planned by ``com_line``."""
    arm = jaxbal.robots.planar_3r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25, 2.0]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70, 2.5]), branch=-1)
    plan = com_line(arm, q0, q1, BangBang(), 0.5)
    phi = np.unwrap([float(jnp.sum(plan(t))) for t in np.linspace(0.0, 0.5, 41)])
    assert phi[-1] - phi[0] == pytest.approx(0.5, abs=1e-12)
    assert np.all(np.diff(phi) >= -1e-12)


def test_end_effector_pose_shapes():
    """The 2R's end effector is the tip (x, y); the 3R's is (x, y, φ) with φ = Σq
    (closed form: the tip of the unit-angle chain, 1e-15 m)."""
    arm2, arm3 = jaxbal.robots.planar_2r(), jaxbal.robots.planar_3r()
    q2, q3 = jnp.array([0.4, -1.3]), jnp.array([0.4, -1.3, 0.5])
    l1, l2 = 0.5, 0.3
    tip = [l1 * np.cos(0.4) + l2 * np.cos(-0.9), l1 * np.sin(0.4) + l2 * np.sin(-0.9)]
    np.testing.assert_allclose(arm2.end_effector(q2), tip, atol=1e-15)
    assert arm3.end_effector(q3).shape == (3,)
    np.testing.assert_allclose(arm3.end_effector(q3)[2], -0.4, atol=1e-15)


@pytest.mark.parametrize("maker", [jaxbal.robots.planar_2r, jaxbal.robots.planar_3r])
@pytest.mark.parametrize("bad", [2, 0, -3, (1, 1), (), (0,), "up"])
def test_invalid_branch_raises(maker, bad):
    """A sign other than ±1 or a tuple not of one sign is a structure error
    (ValueError) for the IK, the COM IK, EndEffectorLine and with return_valid=True."""
    arm = maker()
    q = jnp.array([0.4, -1.3, 0.5])[: arm.dof]
    pose = arm.end_effector(q)
    com = jaxbal.center_of_mass(arm, q)[:2]
    free = None if arm.dof == 2 else pose[2]
    with pytest.raises(ValueError, match="branch"):
        arm.inverse_kinematics(pose, branch=bad)
    with pytest.raises(ValueError, match="branch"):
        arm.inverse_kinematics(pose, branch=bad, return_valid=True)
    with pytest.raises(ValueError, match="branch"):
        arm.com_inverse_kinematics(com, free, branch=bad)
    line = jaxbal.StraightLine(pose, pose, jaxbal.profiles.Quintic(), 0.5)
    with pytest.raises(ValueError, match="branch"):
        jaxbal.planning.EndEffectorLine(arm, line, branch=bad)(0.1)


def test_branch_tuple_equals_int():
    """branch=(−1,) is branch=−1 (exact), and the elbow sign is sin q2's (Briot §3.1)."""
    arm = jaxbal.robots.planar_2r()
    pose = jnp.array([0.3, 0.5])
    for sign in (1, -1):
        q = arm.inverse_kinematics(pose, branch=sign)
        np.testing.assert_array_equal(q, arm.inverse_kinematics(pose, branch=(sign,)))
        assert np.sign(np.sin(q[1])) == sign


def test_bang_bang_com_plan_gives_constant_force(arm):
    """Bang-bang on the COM: ‖f_sh‖ = m_tot·4·|Δx_S|/T² at every instant (eqs 1, 3-4)."""
    q0, q1 = jnp.array([1.0, -1.0]), jnp.array([1.6, -0.6])
    plan = com_line(arm, q0, q1, BangBang(), 0.5)
    assert isinstance(plan, ComLine)
    times = jnp.linspace(0.0, 0.5, 101)
    force, _ = jaxbal.planning.wrench_along(arm, plan, times)
    expected = jaxbal.total_mass(arm) * 4 * jnp.linalg.norm(plan.line.end - plan.line.start) / 0.25
    np.testing.assert_allclose(jnp.linalg.norm(force, axis=-1), expected, rtol=1e-9)
    assert bool(jnp.all(plan.valid(times)))


def test_grad_of_peak_force_wrt_payload_through_planner():
    """d max‖f‖/d m_tool through the COM plan and the IK: finite, and equal to FD (1e-5)."""
    base = jaxbal.robots.planar_2r()
    q0, q1 = jnp.array([1.0, -1.0]), jnp.array([1.6, -0.6])
    times = jnp.linspace(0.0, 0.5, 41)

    @jax.jit  # one program for the values, one for the gradient (eagerly: op by op)
    def peak(payload):
        arm = jaxbal.robots.PlanarArm(
            base.lengths, base.com_ratios, base.masses, base.inertias, payload
        )
        line = jaxbal.StraightLine(
            arm.end_effector(q0), arm.end_effector(q1), jaxbal.profiles.Quintic(), 0.5
        )
        path = jaxbal.planning.EndEffectorLine(arm, line, branch=-1)
        return jaxbal.planning.peak_norm(jaxbal.planning.wrench_along(arm, path, times)[0])

    grad = jax.grad(peak)(5.0)
    assert np.isfinite(grad)
    numeric = (peak(5.0 + 1e-4) - peak(5.0 - 1e-4)) / 2e-4
    np.testing.assert_allclose(grad, numeric, rtol=1e-5)


def test_compiles_once_per_structure():
    """New parameter values reuse the compiled wrench; a new structure (3R) recompiles."""
    traces = []  # one trace per compilation (jit's executable cache size depends on
    # effects and on what other tests of the process compiled)

    def counted(*args):
        traces.append(type(args[0]).__name__)
        return jaxbal.shaking_wrench(*args)

    wrench = jax.jit(counted)
    q, qd, qdd = (x[0] for x in random_states(1, 2))
    for payload in (0.0, 2.0, 5.0):
        arm = jaxbal.robots.planar_2r(payload=payload)
        wrench(arm, q, qd, qdd)
    heavier = jaxbal.robots.PlanarArm([0.6, 0.4], [0.3, 0.1], [30.0, 9.0], [1.5, 0.1], 1.0)
    wrench(heavier, q, qd, qdd)
    assert traces == ["PlanarArm"]
    q3 = jnp.zeros(3)
    wrench(jaxbal.robots.planar_3r(), q3, q3, q3)
    assert traces == ["PlanarArm", "PlanarArm"]


def test_force_balanced_arm_has_zero_shaking_force():
    """Counterweights from the closed form keep the COM at O: f_sh = 0 (1e-12 N) for any
    motion, while the moment does not vanish (Briot et al. 2012, §3.3)."""
    arm = force_balanced(jaxbal.robots.planar_2r(), [0.35, 0.2])
    np.testing.assert_allclose(arm.equivalent_lengths(), 0.0, atol=1e-15)
    qs, qds, qdds = random_states(10, 2)
    force, moment = jax.jit(jax.vmap(lambda *s: jaxbal.shaking_wrench(arm, *s)))(qs, qds, qdds)
    np.testing.assert_allclose(force, 0.0, atol=1e-11)
    assert float(jnp.max(jnp.abs(moment))) > 1.0
    distances = jnp.array([0.35, 0.2])
    grad = jax.grad(lambda d: jnp.sum(force_balanced(arm, d).counter_masses))(distances)
    assert bool(jnp.all(jnp.isfinite(grad))) and bool(jnp.all(grad < 0))
    # reference: central finite differences of the closed form (check_grads)
    check_grads(lambda d: force_balanced(arm, d).counter_masses, (distances,), order=1)
    with pytest.raises(ValueError, match="positive"):
        force_balanced(arm, [0.35, -0.2])
