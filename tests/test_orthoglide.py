"""Tests of the Orthoglide (Geng et al. 2021) and of the implicit Newton solver."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal import newton_solve
from jaxbal.planning import ComLine, EndEffectorLine, shaking_peaks
from jaxbal.profiles import BangBang, Quintic
from jaxbal.robots import orthoglide
from jaxbal.robots.orthoglide_planning import motion_cases, switching_times

P_START = jnp.zeros(3)
P_END = jnp.array([-0.1, 0.07, -0.11])  # §3
DURATION = 0.1
L = 0.31


def _with_payload(robot, payload):
    return eqx.tree_at(lambda r: r.payload, robot, payload)


def _eq6(robot, p):
    """Eq (6) of the paper written out by hand (independent of the body frames)."""
    rho = robot.inverse_kinematics(p)[:3]
    m1, m2 = robot.parallelogram_mass, robot.slider_mass
    m = 3 * (m1 + m2) + robot.platform_mass + robot.payload
    return (
        0.5 * m1 * (rho + 3 * p)
        + m2 * (rho + robot.slider_offset)
        + (robot.platform_mass + robot.payload) * p
    ) / m


# --- implicit solver --------------------------------------------------------------------


def test_newton_solve_value_and_implicit_gradient():
    # reference: closed form x = sqrt(a), dx/da = 1/(2 sqrt(a)), d2x/da2 = -1/(4 a^1.5)
    def residual(x, a):
        return x**2 - a

    @jax.jit
    def root(a):
        return newton_solve(residual, jnp.array([1.0]), a).value[0]

    a = jnp.array(2.0)
    assert root(a) == pytest.approx(np.sqrt(2.0), abs=1e-14)
    assert jax.grad(root)(a) == pytest.approx(0.5 / np.sqrt(2.0), rel=1e-12)
    assert jax.grad(jax.grad(root))(a) == pytest.approx(-0.25 * 2.0**-1.5, rel=1e-10)
    check_grads(root, (a,), order=2, modes=("fwd", "rev"))


def test_newton_solve_reports_failure():
    def residual(x, a):  # x^2 + a = 0 has no real root for a > 0
        return x**2 + a

    with pytest.raises(ValueError, match="did not converge"):
        newton_solve(residual, jnp.array([1.0]), jnp.array(1.0), what="test")
    sol = newton_solve(residual, jnp.array([1.0]), jnp.array(1.0), throw=False)
    assert not bool(sol.converged)
    with pytest.raises(ValueError, match="residual must map"):
        newton_solve(lambda x, a: jnp.sum(x), jnp.array([1.0, 2.0]), 0.0)


# --- kinematics -------------------------------------------------------------------------


def test_inverse_kinematics_matches_paper():
    # reference: §3, ρ_i = 0.31 m at P = 0 and (0.18, 0.34, 0.17) m at P_f (2 decimals;
    # the paper's labels ρ_xf and ρ_yf are swapped: eq (1) gives ρ_xf = 0.18)
    robot = orthoglide()
    np.testing.assert_allclose(robot.inverse_kinematics(P_START)[:3], [L, L, L], atol=1e-15)
    rho_f = robot.inverse_kinematics(P_END)[:3]
    np.testing.assert_allclose(rho_f, [0.18, 0.34, 0.17], atol=0.005)
    expected_x = -0.1 + np.sqrt(L**2 - 0.07**2 - 0.11**2)  # eq (1) by hand
    assert rho_f[0] == pytest.approx(expected_x, abs=1e-15)


def test_forward_kinematics_inverts_inverse_and_vmap_equals_loop():
    # reference: IK(FK(ρ)) = ρ to machine precision on random reachable points
    robot = orthoglide()
    points = jax.random.uniform(jax.random.PRNGKey(0), (8, 3), minval=-0.12, maxval=0.12)
    rho = jax.jit(jax.vmap(lambda p: robot.inverse_kinematics(p)))(points)[:, :3]
    back = jax.jit(jax.vmap(lambda r: robot.forward_kinematics(r)))(rho)
    np.testing.assert_allclose(back, points, atol=1e-13)
    one = jax.jit(lambda r: robot.forward_kinematics(r))
    loop = np.stack([one(r) for r in rho])
    np.testing.assert_allclose(back, loop, atol=1e-15)
    check_grads(jax.jit(lambda r: robot.forward_kinematics(r)), (rho[0],), order=2, modes=("rev",))


def test_com_matches_eq6_and_designed_acceleration():
    # reference: eq (6) by hand; §3: designed COM acceleration 4|D|/T^2 = 38.7 m/s^2
    robot = orthoglide(slider_offset=0.05)
    for p in (P_START, P_END):
        np.testing.assert_allclose(robot.com_of_point(p), _eq6(robot, p), atol=1e-15)
    displacement = robot.com_of_point(P_END) - robot.com_of_point(P_START)
    a_com = 4 * jnp.linalg.norm(displacement) / DURATION**2
    assert a_com == pytest.approx(38.7, abs=0.05)
    # the other mass assignment (§3's words) misses 38.7 by > 10 %: eq (6) by hand
    swapped = orthoglide(parallelogram_mass=0.248, slider_mass=0.396, slider_offset=0.05)
    d_swapped = swapped.com_of_point(P_END) - swapped.com_of_point(P_START)
    by_hand = _eq6(swapped, P_END) - _eq6(swapped, P_START)
    np.testing.assert_allclose(d_swapped, by_hand, atol=1e-15)
    assert abs(4 * float(jnp.linalg.norm(d_swapped)) / DURATION**2 / 38.7 - 1) > 0.10


def test_bad_input_raises():
    robot = orthoglide()
    with pytest.raises(ValueError, match="out of reach"):
        robot.inverse_kinematics(jnp.array([0.0, 0.25, 0.25]))
    with pytest.raises(ValueError, match="shape"):
        robot.inverse_kinematics(jnp.zeros(2))
    with pytest.raises(ValueError, match="non-negative"):
        orthoglide(payload=-1.0)
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(P_START, branch=0)
    with pytest.raises(ValueError, match="not assemblable"):
        robot.forward_kinematics(jnp.array([0.9, 0.1, 0.1]))
    with pytest.raises(ValueError, match="COM target not reachable"):
        robot.com_inverse_kinematics(jnp.array([1.0, 1.0, 1.0]))


@pytest.mark.parametrize("bad", [2, 0, -2, (1, 1), (1, 1, 1, 1), (1, 0, 1), "up"])
def test_invalid_branch_raises(bad):
    # reference: the contract -- a sign other than ±1 or a tuple not of 3 signs is a
    # structure error (ValueError), for the IK, the COM IK and with return_valid=True
    robot = orthoglide()
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(P_END, branch=bad)
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(P_END, branch=bad, return_valid=True)
    with pytest.raises(ValueError, match="branch"):
        robot.com_inverse_kinematics(robot.com_of_point(P_END), branch=bad)


def test_branch_selects_the_configuration_index_of_eq1():
    # reference: eq (1) by hand, ρ_i = p_i + s_i sqrt(L² − p_j² − p_k²) (tol 1e-15 m);
    # an int branch means the same sign on every leg
    robot = orthoglide()
    branch = (1, -1, 1)
    rho = robot.inverse_kinematics(P_END, branch=branch)[:3]
    radicands = L**2 - (np.sum(np.asarray(P_END) ** 2) - np.asarray(P_END) ** 2)
    np.testing.assert_allclose(rho, P_END + np.array(branch) * np.sqrt(radicands), atol=1e-15)
    np.testing.assert_array_equal(
        robot.inverse_kinematics(P_END, branch=-1),
        robot.inverse_kinematics(P_END, branch=(-1, -1, -1)),
    )


def test_return_valid_never_raises_on_unreachable_pose():
    # reference: the contract -- with return_valid=True an unreachable pose gives
    # valid=False and a finite q, eagerly, under jit and under vmap (no exception)
    robot = orthoglide()
    unreachable = jnp.array([0.0, 0.25, 0.25])  # |p_⊥| > L for the x leg
    for branch in (None, -1, (1, -1, 1)):
        q, valid = robot.inverse_kinematics(unreachable, branch=branch, return_valid=True)
        assert not bool(valid) and bool(jnp.all(jnp.isfinite(q)))
    q, valid = jax.jit(lambda p: robot.inverse_kinematics(p, return_valid=True))(unreachable)
    assert not bool(valid) and bool(jnp.all(jnp.isfinite(q)))
    poses = jnp.stack([P_START, unreachable, P_END, jnp.full(3, jnp.nan)])
    q, valid = jax.vmap(lambda p: robot.inverse_kinematics(p, return_valid=True))(poses)
    assert valid.tolist() == [True, False, True, False]
    np.testing.assert_allclose(q[2], robot.inverse_kinematics(P_END), atol=1e-15)
    _, valid = robot.com_inverse_kinematics(jnp.ones(3), return_valid=True)
    assert not bool(valid)


def test_counter_sliders_add_their_momentum_rate():
    # reference: closed form -- counter-slider i is a point mass at −ρ_i e_i, so it adds
    # +m_c,i ρ̈_i e_i to f_sh = −Σ m a (tol 1e-10 N); zero mass (default) changes nothing;
    # the design variable counter_mass round-trips through with_design
    robot = orthoglide()
    motion = (
        jnp.array([0.02, -0.03, 0.05]),
        jnp.array([0.5, -0.2, 0.3]),
        jnp.array([40.0, 10, -25]),
    )
    q, qd, qdd = jaxbal.pose_motion(robot, *motion)
    counter = jnp.array([0.3, 0.5, 0.7])
    heavier = robot.with_design({"counter_mass": counter})
    np.testing.assert_array_equal(heavier.design()["counter_mass"], counter)
    force0, _ = jaxbal.shaking_wrench(robot, q, qd, qdd)
    force1, _ = jaxbal.shaking_wrench(heavier, q, qd, qdd)
    np.testing.assert_allclose(force1 - force0, counter * qdd[:3], atol=1e-10)
    assert jaxbal.total_mass(heavier) == pytest.approx(float(jaxbal.total_mass(robot)) + 1.5)


# --- COM inverse kinematics ---------------------------------------------------------------


@pytest.mark.slow
def test_com_inverse_kinematics_round_trip_and_vmap():
    # reference: COM(COM-IK(S)) = S; vmap equals a Python loop
    robot = orthoglide(payload=2.0)
    targets = jnp.stack([robot.com_of_point(P_START), robot.com_of_point(P_END)])
    q = jax.vmap(robot.com_inverse_kinematics)(targets)
    np.testing.assert_allclose(q[1, 3:], P_END, atol=1e-12)
    np.testing.assert_allclose(jax.vmap(robot.com_of_point)(q[:, 3:]), targets, atol=1e-14)
    loop = np.stack([robot.com_inverse_kinematics(s) for s in targets])
    np.testing.assert_allclose(q, loop, atol=1e-15)
    _, valid = jax.vmap(lambda s: robot.com_inverse_kinematics(s, return_valid=True))(
        jnp.stack([targets[0], jnp.ones(3)])
    )
    assert valid.tolist() == [True, False]


@pytest.mark.slow
def test_com_inverse_kinematics_gradients_match_finite_differences():
    # reference: central finite differences (h = 1e-6) and check_grads (order 2)
    robot = orthoglide(payload=1.0)
    target = 0.5 * (robot.com_of_point(P_START) + robot.com_of_point(P_END))

    @jax.jit
    def rho_x(payload):
        return _with_payload(robot, payload).com_inverse_kinematics(target)[0]

    h = 1e-6
    fd = (rho_x(1.0 + h) - rho_x(1.0 - h)) / (2 * h)
    grad = jax.grad(rho_x)(1.0)
    assert np.isfinite(grad)
    assert grad == pytest.approx(float(fd), rel=1e-6)
    check_grads(
        jax.jit(lambda s: robot.com_inverse_kinematics(s)), (target,), order=1, modes=("fwd", "rev")
    )


# --- shaking force along the plans of §3.1 -------------------------------------------------


# make test-all: the 2R's COM plan (test_planar_arm) and the Orthoglide's COM Newton solve
# (test_newton_solve_value_and_implicit_gradient) stay in make test
@pytest.mark.slow
def test_com_plan_gives_constant_bang_bang_force():
    # reference: f_sh = -M a_S (eq 2); along the COM bang-bang plan |f_sh| = M·4|D|/T^2
    robot = orthoglide(payload=1.0)
    plan = jaxbal.planning.com_line(
        robot,
        robot.inverse_kinematics(P_START),
        robot.inverse_kinematics(P_END),
        BangBang(),
        DURATION,
        dims=3,
    )
    assert isinstance(plan, ComLine)
    times = jnp.array([0.01, 0.03, 0.07, 0.09])
    force, _ = jax.jit(jaxbal.planning.wrench_along)(robot, plan, times)
    expected = jaxbal.total_mass(robot) * 4 * jnp.linalg.norm(plan.line.end - plan.line.start)
    np.testing.assert_allclose(jnp.linalg.norm(force, axis=1), expected / DURATION**2, rtol=1e-10)


@pytest.mark.slow
def test_table1_payload0_and_gradient_through_planner():
    # reference: Table 1 (payload 0): case 1 117.99 N, case 3 78.86 N, within 1 %;
    # d max|F| / d payload of case 3 through the COM planner vs the closed form M·4|D|/T²
    robot = orthoglide()
    times = switching_times(DURATION, 41)
    case1 = EndEffectorLine(robot, jaxbal.StraightLine(P_START, P_END, Quintic(), DURATION))
    f1, _ = jax.jit(shaking_peaks)(robot, case1, jaxbal.sample_times(DURATION, 201))
    assert f1 == pytest.approx(117.99, rel=0.01)

    def case3_force(payload):
        r = _with_payload(robot, payload)
        plan = jaxbal.planning.com_line(
            r,
            r.inverse_kinematics(P_START),
            r.inverse_kinematics(P_END),
            BangBang(),
            DURATION,
            dims=3,
        )
        return shaking_peaks(r, plan, times)[0]

    force0, grad0 = jax.jit(jax.value_and_grad(case3_force))(0.0)
    assert force0 == pytest.approx(78.86, rel=0.01)

    def closed_form(payload):  # M · 4|D| / T², D from eq (6) at the two end points
        r = _with_payload(robot, payload)
        displacement = _eq6(r, P_END) - _eq6(r, P_START)
        return jaxbal.total_mass(r) * 4 * jnp.linalg.norm(displacement) / DURATION**2

    assert np.isfinite(grad0)
    assert grad0 == pytest.approx(float(jax.grad(closed_form)(0.0)), rel=1e-8)


def test_case4_plan_is_case3_plan_without_payload_error():
    # reference: §3.3, with Δm = 0 the two plans coincide; with Δm ≠ 0 case 4 keeps the
    # nominal-payload plan (its COM line ends at the nominal-payload COMs)
    robot = orthoglide(payload=2.0)
    off = motion_cases(robot, P_START, P_END, DURATION, planned_payload=1.0)
    nominal = orthoglide(payload=1.0)
    # case 3 plans for the true 2 kg (eq 6 by hand), case 4 for the nominal 1 kg
    np.testing.assert_allclose(off["case3"].line.end, _eq6(robot, P_END), atol=1e-15)
    np.testing.assert_allclose(off["case4"].line.end, _eq6(nominal, P_END), atol=1e-15)
    assert float(jnp.linalg.norm(off["case3"].line.end - off["case4"].line.end)) > 1e-3
    np.testing.assert_allclose(off["case3"](DURATION)[3:], P_END, atol=1e-12)
    np.testing.assert_allclose(off["case4"](DURATION)[3:], P_END, atol=1e-12)
