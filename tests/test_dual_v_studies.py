"""Tests of the DUAL-V studies (van der Wijk et al. 2013): the paper's motions, peaks and
ratios, the model checks, eq (30) and the co-design trade. Every reference is a closed
form, finite differences or an independent computation; each tolerance is stated."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.profiles import Quintic
from jaxbal.robots import OUTWARD, dual_v
from jaxbal.robots import dual_v_studies as studies
from jaxbal.robots.dual_v_balancing import (
    BALANCE_NULL_DIRECTION,
    balance_condition_eq1,
    balance_condition_eq2,
    balance_line_offsets,
    balance_sweep,
    payload_sweep,
    reduced_mass,
    with_balance_fraction,
)
from jaxbal.robots.dual_v_dynamics import MotionSample

# Reproduction studies (their numbers are also written by `make reproduce`): make test-all.
pytestmark = pytest.mark.slow


def test_quintic_duration_closed_form():
    """T = sqrt(10 S/(√3 a)) ⇔ the quintic's peak s̈ is 10/√3, at u* = 1/2 - √3/6 where
    s⃛ = 0 (closed form vs autodiff of the profile, 1e-12); the orthogonal move reaches
    a (rtol 1e-4, 301 samples) and never exceeds it."""
    peak = 0.5 - np.sqrt(3.0) / 6.0
    second = jax.grad(jax.grad(Quintic()))
    np.testing.assert_allclose(second(peak), 10 / np.sqrt(3.0), rtol=1e-12)
    np.testing.assert_allclose(jax.grad(second)(peak), 0.0, atol=1e-12)
    duration = studies.quintic_duration(0.2, 51.0)
    np.testing.assert_allclose(0.2 * 10 / np.sqrt(3.0) / duration**2, 51.0, rtol=1e-14)
    for axis in (0, 1):
        u, ud, udd = (np.asarray(m) for m in studies.orthogonal_motion(axis, 51.0, 0.2, 301))
        peak = np.max(np.abs(udd[:, axis]))
        assert 51.0 * (1 - 1e-4) < peak <= 51.0 * (1 + 1e-12)
        np.testing.assert_allclose(u[[0, -1], axis], [-0.1, 0.1], atol=1e-15)
        np.testing.assert_allclose(ud[[0, -1]], 0.0, atol=1e-12)
        assert np.all(udd[:, 1 - axis] == 0.0)


def test_triangle_geometry_and_peaks():
    """Fig 12 triangle: equilateral, side r·√3, vertices on the circle (closed form, 1e-15);
    at rest at the vertices; peaks 10·r/T² along x and (10/√3)·1.5·r/T² along y (closed
    form of the quintic, rtol 1e-4 at 301 samples per side)."""
    radius, side_time = studies.TEST_CIRCLE_RADIUS, 0.11
    vertices = studies.triangle_vertices(radius)
    sides = np.linalg.norm(vertices - np.roll(vertices, 1, axis=0), axis=1)
    np.testing.assert_allclose(sides, radius * np.sqrt(3.0), rtol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(vertices[:, :2], axis=1), radius, rtol=1e-15)
    u, ud, udd = studies.triangle_motion(301, side_time)
    assert u.shape == (903, 3)
    np.testing.assert_allclose(u[::301], vertices, atol=1e-15)
    np.testing.assert_allclose(np.asarray(ud).reshape(3, 301, 3)[:, [0, -1]], 0.0, atol=1e-12)
    np.testing.assert_allclose(jnp.max(jnp.abs(udd[:, 0])), 10 * radius / side_time**2, rtol=1e-4)
    peak_y = 10 / np.sqrt(3.0) * 1.5 * radius / side_time**2
    np.testing.assert_allclose(jnp.max(jnp.abs(udd[:, 1])), peak_y, rtol=1e-4)


def test_validation_motion_reaches_the_section_4_2_peaks():
    """The Fig 6 validation move reaches (118, 202, 1612) (rtol 1e-4 at 101 samples)."""
    peaks = jnp.max(jnp.abs(studies.validation_motion()[2]), axis=0)
    np.testing.assert_allclose(peaks, [118.0, 202.0, 1612.0], rtol=1e-4)


def test_workspace_widths_match_inverse_kinematics():
    """The x width 2(l1 + l2 - a) and y width 2·sqrt((l1 + l2)² - a²) (paper 0.328, 0.792 m,
    rtol 1e-3) bound the poses the IK reaches (1e-6 m inside valid, outside not)."""
    robot = dual_v()
    width_x, width_y = studies.workspace_widths(robot)
    np.testing.assert_allclose([width_x, width_y], [0.328, 0.792], rtol=1e-3)
    for pose, valid in (
        ((width_x / 2 - 1e-6, 0.0, 0.0), True),
        ((width_x / 2 + 1e-6, 0.0, 0.0), False),
        ((0.0, width_y / 2 - 1e-6, 0.0), True),
        ((0.0, width_y / 2 + 1e-6, 0.0), False),
    ):
        _, ok = robot.inverse_kinematics(jnp.asarray(pose), return_valid=True)
        assert bool(ok) == valid, pose


def test_joint_states_give_the_reduced_mass_force_along_a_move():
    """Eq (30)/§6: F(t) = -m_red·a(t) at every sample of a non-rotated translation along
    y (rtol 1e-9), from the joint states (branch OUTWARD) and jaxbal.shaking_wrench."""
    robot = dual_v(counter_masses=False)
    motion = studies.orthogonal_motion(1, 51.0, 0.2, 9)
    states = studies.joint_states(robot, motion)
    np.testing.assert_allclose(states[0][:, 8:], motion[0], rtol=0, atol=1e-15)
    wrench = jax.jit(jax.vmap(lambda q, qd, qdd: jaxbal.shaking_wrench(robot, q, qd, qdd)[0]))
    force = wrench(*states)
    expected = -reduced_mass(robot) * motion[2][:, :2]
    np.testing.assert_allclose(force[:, :2], expected, rtol=1e-9, atol=1e-9)


def test_motion_peaks_of_a_history():
    """Peaks of a two-sample history (exact arithmetic): component and norm maxima."""
    history = MotionSample(
        shaking_force=jnp.array([[3.0, -4.0], [-6.0, 1.0]]),
        shaking_moment=jnp.array([-2.0, 1.5]),
        torques=jnp.array([[1.0, -2.0, 3.0, 0.0], [-4.0, 1.0, 0.0, 0.5]]),
        torques_min_norm=jnp.zeros((2, 4)),
        bearing=jnp.zeros((2, 4, 2)).at[1, 2].set(jnp.array([3.0, 4.0])),
    )
    peaks = studies.motion_peaks(history)
    np.testing.assert_array_equal(peaks.force, [6.0, 4.0])
    np.testing.assert_allclose(peaks.force_norm, np.hypot(6.0, 1.0), rtol=1e-15)
    assert float(peaks.moment) == 2.0
    np.testing.assert_array_equal(peaks.torques, [4.0, 2.0, 3.0, 0.5])
    np.testing.assert_array_equal(peaks.bearing, [0.0, 0.0, 5.0, 0.0])


def test_balancing_ratios_definitions():
    """Ratios of synthetic peaks (exact arithmetic): torque ratio, its mean, reductions."""
    zeros = jnp.zeros(4)
    unbalanced = studies.Peaks(zeros, 0.0, 16.0, jnp.full(4, 2.0), zeros, jnp.full(4, 4.0))
    balanced = studies.Peaks(zeros, 0.0, 12.0, jnp.array([3.0, 3.0, 4.0, 4.0]), zeros, zeros + 1)
    ratios = studies.balancing_ratios(balanced, unbalanced)
    np.testing.assert_array_equal(ratios.torque, [1.5, 1.5, 2.0, 2.0])
    assert float(ratios.torque_mean) == 1.75
    np.testing.assert_array_equal(ratios.bearing_reduction, 0.75)
    assert float(ratios.moment_reduction) == 0.25


@pytest.mark.slow
def test_model_checks_on_a_fast_move():
    """Fig 6 analogue: forward dynamics returns q̈ to round-off (< 1e-12 relative); eqs
    (3)-(29) equal Lagrange on the split model and have the min-norm platform effect
    (< 1e-9 N·m); the paper's distribution carries a non-zero preload (> 1e-3)."""
    robot = dual_v()
    motion = tuple(m[jnp.array([10, 25, 40])] for m in studies.validation_motion(51))
    assert float(studies.forward_dynamics_error(robot, motion)) < 1e-12
    check = studies.torque_model_check(robot, motion)
    assert float(check.split_model) < 1e-9 and float(check.platform_effect) < 1e-9
    assert float(check.preload) > 1e-3


def test_eq30_sensitivity_closed_form():
    """Eq (30): Σ∂F_x/∂μ_i / ẍ = 2/l, -∂F_x/∂payload / ẍ = 1, tuning masses = a payload of
    2·m_tun·p_tun/l (closed forms, rtol 1e-9; a payload does not change them)."""
    robot = dual_v(payload=0.05)
    motion = studies.triangle_motion(11, 0.11)
    result = studies.eq30_sensitivity(robot, motion)
    np.testing.assert_allclose(result.moment, 2 / 0.28, rtol=1e-9)
    np.testing.assert_allclose(result.payload, 1.0, rtol=1e-9)
    np.testing.assert_allclose(result.tuning_equivalent, 2 * 0.188 * 0.08 / 0.28, rtol=1e-9)
    # the move's two peaks of |ẍ| mirror each other (±82.45 m/s², equal up to rounding,
    # which differs between CPUs): either may be the instant, so compare magnitudes
    peak = jnp.max(jnp.abs(motion[2][:, 0]))
    np.testing.assert_allclose(jnp.abs(result.acceleration), peak, rtol=0)


def test_sweeps_follow_the_reduced_mass():
    """max|F_x| on a move along x = |m_red + payload|·max|ẍ|, with m_red = 2(1 - f)μ*/l
    for a counter-mass moment f·μ* (closed form, eq 30; rtol 1e-9). The sweeps are
    labelled (jaxbal.sweep): dimension, coordinates and units."""
    robot = dual_v()
    motion = studies.orthogonal_motion(0, 51.0, 0.2, 11)
    acc = float(jnp.max(jnp.abs(motion[2][:, 0])))
    payloads = np.array([0.0, 0.1, 0.3])
    expected = (float(reduced_mass(robot)) + payloads) * acc
    got = payload_sweep(robot, studies.joint_states(robot, motion), payloads)
    assert got.dims == ("payload",) and got.attrs["units"] == "N"
    assert got["payload"].attrs["units"] == "kg"
    np.testing.assert_array_equal(got["payload"].values, payloads)
    np.testing.assert_allclose(got.values, expected, rtol=1e-9)
    fractions = np.array([0.9, 0.9672, 1.05])
    mu = float(balance_condition_eq2(robot)[0])
    expected = np.abs(2 * (1 - fractions) * mu / 0.28) * acc
    got = balance_sweep(robot, studies.joint_states(robot, motion), fractions)
    assert got.dims == ("balance_fraction",) and got.name == "peak_force_x"
    np.testing.assert_array_equal(got["balance_fraction"].values, fractions)
    np.testing.assert_allclose(got.values, expected, rtol=1e-9)
    moved = with_balance_fraction(robot, 0.9672)  # m_cm scaled, p_cm kept
    np.testing.assert_array_equal(moved.p_cm, robot.p_cm)
    required = 0.9672 * balance_condition_eq2(robot)
    np.testing.assert_allclose(moved.m_cm * moved.p_cm, required, rtol=1e-15)


def test_balance_line_offsets():
    """Designs on μ* + c·(-1, 1, 1, -1) are off the line by 0 (round-off, 1e-15) and off μ*
    by |c|/2/μ*; a uniform 1 % excess is off both by 1 % (exact by construction)."""
    reference = balance_condition_eq1(dual_v())
    deviation, off_line = balance_line_offsets(reference + 0.01 * BALANCE_NULL_DIRECTION, reference)
    assert float(off_line) < 1e-15
    np.testing.assert_allclose(deviation, jnp.max(0.005 / reference), rtol=1e-12)
    deviation, off_line = balance_line_offsets(1.01 * reference, reference)
    np.testing.assert_allclose([deviation, off_line], 0.01, rtol=1e-12)


@pytest.mark.slow
def test_codesign_trade_recovers_the_balance_line_and_the_radius_of_gyration():
    """w = 0: the design lies on the line of exactly balanced designs (1e-6) and its
    shaking force vanishes (< 1e-4 N); w > 0: p_cm → sqrt(I_cm/m_cm) (closed form, 1e-6)."""
    robot = dual_v()
    design, evaluation = studies.triangle_motion(5, 0.11), studies.triangle_motion(3, 0.11)
    trade = studies.codesign_trade(robot, (0.0, 0.1), design, evaluation, max_steps=300)
    zero, penalised = trade
    moments = zero.robot.m_cm * zero.robot.p_cm
    assert float(balance_line_offsets(moments, balance_condition_eq1(robot))[1]) < 1e-6
    assert float(zero.peak_force) < 1e-4
    np.testing.assert_allclose(penalised.robot.p_cm, np.sqrt(0.026845 / 7.983), rtol=1e-6)
    penalised_moments = penalised.robot.m_cm * penalised.robot.p_cm
    np.testing.assert_allclose(penalised.mean_moment, jnp.mean(penalised_moments), rtol=1e-15)
    assert float(penalised.mean_moment) < float(jnp.mean(moments))
    assert float(penalised.peak_torque) < float(zero.peak_torque)


def test_quintic_moves_rest_at_the_waypoints():
    """Rest-to-rest moves: the waypoints at the move boundaries, zero velocity there (exact
    by the quintic's boundary conditions, 1e-15); a bad shape raises ValueError."""
    waypoints = np.array([[-0.1, -0.175, 0.0], [0.1, 0.175, 0.1], [0.1, 0.175, -0.3]])
    path = studies.QuinticMoves(waypoints, (0.1, 0.0345))
    assert path.duration == 0.1 + 0.0345
    for t, point in zip((0.0, 0.1, 0.1345, 0.2), waypoints[[0, 1, 2, 2]], strict=True):
        u, ud = jaxbal.time_derivatives(path, t, 1)
        np.testing.assert_allclose(u, point, atol=1e-15)
        np.testing.assert_allclose(ud, 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="waypoints"):
        studies.QuinticMoves(waypoints, (0.1,))


def test_torque_laws_have_the_same_platform_effect():
    """The paper's and the minimum-norm torques differ only along null(Jᵀ): Jᵀ(τ_paper -
    τ_min) = 0 (1e-9 relative to Jᵀτ); an unknown model raises ValueError."""
    robot = dual_v()
    path = studies.QuinticMoves([[-0.05, -0.05, 0.0], [0.05, 0.05, 0.1]], (0.05,))
    t = 0.013
    paper = jax.jit(studies.torque_law(robot, path, "paper"))(t)
    minimum = jax.jit(studies.torque_law(robot, path, "min_norm"))(t)
    jacobian = robot.jacobian(robot.inverse_kinematics(path(t)))
    scale = float(jnp.max(jnp.abs(jacobian.T @ paper)))
    np.testing.assert_allclose(jacobian.T @ (paper - minimum), 0.0, atol=1e-9 * scale)
    assert float(jnp.max(jnp.abs(paper - minimum))) > 1e-6 * float(jnp.max(jnp.abs(paper)))
    with pytest.raises(ValueError, match="model"):
        studies.torque_law(robot, path, "spacar")


@pytest.mark.slow
def test_open_loop_convergence_in_mujoco():
    """MuJoCo driven by the eqs (3)-(29) torques on a short fast move: the tracking error
    falls as dt² (observed order in [1.8, 2.2], RK4 with a mid-step control) and the
    Richardson limit is far below the error at the finest step (< 5 %)."""
    robot = dual_v()
    path = studies.QuinticMoves([[-0.02, -0.02, 0.0], [0.02, 0.02, 0.05]], (0.01,))
    study = studies.open_loop_convergence(robot, path, path.duration, timesteps=(2e-4, 1e-4, 5e-5))
    assert set(study.runs) == {2e-4, 1e-4, 5e-5}
    assert np.all((study.order > 1.8) & (study.order < 2.2)), study.order
    assert np.all(study.extrapolated < 0.05 * study.runs[5e-5].error)
    assert study.passed((1.8, 2.2), 0.05 * study.runs[5e-5].error)


def test_confirm_motions_with_mujoco_c():
    """jaxbal's shaking wrench equals MuJoCo C's base reaction along a move (relative
    1e-9) for every robot and case; keys '{case} {label}', cases outermost."""
    motion = studies.orthogonal_motion(0, 51.0, 0.2, 9)
    robots = {"unbalanced": dual_v(counter_masses=False), "balanced": dual_v()}
    found = studies.confirm_motions(robots, {"x": (motion, OUTWARD)}, engine="mujoco")
    assert list(found) == ["x unbalanced", "x balanced"]
    for agreement in found.values():
        assert agreement.force_relative < 1e-9 and agreement.moment_relative < 1e-9
