"""Tests of the DUAL-V (van der Wijk et al. 2013): kinematics, balance, dynamics."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.robots import CROSSED, OUTWARD, dual_v
from jaxbal.robots.dual_v_dynamics import (
    base_wrench_from_bearings,
    bearing_forces,
    paper_torques,
    torque_split,
    virtual_work_torques,
)

POSES = jnp.array([[0.0, 0.0, 0.0], [0.05, 0.02, 0.0], [0.03, -0.04, 0.1], [-0.06, 0.08, -0.15]])
MOTION = (
    jnp.array([0.03, -0.05, 0.1]),
    jnp.array([0.8, -0.5, 2.0]),
    jnp.array([30.0, -50.0, 300.0]),
)


@pytest.mark.parametrize("branch", [OUTWARD, CROSSED])
def test_ik_round_trip_and_loop_closure(branch):
    """IK → joint positions closes every loop (reference: 0, tol 1e-12 m) and the
    elbow signs are the requested branch."""
    robot = dual_v()
    for pose in POSES:
        q = robot.inverse_kinematics(pose, branch=branch)
        np.testing.assert_allclose(robot.constraint(q), 0.0, atol=1e-12)
        np.testing.assert_allclose(q[8:], pose, atol=0)
        np.testing.assert_array_equal(np.sign(np.sin(q[4:8] - q[0:4])), branch)


def test_parallelograms_and_workspace_widths():
    """Non-rotated platform: θ41 = θ12, θ42 = θ11, θ31 = θ22, θ32 = θ21 (layout derived
    from eq 2); workspace widths 0.328 m along x and 0.792 m along y (paper §3)."""
    robot = dual_v()
    q = robot.inverse_kinematics(jnp.array([0.07, -0.12, 0.0]))
    wrap = lambda x: np.angle(np.exp(1j * np.asarray(x)))  # noqa: E731
    np.testing.assert_allclose(wrap(q[3] - q[4]), 0.0, atol=1e-12)
    np.testing.assert_allclose(wrap(q[7] - q[0]), 0.0, atol=1e-12)
    np.testing.assert_allclose(wrap(q[2] - q[5]), 0.0, atol=1e-12)
    np.testing.assert_allclose(wrap(q[6] - q[1]), 0.0, atol=1e-12)
    # The workspace edges found by bisection on the IK validity mask, against §3's widths.
    assert abs(2 * _reach(robot, np.array([1.0, 0.0, 0.0])) - 0.328) < 1e-6
    assert abs(2 * _reach(robot, np.array([0.0, 1.0, 0.0])) - 0.792) < 1e-3  # printed 0.792


def _reach(robot, direction, steps=40):
    """Largest s with the pose s·direction reachable (IK validity mask), by bisection."""
    inside, outside = 0.0, 1.0
    for _ in range(steps):
        middle = 0.5 * (inside + outside)
        _, ok = robot.inverse_kinematics(jnp.asarray(middle * direction), return_valid=True)
        inside, outside = (middle, outside) if bool(ok) else (inside, middle)
    return inside


def test_out_of_workspace_raises():
    with pytest.raises(ValueError, match="outside the workspace"):
        dual_v().inverse_kinematics(jnp.array([0.3, 0.0, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        dual_v().inverse_kinematics(jnp.array([0.0, 0.0]))


@pytest.mark.parametrize("bad", [2, 0, (1, -1, 1), (1, -1, 1, -1, 1), (1, 2, 1, -1)])
def test_invalid_branch_raises(bad):
    """A sign other than ±1 or a tuple not of four signs raises ValueError (structure
    error, at trace time), also through pose_motion and return_valid=True."""
    robot = dual_v()
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(POSES[1], branch=bad)
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(POSES[1], branch=bad, return_valid=True)
    with pytest.raises(ValueError, match="branch"):
        jaxbal.pose_motion(robot, *MOTION, branch=bad)


def test_int_branch_means_all_signs():
    """branch=-1 is (-1, -1, -1, -1): the same q as the explicit tuple (exact)."""
    robot = dual_v()
    np.testing.assert_array_equal(
        robot.inverse_kinematics(POSES[1], branch=-1),
        robot.inverse_kinematics(POSES[1], branch=(-1, -1, -1, -1)),
    )


def test_negative_mass_raises():
    robot = dual_v()
    with pytest.raises(ValueError, match="non-negative"):
        type(robot)(**{**robot.__dict__, "m5": jnp.asarray(-1.0)})


def test_jacobian_eq9_matches_autodiff():
    """Eq (9) vs autodiff of the IK (tol 1e-12)."""
    robot = dual_v()
    for pose in POSES:
        for branch in (OUTWARD, CROSSED):
            q = robot.inverse_kinematics(pose, branch=branch)
            auto = jax.jacfwd(lambda u, b=branch: robot.inverse_kinematics(u, branch=b))(pose)[:4]
            np.testing.assert_allclose(robot.jacobian(q), auto, atol=1e-12)


def test_condition_number_at_centre():
    """The harmonised Jacobian is well conditioned at the centre (Fig 8: κ close to 1)."""
    robot = dual_v()
    kappa = robot.harmonised_condition_number(robot.inverse_kinematics(jnp.zeros(3)))
    assert 1.0 <= float(kappa) < 1.2


@eqx.filter_jit
def _wrench(robot, pose, velocity, acceleration, branch=OUTWARD):
    q, qd, qdd = jaxbal.pose_motion(robot, pose, velocity, acceleration, branch=branch)
    return jaxbal.shaking_wrench(robot, q, qd, qdd)


@pytest.mark.parametrize("branch", [OUTWARD, CROSSED])
def test_balanced_robot_zero_shaking_force(branch):
    """Counter-masses exactly at eq (2): zero shaking force for any non-rotated
    translation (reference 0, tol 1e-10 N at ~100 m/s²)."""
    from jaxbal.robots.dual_v_balancing import balance_condition_eq2, with_counter_mass_moments

    robot = with_counter_mass_moments(dual_v(), balance_condition_eq2(dual_v()))
    for pose in POSES[:2]:
        force, _ = _wrench(
            robot, pose, jnp.array([0.7, -1.1, 0.0]), jnp.array([80.0, 60.0, 0]), branch
        )
        np.testing.assert_allclose(force, 0.0, atol=1e-10)


def test_unbalanced_force_is_reduced_mass_times_acceleration():
    """Without counter-masses: f = -m_red·a5, m_red = 2 μ*/l (eq 2 μ*; paper 3.279 kg)."""
    from jaxbal.robots.dual_v_balancing import balance_condition_eq2

    robot = dual_v(counter_masses=False)
    m_red = 2.0 * balance_condition_eq2(robot)[0] / robot.l1[0]
    acc = jnp.array([60.0, -45.0, 0.0])
    force, _ = _wrench(robot, POSES[1], jnp.array([0.3, 0.2, 0.0]), acc)
    np.testing.assert_allclose(force[:2], -m_red * acc[:2], rtol=1e-12)
    assert abs(float(m_red) - 3.279) / 3.279 < 0.01


def test_table1_residual_explained_by_rounding():
    """Table 1 counter-masses: |f| ≤ (rounding of m_cm, p_cm) · 2/l · |a|."""
    robot = dual_v()
    acc = jnp.array([82.6, 0.0, 0.0])
    force, _ = _wrench(robot, jnp.zeros(3), jnp.zeros(3), acc)
    rounding = 0.0005 * 0.0575 + 7.983 * 0.00005  # half a unit in the last digit
    assert float(jnp.linalg.norm(force)) <= 2 * rounding / 0.28 * 82.6


def test_vmap_equals_loop():
    robot = dual_v()
    batched = jax.jit(jax.vmap(lambda p: robot.inverse_kinematics(p)))(POSES)
    one = jax.jit(lambda p: robot.inverse_kinematics(p))
    looped = jnp.stack([one(p) for p in POSES])
    np.testing.assert_allclose(batched, looped, atol=1e-15)
    qs, valid = jax.jit(jax.vmap(lambda p: robot.inverse_kinematics(p, return_valid=True)))(
        POSES.at[0, 0].set(0.5)
    )
    assert not bool(valid[0]) and bool(jnp.all(valid[1:]))


@pytest.mark.slow
def test_ik_gradients_finite_and_correct():
    """IK: check_grads (finite differences). Wrench: its gradient with respect to the
    payload and a counter-mass equals central finite differences (1e-6 relative)."""
    robot = dual_v()
    check_grads(lambda u: robot.inverse_kinematics(u), (POSES[2],), order=1, modes=["fwd", "rev"])
    grad = jax.grad(lambda r: _wrench(r, *MOTION)[0][0])(robot)
    assert all(bool(jnp.all(jnp.isfinite(leaf))) for leaf in jax.tree_util.tree_leaves(grad))
    design = robot.design()

    def force_x(name, value):
        return float(_wrench(robot.with_design({name: value}), *MOTION)[0][0])

    step = 1e-4
    numeric = (force_x("payload", 0.1 + step) - force_x("payload", 0.1 - step)) / (2 * step)
    exact = jax.grad(lambda p: _wrench(robot.with_design({"payload": p}), *MOTION)[0][0])(0.1)
    np.testing.assert_allclose(exact, numeric, rtol=1e-6)
    masses = design["counter_mass"]
    bump = jnp.zeros_like(masses).at[0].set(step)
    numeric = (force_x("counter_mass", masses + bump) - force_x("counter_mass", masses - bump)) / (
        2 * step
    )
    exact = jax.grad(lambda m: _wrench(robot.with_design({"counter_mass": m}), *MOTION)[0][0])(
        masses
    )[0]
    np.testing.assert_allclose(exact, numeric, rtol=1e-6)


@eqx.filter_jit
def _three_torques(robot):
    q, _, _ = jaxbal.pose_motion(robot, *MOTION)
    tau_paper = paper_torques(robot, q, MOTION[1], MOTION[2])
    tau_vw = virtual_work_torques(robot, *MOTION)
    same_split = virtual_work_torques(robot, *MOTION, distribution="paper")
    return q, tau_paper, tau_vw, same_split


@pytest.mark.parametrize("balanced", [pytest.param(True, marks=pytest.mark.slow), False])
def test_paper_torques_match_virtual_work(balanced):
    """Eqs (3)-(29) vs Lagrange over all bodies (autodiff): same platform effect
    Jᵀτ, the minimum-norm part equals the virtual-work torques, and Lagrange on the
    split model (same distribution as the paper) equals τ itself (tol 1e-9 N·m)."""
    robot = dual_v(counter_masses=balanced)
    q, tau_paper, tau_vw, same_split = _three_torques(robot)
    jac = robot.jacobian(q)
    np.testing.assert_allclose(jac.T @ tau_paper, jac.T @ tau_vw, atol=1e-9)
    ranged, preload = torque_split(robot, q, tau_paper)
    np.testing.assert_allclose(ranged, tau_vw, atol=1e-9)
    np.testing.assert_allclose(tau_paper, same_split, atol=1e-9)
    assert float(jnp.max(jnp.abs(preload))) > 1e-3  # the paper's τ is not minimum-norm
    with pytest.raises(ValueError, match="distribution"):
        virtual_work_torques(robot, *MOTION, distribution="other")


def test_forward_dynamics_inverts_paper_model():
    """Fig 6 analogue: forward dynamics (KKT over all bodies) driven by the eqs (3)-(29)
    torques gives back the prescribed accelerations (118 / 202 m/s², 1612 rad/s² as in
    §4.2; tol 1e-9 relative), and its constraint forces give the same bearing loads."""
    from jaxbal.robots.dual_v_dynamics import forward_accelerations

    robot = dual_v()
    motion = (MOTION[0], MOTION[1], jnp.array([118.0, -202.0, 1612.0]))

    @eqx.filter_jit
    def round_trip(robot):
        q, qd, qdd = jaxbal.pose_motion(robot, *motion)
        tau = paper_torques(robot, q, motion[1], motion[2])
        return qdd, forward_accelerations(robot, q, qd, tau)[0]

    qdd, recovered = round_trip(robot)
    np.testing.assert_allclose(recovered, qdd, atol=1e-9 * float(jnp.max(jnp.abs(qdd))))


@pytest.mark.slow
def test_bearing_forces_sum_to_shaking_wrench():
    """Σ(-F_A,i) = shaking force and Σ A_i×(-F_A,i) - Στ = shaking moment (tol 1e-9)."""
    robot = dual_v()
    q, qd, qdd = jaxbal.pose_motion(robot, *MOTION)
    tau = paper_torques(robot, q, MOTION[1], MOTION[2])
    force, moment = base_wrench_from_bearings(robot, bearing_forces(robot, *MOTION, tau), tau)
    f_ref, m_ref = jaxbal.shaking_wrench(robot, q, qd, qdd)
    np.testing.assert_allclose(force, f_ref[:2], atol=1e-9)
    np.testing.assert_allclose(moment, m_ref[2], atol=1e-9)


def test_balance_conditions_eq1_eq2():
    """Eqs (1) and (2) agree for Table 1 (tol 1e-15) and give m_cm·p_cm ≈ 7.983·0.0575
    (Table 1 rounding, 0.1 %). With unequal links i2 they differ only along the
    balance line (-1, 1, 1, -1), and both designs give zero shaking force (1e-10 N)."""
    from jaxbal.robots.dual_v_balancing import (
        BALANCE_NULL_DIRECTION,
        balance_condition_eq1,
        balance_condition_eq2,
        with_counter_mass_moments,
    )

    robot = dual_v()
    np.testing.assert_allclose(
        balance_condition_eq1(robot), balance_condition_eq2(robot), rtol=1e-15
    )
    np.testing.assert_allclose(balance_condition_eq2(robot), 7.983 * 0.0575, rtol=1e-3)
    odd = eqx_set(
        robot, m2=jnp.array([0.5, 0.6, 0.7, 0.65]), p2=jnp.array([0.12, 0.13, 0.11, 0.14])
    )
    difference = balance_condition_eq1(odd) - balance_condition_eq2(odd)
    along = difference @ BALANCE_NULL_DIRECTION / (BALANCE_NULL_DIRECTION @ BALANCE_NULL_DIRECTION)
    np.testing.assert_allclose(difference, along * BALANCE_NULL_DIRECTION, atol=1e-15)
    assert abs(float(along)) > 1e-3
    for condition in (balance_condition_eq1, balance_condition_eq2):
        design = with_counter_mass_moments(odd, condition(odd))
        force, _ = _wrench(
            design, POSES[1], jnp.array([0.4, 0.9, 0.0]), jnp.array([-70.0, 90.0, 0])
        )
        np.testing.assert_allclose(force, 0.0, atol=1e-10)


def eqx_set(robot, **fields):
    names = tuple(fields)
    return eqx.tree_at(lambda r: tuple(getattr(r, n) for n in names), robot, tuple(fields.values()))


def _triangle(samples):
    vertices = np.array([[0.0, -0.1, 0.0], [0.0866025, 0.05, 0.0], [-0.0866025, 0.05, 0.0]])
    pieces = [
        jaxbal.sample(
            jaxbal.StraightLine(
                vertices[k], vertices[(k + 1) % 3], jaxbal.profiles.Quintic(), 0.11
            ),
            jaxbal.sample_times(0.11, samples),
        )
        for k in range(3)
    ]
    return tuple(jnp.concatenate([p[i] for p in pieces]) for i in range(3))


@pytest.mark.slow
def test_codesign_recovers_eq1():
    """L-BFGS co-design with zero inertia penalty recovers eq (1) to 1e-6 (symmetric
    start); with a penalty p_cm → radius of gyration sqrt(I_cm/m_cm) (closed form)."""
    from jaxbal import minimize
    from jaxbal.robots.dual_v_balancing import (
        balance_condition_eq1,
        codesign_loss,
        counter_mass_design,
    )

    robot = dual_v()
    motion = jax.vmap(lambda a, b, c: jaxbal.pose_motion(robot, a, b, c))(*_triangle(5))
    start = (jnp.log(jnp.full(4, 4.0)), jnp.log(jnp.full(4, 0.05)))
    solution = minimize(
        codesign_loss, start, max_steps=300, gtol=1e-13, args=(robot, motion, jnp.asarray(0.0))
    )
    design = counter_mass_design(robot, solution.params)
    np.testing.assert_allclose(design.m_cm * design.p_cm, balance_condition_eq1(robot), rtol=1e-6)
    solution = minimize(
        codesign_loss, start, max_steps=300, gtol=1e-13, args=(robot, motion, jnp.asarray(0.1))
    )
    design = counter_mass_design(robot, solution.params)
    np.testing.assert_allclose(design.p_cm, np.sqrt(0.026845 / 7.983), rtol=1e-6)


@pytest.mark.slow
def test_triangle_published_numbers():
    """Fig 12 (smooth triangle, 82.6/71.6 m/s²): 271/235 N unbalanced, shaking moment
    16.1 / 14.2 / 14.1 N·m (unbalanced / 96.72 % / balanced); published, tol 1.5 %."""
    motion = _triangle(31)

    def peaks(robot):
        def one(u, ud, udd):
            return _wrench(robot, u, ud, udd)

        force, moment = jax.jit(jax.vmap(one))(*motion)
        return np.abs(np.asarray(force[:, :2])).max(0), np.abs(np.asarray(moment[:, 2])).max()

    force, moment = peaks(dual_v(counter_masses=False))
    np.testing.assert_allclose(force, [271.0, 235.0], rtol=0.015)
    np.testing.assert_allclose(moment, 16.1, rtol=0.015)
    np.testing.assert_allclose(peaks(dual_v(tuning_masses=False))[1], 14.2, rtol=0.015)
    np.testing.assert_allclose(peaks(dual_v())[1], 14.1, rtol=0.015)


def test_sensitivity_gradients_eq30():
    """∂f_x/∂(m_cm·p_cm) summed over arms = 2ẍ5/l and ∂f_x/∂payload = -ẍ5 (eq 30,
    exact for a non-rotated translation; tol 1e-9), so removing the tuning masses is a
    payload of 2·m_tun·p_tun/l = 0.107 kg."""
    from jaxbal.robots.dual_v_balancing import reduced_mass, with_counter_mass_moments

    robot = dual_v()
    acc = jnp.array([82.6, 0.0, 0.0])

    def force_x(moments, payload):
        design = with_counter_mass_moments(eqx_set(robot, payload=payload), moments)
        return _wrench(design, POSES[1], jnp.array([0.5, 0.1, 0.0]), acc)[0][0]

    grads = jax.grad(force_x, argnums=(0, 1))(robot.counter_mass_moments(), jnp.asarray(0.0))
    d_moment, d_payload = grads
    np.testing.assert_allclose(jnp.sum(d_moment), 2 * 82.6 / 0.28, rtol=1e-9)
    np.testing.assert_allclose(d_payload, -82.6, rtol=1e-9)
    equivalent = 2 * robot.m_tun[0] * robot.p_tun[0] / robot.l1[0]
    np.testing.assert_allclose(equivalent, 0.107, rtol=0.01)
    np.testing.assert_allclose(reduced_mass(robot.without_tuning_masses()), 0.107, rtol=0.02)


def test_condition_grid_and_drawings():
    """Fig 8 grid: NaN outside the workspace (corners of the box), κ ≥ 1 inside; the
    layout and κ drawings run (matplotlib Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from jaxbal.robots.dual_v_plots import (
        condition_number_grid,
        plot_condition_number,
        plot_layout,
    )

    robot = dual_v()
    xs, ys, kappa = condition_number_grid(robot, 0.0, count=9)
    kappa = np.asarray(kappa)
    assert np.isnan(kappa[0, 0]) and np.isnan(kappa[-1, -1])
    assert np.all(kappa[np.isfinite(kappa)] >= 1.0 - 1e-12)
    assert np.isfinite(kappa[4, 4])
    plt.close(plot_layout(robot, pose=(0.05, 0.08, 0.1)).figure)
    plt.close(plot_condition_number(robot, orientations=(0.0,), count=9))


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_bearing_forces_refuse_torques_that_do_not_produce_the_motion():
    """With one distal link 1.5× heavier the paper's torques (eq 10 exact only for equal
    equivalent masses) do not produce the motion: their bearing forces were 3e-2 N·m off
    Newton–Euler without a word. Refused (eagerly and under ``jit``); ``evaluate`` gives
    the bearing forces of the paper's torques made exact, whose base wrench is the
    shaking wrench (1e-9), and the paper's own where they are exact (Table 1)."""
    from jaxbal.robots.dual_v_dynamics import evaluate

    table1 = dual_v()
    heavier = eqx.tree_at(lambda r: r.m2, table1, table1.m2.at[0].multiply(1.5))
    q = heavier.inverse_kinematics(MOTION[0])
    tau = paper_torques(heavier, q, MOTION[1], MOTION[2])
    with pytest.raises(ValueError, match="do not produce this motion"):
        bearing_forces(heavier, *MOTION, tau)
    with pytest.raises(Exception, match="do not produce this motion"):
        jax.block_until_ready(jax.jit(lambda t: bearing_forces(heavier, *MOTION, t))(tau))
    exact = virtual_work_torques(heavier, *MOTION)
    assert np.all(np.isfinite(np.asarray(bearing_forces(heavier, *MOTION, exact))))
    sample = evaluate(heavier, *MOTION)
    np.testing.assert_allclose(sample.torques_min_norm, exact, rtol=1e-12)
    tau_exact = exact + torque_split(heavier, q, tau)[1]  # the paper's preload kept
    force, moment = base_wrench_from_bearings(heavier, sample.bearing, tau_exact)
    f_ref, m_ref = jaxbal.shaking_wrench(heavier, *jaxbal.pose_motion(heavier, *MOTION))
    np.testing.assert_allclose(force, f_ref[:2], atol=1e-9)
    np.testing.assert_allclose(moment, m_ref[2], atol=1e-9)
    q1 = table1.inverse_kinematics(MOTION[0])
    tau1 = paper_torques(table1, q1, MOTION[1], MOTION[2])
    np.testing.assert_allclose(
        evaluate(table1, *MOTION).bearing, bearing_forces(table1, *MOTION, tau1), atol=1e-10
    )


def test_a_counter_mass_of_no_inertia_stays_physical():
    """The brass inertia ``about_base − m·d²`` rounded to −3.5e-18 kg·m² for the
    README's co-designed DUAL-V (counter-masses of no inertia of their own), which
    jaxbal then refused to evaluate as non-physical. Written without cancellation it
    is exactly 0, and equals the parallel-axis difference for a tuned counter-mass."""
    bare = dual_v(counter_masses=False)
    # m·d² − m·(m·d/m)² rounds to −8.7e-19 for this pair
    masses, distances = jnp.full(4, 2.8255508412241426), jnp.full(4, 0.028439622365618363)
    designed = bare.with_design({"counter_mass": masses, "counter_distance": distances})
    inertia = np.asarray(designed.mass_properties().inertia[:, 2, 2])
    assert np.all(inertia >= 0.0), inertia
    q, qd, qdd = jaxbal.pose_motion(designed, *MOTION)
    assert np.all(np.isfinite(np.asarray(jaxbal.checked_jit(jaxbal.shaking_wrench)(
        designed, q, qd, qdd)[0])))  # fmt: skip
    table1 = dual_v()
    mass, distance, own = table1._brass()
    about_base = table1.inertia_cm + table1.m_cm * table1.p_cm**2 - table1.m_tun * table1.p_tun**2
    np.testing.assert_allclose(own, about_base - mass * distance**2, rtol=1e-12)
